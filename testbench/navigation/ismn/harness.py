"""Offline ISMN harness: replay the camera frames of a recorded run through the pipeline.

A scenario run records, at 10 Hz, the true pose and the navigator's estimate (pose and
sigmas) in telemetry.parquet. This harness renders the scenario's camera at the true poses of
chosen frames (the engine's own camera sensor and world, so the imagery is what the run saw),
hands the pipeline the recorded estimate, and compares each fix with the truth. Open loop: the
fixes do not feed back into the estimate, so pipeline changes can be compared frame by frame in
seconds instead of re-running the scenario.

    testbench ismn replay scenarios/paper_ismn_800m.yaml RUN_DIR \
        [--t0 60 --t1 600 --step 0.5] [--pipeline '{"n_sigma": 3}'] [--matcher '{"tiles_x": 9}']
        [--frames-dir /tmp/ismn_frames] [--save-bad 5.0 --save-dir /tmp/bad]

Frames are cached as grey PNG in --frames-dir (rendering costs more than matching).
"""

from __future__ import annotations

import json
import math
import os
import time

import cv2
import numpy as np

from testbench.core.messages import NavEstimate, TruthState
from testbench.core.rotations import quat_to_dcm


def _euler_cov(row) -> np.ndarray:
    return np.diag([row.nav_sigma_roll_rad**2, row.nav_sigma_pitch_rad**2, row.nav_sigma_yaw_rad**2])


def estimate_of(row) -> NavEstimate:
    """NavEstimate from one telemetry row (marginal covariances from the recorded sigmas)."""
    cne = float(getattr(row, "nav_cov_ne_m2", 0.0) or 0.0)
    cov_pos = np.array([[row.nav_sigma_north_m**2, cne, 0.0], [cne, row.nav_sigma_east_m**2, 0.0],
                        [0.0, 0.0, row.nav_sigma_down_m**2]])
    q = np.array([row.nav_qw, row.nav_qx, row.nav_qy, row.nav_qz])
    return NavEstimate(float(row.t_s), np.array([row.nav_north_m, row.nav_east_m, row.nav_down_m]),
                       np.array([row.nav_vn_mps, row.nav_ve_mps, row.nav_vd_mps]), q,
                       np.array([row.nav_roll_rad, row.nav_pitch_rad, row.nav_yaw_rad]), np.zeros(3), cov_pos,
                       np.eye(3) * 0.01, _euler_cov(row))


def truth_of(row) -> TruthState:
    z = np.zeros(3)
    return TruthState(float(row.t_s), 0.0, 0.0, 0.0, np.array([row.truth_north_m, row.truth_east_m, row.truth_down_m]),
                      np.array([row.truth_vn_mps, row.truth_ve_mps, row.truth_vd_mps]),
                      np.array([row.truth_qw, row.truth_qx, row.truth_qy, row.truth_qz]),
                      np.array([row.truth_roll_rad, row.truth_pitch_rad, row.truth_yaw_rad]),
                      np.array([row.truth_p_rps, row.truth_q_rps, row.truth_r_rps]), z, z, 25.0,
                      float(row.truth_height_agl_m), 101325.0, 288.15, z)


def build(scenario_path: str, overrides=(), pipeline_over: dict | None = None, matcher_over: dict | None = None,
          matcher_type: str | None = None):
    """(camera sensor, pipeline, run world) of the scenario's first vehicle with an ismn aid."""
    from testbench.config.loader import load_scenario
    from testbench.core.interfaces import BuildContext
    from testbench.core.registry import build as build_component
    from testbench.core.rng import RngStreams
    from testbench.navigation.ismn import IsmnParams, IsmnPipeline
    from testbench.navigation.ismn.pipeline import with_camera_readout
    from testbench.sensors.camera.sensor import CameraSensor
    from testbench.sim.runner import origin_of
    from testbench.sim.world_runtime import RunWorld

    loaded = load_scenario(scenario_path, list(overrides))
    scn = loaded.scenario
    # The scenario seed's streams draw what the world draws per run (clouds, anomaly): those
    # of a `testbench run` at that seed, not of a Monte Carlo run's own seed sequence.
    world = RunWorld(scn.world, origin_of(loaded), streams=RngStreams(scn.seed), epoch_year=scn.epoch_year)
    veh = scn.vehicles[0]
    aid = next(a for a in veh.aids if a.type == "ismn")
    ap = dict(aid.params)
    cam_spec = next(s for s in veh.sensors if (s.name or s.type) == ap["camera"])
    ctx = BuildContext(veh.id, (veh.id,), world.origin, physics_rate_hz=scn.physics_rate_hz, world=world)
    sensor = CameraSensor(CameraSensor.Params.model_validate(cam_spec.params), ctx=ctx)
    m = dict(ap.get("matcher", {}) or {})
    mparams = {**m.get("params", {}), **(matcher_over or {})}
    matcher = build_component("matcher", matcher_type or m.get("type", "ncc"), mparams, "matcher", ctx=ctx)
    pp = with_camera_readout(IsmnParams.model_validate({**ap.get("pipeline", {}), **(pipeline_over or {})}), sensor)
    pipe = IsmnPipeline(sensor.camera, sensor.mount, world.reference_map(), world.reference_elevation(), matcher, pp)
    return sensor, pipe, world


def frame_for(sensor, world, row, frames_dir: str | None, seed: int = 0) -> np.ndarray:
    """Grey uint8 frame at the row's true pose (cached as PNG under frames_dir)."""
    path = os.path.join(frames_dir, f"t{row.t_s:08.2f}.png") if frames_dir else None
    if path and os.path.exists(path):
        cached = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
        if cached is not None:
            return cached
    from testbench.sim.world_runtime import TickWorldView

    rng = np.random.default_rng([seed, int(round(row.t_s * 1000))])
    # The world as at the frame's time (its clouds have moved), without other vehicles.
    fr = sensor.measure(truth_of(row), TickWorldView(world, float(row.t_s), "", {}), rng)
    grey = cv2.cvtColor(fr.image, cv2.COLOR_RGB2GRAY)
    if path:
        # Written aside and renamed: another replay sharing the cache never reads half a file.
        os.makedirs(frames_dir, exist_ok=True)
        tmp = f"{path}.{os.getpid()}.png"
        cv2.imwrite(tmp, grey)
        os.replace(tmp, path)
    return grey


def recorded_rows(run_dir: str, t0_s: float, t1_s: float, step_s: float):
    """The run's telemetry rows (itertuples) from t0_s to t1_s, one every step_s."""
    import pandas as pd

    tel = pd.read_parquet(os.path.join(run_dir, "telemetry.parquet"))
    tel = tel[(tel.t_s >= t0_s - 1e-6) & (tel.t_s <= t1_s + 1e-6)]
    k = np.round(tel.t_s / step_s)
    return tel[np.abs(tel.t_s - k * step_s) < 1e-6].itertuples()


def run(args) -> list[dict]:
    cv2.setNumThreads(1)
    sensor, pipe, world = build(args.scenario, args.set or (), json.loads(args.pipeline or "{}"),
                                json.loads(args.matcher or "{}"), args.matcher_type)
    rows = []
    for row in recorded_rows(args.run_dir, args.t0, args.t1, args.step):
        img = frame_for(sensor, world, row, args.frames_dir)
        est = estimate_of(row)
        if args.est_truth:  # the true pose with the recorded sigmas, plus a chosen offset
            from dataclasses import replace
            q = np.array([row.truth_qw, row.truth_qx, row.truth_qy, row.truth_qz])
            off = np.array([float(v) for v in args.est_offset.split(",")]) if args.est_offset else np.zeros(3)
            est = replace(est, pos_ned_m=np.array([row.truth_north_m, row.truth_east_m, row.truth_down_m]) + off,
                          q_nb_wxyz=q, rpy_rad=np.array([row.truth_roll_rad, row.truth_pitch_rad, row.truth_yaw_rad]))
        t = time.perf_counter()
        fix, diag = pipe.process(img, float(row.t_s), est)
        wall = 1e3 * (time.perf_counter() - t)
        truth = np.array([row.truth_north_m, row.truth_east_m])
        psi_dot = (row.truth_q_rps * math.sin(row.truth_roll_rad) + row.truth_r_rps * math.cos(row.truth_roll_rad)) \
            / math.cos(row.truth_pitch_rad)
        r = dict(t_s=float(row.t_s), roll_deg=math.degrees(row.truth_roll_rad), turning=bool(
                 abs(row.truth_roll_rad) > math.radians(args.turn_bank_deg) or abs(psi_dot) > math.radians(args.turn_rate_deg_s)),
                 fix=fix is not None,
                 reason=diag.reason, quality=float(diag.peak_quality), ms=diag.latency_ms.get("ortho_to_fix", np.nan),
                 wall_ms=wall, est_err=float(np.hypot(*(est.pos_ned_m[:2] - truth))))
        if fix is not None:
            e = fix.pos_ned_m[:2] - truth
            s = np.sqrt(np.diag(fix.cov_ned_m2)[:2])
            r.update(err=float(np.hypot(*e)), en=float(e[0]), ee=float(e[1]), sn=float(s[0]), se=float(s[1]),
                     nees=float(e @ np.linalg.solve(fix.cov_ned_m2[:2, :2], e)), n_in=diag.n_inliers,
                     n_corr=diag.n_correspondences)
        if args.save_dir and (fix is None or r["err"] > args.save_bad):
            os.makedirs(args.save_dir, exist_ok=True)
            np.savez_compressed(os.path.join(args.save_dir, f"t{row.t_s:08.2f}.npz"), ortho=diag.ortho,
                                ortho_valid=diag.ortho_valid, map_window=diag.map_window,
                                origin=np.array(diag.window.bounds_ne_m if diag.window else [np.nan] * 4),
                                offset_px=np.asarray(diag.offset_px if diag.offset_px is not None else [np.nan, np.nan]))
        rows.append(r)
    return rows


def summarise(rows: list[dict]) -> dict:
    ok = [r for r in rows if r["fix"]]
    err = np.array([r["err"] for r in ok]) if ok else np.array([np.nan])
    turn = np.array([r["turning"] for r in ok], bool)
    nees = np.array([r["nees"] for r in ok]) if ok else np.array([np.nan])
    return dict(n=len(rows), fix_rate=len(ok) / max(1, len(rows)), mean=float(err.mean()), median=float(np.median(err)),
                p95=float(np.percentile(err, 95)), max=float(err.max()),
                smooth_mean=float(err[~turn].mean()) if (~turn).any() else np.nan,
                turn_mean=float(err[turn].mean()) if turn.any() else np.nan, n_turn=int(turn.sum()),
                nees_mean=float(nees.mean()), nees_gt_9_21=float((nees > 9.21).mean()),
                ms_p95=float(np.nanpercentile([r["ms"] for r in rows], 95)))
