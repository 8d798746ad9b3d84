"""Engine benchmarks: the engine against bare JSBSim for the same steps, and real-time factors.

Overhead: the scenario runs through the engine while every command its controller issues is
captured; then a bare JSBSim of the same model, from the same initial condition, steps the
same number of physics steps, applying the captured commands at the same ticks (so it flies
the same trajectory). Both are timed in this process, alternately, several times.
"""

from __future__ import annotations

import time
from pathlib import Path

from testbench.config.loader import load_scenario
from testbench.sim.runner import build_engine
from testbench.sim.vehicle import initial_condition

SCENARIOS_DIR = Path(__file__).resolve().parents[2] / "scenarios"


def engine_overhead(scenario: str = "fixedwing_racetrack", duration_s: float = 120.0, repeats: int = 5) -> dict[str, float]:
    """{'engine.overhead_ratio', 'engine.engine_step_us', 'engine.bare_step_us', ...}.

    The engine run, the replay run (below) and the bare run alternate `repeats` times, each
    from a fresh build, and each ratio is of the fastest run of each kind: the least disturbed
    by the host's load (on a shared 2-core machine the bare step varied from 10 to 17 us
    between single runs a minute apart). The range of the per-repeat ratios is reported
    beside it (`engine.overhead_ratio_lo` / `_hi`)."""
    loaded = load_scenario(SCENARIOS_DIR / f"{scenario}.yaml", [f"duration_s={duration_s}"])
    captured: list[list] | None = None
    engine_s, replay_s, bare_s = [], [], []
    for _ in range(max(1, int(repeats))):
        res, engine, world, commands = _engine_run(loaded, captured)
        captured = captured if captured is not None else commands
        engine_s.append(res.wall_time_s)
        replay_s.append(_engine_run(loaded, captured, replay=True)[0].wall_time_s)
        bare_s.append(_bare_run(engine, world, loaded.scenario.physics_rate_hz, captured, res.ticks))
    n_steps, sim_time_s = res.ticks, res.sim_time_s
    pairs = [e / b for e, b in zip(engine_s, bare_s)]
    return {
        "engine.overhead_ratio": min(engine_s) / min(bare_s),
        "engine.overhead_ratio_lo": min(pairs),
        "engine.overhead_ratio_hi": max(pairs),
        "engine.orchestration_ratio": min(replay_s) / min(bare_s),
        "engine.engine_step_us": min(engine_s) / n_steps * 1e6,
        "engine.bare_step_us": min(bare_s) / n_steps * 1e6,
        "engine.real_time_factor": sim_time_s / min(engine_s),
    }


def _engine_run(loaded, captured: list[list] | None, replay: bool = False):
    """One run through the engine: (EngineResult, the engine, its world, each vehicle's commands).
    Without `captured`, every command the controllers issue is captured; with replay=True the
    controllers are replaced by a replay of `captured` (the autopilot's own cost removed;
    sensors, navigator, truth extraction, scheduling and recording remain)."""
    engine, world, _ = build_engine(loaded)
    log: list[list] = [[] for _ in engine.vehicles]
    for i, v in enumerate(engine.vehicles):
        if replay:
            it = iter(captured[i])
            v.controller.update = lambda t_s, est, reference=None, _it=it: next(_it)
        elif captured is None:
            update = v.controller.update

            def logged(t_s, est, reference=None, _u=update, _log=log[i]):
                cmd = _u(t_s, est, reference)
                _log.append(cmd)
                return cmd

            v.controller.update = logged
    res = engine.run()
    if res.aborted:
        raise RuntimeError(f"benchmark scenario aborted: {res.aborted}")
    return res, engine, world, log


def _bare_run(engine, world, physics_rate_hz: float, captured: list[list], n_steps: int) -> float:
    """Wall seconds of bare JSBSim models (fresh, at the initial conditions of the engine's
    vehicles, not timed) stepping n_steps physics steps with the captured commands applied at
    the ticks the engine applied them (so they fly the same trajectory)."""
    from testbench.dynamics.jsbsim_adapter import JSBSimDynamics

    bare = []
    for v in engine.vehicles:
        d = JSBSimDynamics(v.spec.aircraft, world.origin, physics_rate_hz, vehicle_id=v.id)
        d.reset(initial_condition(v.spec, world.origin))
        bare.append((d, v.control_every))
    t0 = time.perf_counter()
    for (d, every), cmds in zip(bare, captured):
        fdm_run = d.fdm.run
        apply = d._apply
        for i, cmd in enumerate(cmds):
            apply(cmd)
            for _ in range(min(every, n_steps - i * every)):
                fdm_run()
    return time.perf_counter() - t0


def scenario_rtf(name: str, duration_s: float, overrides: tuple[str, ...] = ()) -> float:
    """Real-time factor of a shipped scenario (shortened), through the whole engine."""
    loaded = load_scenario(SCENARIOS_DIR / f"{name}.yaml", [f"duration_s={duration_s}", *overrides])
    engine, _, _ = build_engine(loaded)
    res = engine.run()
    if res.aborted:
        raise RuntimeError(f"{name} aborted: {res.aborted}")
    return res.sim_time_s / res.wall_time_s


def sensor_suite_share(name: str, duration_s: float, overrides: tuple[str, ...] = ()) -> dict[str, float]:
    """Share of a run's wall time spent in its non-camera sensors' `measure` (IMU, magnetometer,
    barometer, GNSS, UWB, airspeed ...), timed around each call in the real engine, and the
    run's real-time factor. Cameras are excluded from the sum (their renders are the camera
    budget, not the sensor suite's)."""
    from testbench.sensors.camera import CameraSensor

    loaded = load_scenario(SCENARIOS_DIR / f"{name}.yaml", [f"duration_s={duration_s}", *overrides])
    engine, _, _ = build_engine(loaded)
    spent = [0.0]
    for v in engine.vehicles:
        for slot in v.sensors:
            if isinstance(slot.sensor, CameraSensor):
                continue
            measure = slot.sensor.measure

            def timed(truth, view, rng, _m=measure):
                t0 = time.perf_counter()
                try:
                    return _m(truth, view, rng)
                finally:
                    spent[0] += time.perf_counter() - t0

            slot.sensor.measure = timed
    res = engine.run()
    if res.aborted:
        raise RuntimeError(f"{name} aborted: {res.aborted}")
    return {"share": spent[0] / res.wall_time_s, "real_time_factor": res.sim_time_s / res.wall_time_s}


def run_benchmarks() -> dict[str, float]:
    return engine_overhead()
