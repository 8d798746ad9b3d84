"""Run one scenario end to end: assemble, fly, record, score, gate, report.

Output contract (DESIGN.md): DIR/metrics.json, telemetry.parquet, events/, trajectories/*.tum,
scenario.yaml (the resolved scenario), run.json (how the run went), report.html.
Exit status: 0 completed and thresholds held, 3 a threshold failed, 4 the simulation was
aborted (crash, NaN, divergence: the record up to that point is kept and labelled aborted).
"""

from __future__ import annotations

import json
import logging
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
import yaml

from testbench.config.loader import LoadedScenario
from testbench.core.errors import (
    EXIT_OK,
    EXIT_RUN_ABORTED,
    EXIT_THRESHOLD_FAILED,
    InputError,
    SimulationAborted,
)
from testbench.core.interfaces import GeodeticOrigin
from testbench.core.rng import RngStreams
from testbench.sim.engine import Engine, EngineResult
from testbench.sim.provenance import environment
from testbench.sim.recorder import Recorder
from testbench.sim.vehicle import build_vehicle, decimation
from testbench.sim.world_runtime import RunWorld

log = logging.getLogger(__name__)


@dataclass
class RunOutcome:
    """What a run produced: exit status, status text, flat metrics and where it was written."""

    exit_status: int
    status: str
    out_dir: Path
    metrics: dict[str, Any] = field(default_factory=dict)
    failed_thresholds: list[str] = field(default_factory=list)
    abort_reason: str | None = None


def origin_of(loaded: LoadedScenario) -> GeodeticOrigin:
    o = loaded.scenario.world.origin
    return GeodeticOrigin(np.radians(o.lat_deg), np.radians(o.lon_deg), o.alt_m)


def build_engine(
    loaded: LoadedScenario,
    *,
    seed: int | np.random.SeedSequence | None = None,
    realtime: bool = False,
    on_progress: Callable[[float], None] | None = None,
    frame_sink: Callable[[str, str, Any], None] | None = None,
    processes: int = 1,
) -> tuple[Engine, RunWorld, Recorder]:
    """Assemble the world, the vehicles and the engine of a scenario (no I/O of outputs);
    processes: how many processes fly the vehicles' stacks, this one included (Engine)."""
    scn = loaded.scenario
    streams = RngStreams(scn.seed if seed is None else seed)
    world = RunWorld(scn.world, origin_of(loaded), streams=streams, epoch_year=scn.epoch_year)
    world.cloud_layer()  # drawn now: a sun that cannot be placed is bad input before anything is written
    vehicles = [build_vehicle(scn, v, world, streams, str(loaded.directory)) for v in scn.vehicles]
    from testbench.sim.appearance import default_look

    world.looks = {
        rt.id: default_look(i, rt.kind, rt.dynamics.aircraft_meta, rt.spec.colour_rgb, rt.spec.led_rate_hz)
        for i, rt in enumerate(vehicles)
    }
    record_every = decimation(scn.record_rate_hz, scn.physics_rate_hz, "record_rate_hz")
    # Wind columns where there is wind to score or an estimate of it (records of calm-air
    # runs whose navigators carry no wind keep their columns as before).
    recorder = Recorder(wind_columns=scn.world.wind is not None or any(rt.navigator.estimates_wind for rt in vehicles),
                        boresight_columns=any(getattr(rt.navigator, "estimates_camera_boresight", False) for rt in vehicles),
                        time_offset_columns=any(getattr(rt.navigator, "time_offset_camera", None) for rt in vehicles),
                        intrinsics_columns=any(getattr(rt.navigator, "intrinsics_camera", None) for rt in vehicles),
                        map_error_columns=any(getattr(getattr(rt.navigator, "ekf", None), "i_map", None) is not None
                                              for rt in vehicles))
    engine = Engine(
        vehicles, world, scn.physics_rate_hz, scn.duration_s, record_every, recorder,
        realtime=realtime, on_progress=on_progress, frame_sink=frame_sink, formation=scn.formation,
        processes=processes,
    )
    return engine, world, recorder


def check_scenario(loaded: LoadedScenario) -> str:
    """Build everything the scenario names without flying it: the vehicles (JSBSim models,
    sensors, navigators, aids, controllers), every map and elevation model of the world (opened,
    georeference read; procedural worlds generated into the cache), and each vehicle's initial
    state (set, a fixed wing trimmed, the navigators initialised). Bad input raises InputError
    as `run` would; nothing is written. Returns the resolved scenario (after --set and ${VAR})
    as YAML, the scenario.yaml a run would write."""
    engine, world, _ = build_engine(loaded)
    for open_map in (world.imagery, world.reference_map, world.elevation, world.reference_elevation):
        open_map()
    engine.start()
    return yaml.safe_dump(loaded.data, sort_keys=False)


def run_scenario(
    loaded: LoadedScenario,
    out_dir: str | os.PathLike,
    *,
    seed: int | np.random.SeedSequence | None = None,
    realtime: bool = False,
    on_progress: Callable[[float], None] | None = None,
    frame_sink: Callable[[str, str, Any], None] | None = None,
    report: bool = True,
    pdf: bool = False,
    processes: int = 1,
) -> RunOutcome:
    """Fly the scenario and write the output contract into out_dir (processes: see Engine)."""
    out = Path(out_dir)
    # Assembled before the folder is made: a vehicle that cannot be built (bad input, exit 2)
    # leaves no folder behind.
    engine, world, recorder = build_engine(loaded, seed=seed, realtime=realtime, on_progress=on_progress,
                                           frame_sink=frame_sink, processes=processes)
    if (out / "batch.json").is_file():
        raise InputError(f"--out {out}: holds a Monte Carlo batch (batch.json); expected a run folder or a new one")
    out.mkdir(parents=True, exist_ok=True)
    from testbench.scoring.record_io import remove_run_outputs

    # Never leave a previous run's verdict, vehicles, events or images behind.
    remove_run_outputs(out)
    result = engine.run()
    if result.aborted is not None and not isinstance(result.aborted, SimulationAborted):
        raise result.aborted  # a bug or a user error surfaced mid-run: not a flight outcome
    recorder.write(out)
    (out / "scenario.yaml").write_text(yaml.safe_dump(loaded.data, sort_keys=False), encoding="utf-8")
    run_info = _run_info(loaded, engine, world, result, seed)
    preview = _map_preview(world, recorder, out)
    if preview is not None:
        run_info["map_image"] = preview
    (out / "run.json").write_text(json.dumps(run_info, indent=2, sort_keys=True) + "\n", encoding="utf-8")
    return finish_run(out, run_info, report=report, pdf=pdf)


def finish_run(out: Path, run_info: dict[str, Any], *, report: bool, pdf: bool) -> RunOutcome:
    """Score the record, check thresholds, write metrics.json and the report."""
    from testbench import scoring

    result = scoring.score_run(out)
    thresholds = run_info.get("thresholds", {})
    verdict = scoring.check_thresholds(result.flatten(), thresholds)
    scoring.write_metrics_json(out, result, verdict)
    aborted = run_info["status"] != "completed"
    if report:
        from testbench import reporting

        reporting.write_html_report(out, out / "report.html")
        if pdf:
            reporting.write_pdf_report(out, out / "report.pdf")
    if aborted:
        status, code = "aborted", EXIT_RUN_ABORTED
    elif verdict.failed:
        status, code = "threshold_failed", EXIT_THRESHOLD_FAILED
    else:
        status, code = "passed", EXIT_OK
    return RunOutcome(
        exit_status=code, status=status, out_dir=out, metrics=result.flatten(),
        failed_thresholds=[f["key"] if isinstance(f, dict) else str(f) for f in verdict.failed],
        abort_reason=run_info.get("abort_reason"),
    )


def _map_preview(world: RunWorld, recorder: Recorder, out: Path, max_px: int = 1200) -> dict[str, Any] | None:
    """A PNG of the camera imagery under the flown area (for the report's trajectory plot):
    {"path": "map_preview.png", "bounds_ne_m": [n_min, n_max, e_min, e_max]}; None without imagery."""
    if world.spec.imagery is None or recorder.n_rows == 0:
        return None
    import cv2

    tel = recorder.telemetry_table()
    n = np.asarray(tel.column("truth_north_m").to_numpy())
    e = np.asarray(tel.column("truth_east_m").to_numpy())
    margin = 300.0 + 0.1 * max(np.ptp(n), np.ptp(e))
    n0, n1, e0, e1 = n.min() - margin, n.max() + margin, e.min() - margin, e.max() + margin
    gsd = max(n1 - n0, e1 - e0) / max_px
    try:
        raster = world.imagery().read_local(n0, n1, e0, e1, gsd)
    except Exception as exc:  # noqa: BLE001 -- a missing preview must not fail the run
        log.warning("no map preview for the report: %s", exc)
        return None
    img = np.where(raster.valid[..., None], raster.data[..., :3], 255).astype(np.uint8)
    cv2.imwrite(str(out / "map_preview.png"), np.ascontiguousarray(img[..., ::-1]))
    h, w = raster.shape
    return {
        "path": "map_preview.png",
        "bounds_ne_m": [raster.north0_m - h * raster.gsd_m, raster.north0_m, raster.east0_m, raster.east0_m + w * raster.gsd_m],
    }


def _run_info(loaded: LoadedScenario, engine: Engine, world: RunWorld, result: EngineResult, seed) -> dict[str, Any]:
    scn = loaded.scenario
    wall = max(result.wall_time_s, 1e-9)
    seed_repr: Any = scn.seed if seed is None else (seed if isinstance(seed, int) else {"entropy": seed.entropy, "spawn_key": list(seed.spawn_key)})
    return {
        "scenario_name": scn.name,
        "scenario_file": str(loaded.path),
        "seed": seed_repr,
        "sim_time_s": result.sim_time_s,
        "wall_time_s": result.wall_time_s,
        "real_time_factor": result.sim_time_s / wall,
        "max_realtime_lag_s": result.max_realtime_lag_s,
        "status": "completed" if result.aborted is None else "aborted",
        "abort_reason": None if result.aborted is None else str(result.aborted),
        "vehicles": [{"id": v.id, "aircraft": v.spec.aircraft, "kind": v.kind} for v in engine.vehicles],
        "phases": scn.phases.model_dump(),
        "origin": scn.world.origin.model_dump(),
        "same_raster": world.same_raster,
        "same_dem": world.same_dem,
        "world": scn.world.model_dump(exclude={"origin"}),
        "thresholds": {k: v.model_dump(exclude_none=True) for k, v in scn.thresholds.items()},
        "gnss_denied_windows": {v.id: _gnss_denied_windows(v.spec, result.sim_time_s) for v in engine.vehicles},
        "gnss_spoofed_windows": {v.id: _gnss_denial_windows(v.spec, result.sim_time_s, "spoofing") for v in engine.vehicles},
        "aid_counters": _aid_counters(engine),
        "camera_boresight_error_deg": _camera_boresights(engine),
        "camera_time_offset_s": _camera_time_offsets(engine),
        "camera_intrinsics_error": _camera_intrinsics_errors(engine),
        "camera_time_offset_estimated": {v.id: v.navigator.time_offset_camera for v in engine.vehicles
                                         if getattr(v.navigator, "time_offset_camera", None)},
        "camera_boresight_estimated": {v.id: v.navigator.boresight_camera for v in engine.vehicles
                                       if getattr(v.navigator, "boresight_camera", None)},
        "camera_intrinsics_estimated": {v.id: v.navigator.intrinsics_camera for v in engine.vehicles
                                        if getattr(v.navigator, "intrinsics_camera", None)},
        # The code, library builds and CPU features the record's bits depend on (provenance).
        "environment": environment(),
    }


def _camera_truths(engine: Engine, value: Callable[[Any], Any]) -> dict[str, dict[str, Any]]:
    """vehicle id -> sensor name -> value(sensor), for the sensors whose value is not None."""
    out: dict[str, dict[str, Any]] = {}
    for v in engine.vehicles:
        for slot in v.sensors:
            x = value(slot.sensor)
            if x is not None:
                out.setdefault(v.id, {})[slot.name] = x
    return out


def _camera_boresights(engine: Engine) -> dict[str, dict[str, list[float]]]:
    """vehicle id -> camera name -> its true boresight error (roll, pitch, yaw about body x, y,
    z; deg; CameraSensor.boresight_error_deg), for the cameras that have one: the truth a
    navigator's boresight estimate is scored against."""
    def value(sensor):
        err = getattr(sensor, "boresight_error_deg", None)
        return [float(x) for x in err] if err is not None and np.any(err) else None

    return _camera_truths(engine, value)


def _camera_time_offsets(engine: Engine) -> dict[str, dict[str, float]]:
    """vehicle id -> camera name -> its frames' stamp minus their true exposure time (s;
    CameraSensor.time_offset_s), for the cameras whose clock is off: the truth an estimate of
    the offset is scored against."""
    return _camera_truths(engine, lambda sensor: float(getattr(sensor, "time_offset_s", 0.0)) or None)


def _camera_intrinsics_errors(engine: Engine) -> dict[str, dict[str, dict[str, Any]]]:
    """vehicle id -> camera name -> {focal_error_rel, principal_point_error_px: [u, v]} of its
    true intrinsics against the calibrated ones (CameraSensor.intrinsics_error), for the cameras
    that have an error."""
    def value(sensor):
        err = getattr(sensor, "intrinsics_error", None)
        if err is None or not any(err):
            return None
        return {"focal_error_rel": float(err[0]), "principal_point_error_px": [float(err[1]), float(err[2])]}

    return _camera_truths(engine, value)


def _aid_counters(engine: Engine) -> dict[str, dict[str, dict[str, int]]]:
    """vehicle id -> aid class -> its event counters (aids with all_counters(), e.g. relnav:
    tracks born and revoked IDs, bearings fused, refused as ambiguous, filter resets), for
    diagnosing a run without rerunning it."""
    out: dict[str, dict[str, dict[str, int]]] = {}
    for v in engine.vehicles:
        for aid in v.aids:
            counters = getattr(aid, "all_counters", None)
            if callable(counters):
                out.setdefault(v.id, {})[type(aid).__name__] = {k: int(n) for k, n in counters().items()}
    return out


def _gnss_denied_windows(vehicle_spec, sim_time_s: float) -> list[list[float]]:
    """[[start_s, end_s], ...] when the vehicle had no GNSS fix by configuration: its receivers'
    jamming windows (clipped to the run), or the whole run without a GNSS receiver. Degraded
    and spoofed windows still deliver fixes and are not listed."""
    if not any(s.type == "gnss" for s in vehicle_spec.sensors):
        return [[0.0, float(sim_time_s)]]
    return _gnss_denial_windows(vehicle_spec, sim_time_s, "jamming")


def _gnss_denial_windows(vehicle_spec, sim_time_s: float, kind: str) -> list[list[float]]:
    """[[start_s, end_s], ...] of the vehicle's GNSS receivers' denial windows of one kind
    ("jamming", "spoofing", "degraded"), clipped to the run, sorted."""
    from testbench.sensors.gnss import GnssParams

    windows = []
    for spec in (s for s in vehicle_spec.sensors if s.type == "gnss"):
        for w in GnssParams.model_validate(spec.params).denial:
            if w.type == kind and w.start_s < sim_time_s:
                windows.append([float(w.start_s), float(min(w.end_s, sim_time_s))])
    return sorted(windows)
