"""Engine benchmarks: the engine against bare JSBSim for the same steps, and real-time factors.

Overhead: the scenario runs through the engine while every command its controller issues is
captured; then a bare JSBSim of the same model, from the same initial condition, steps the
same number of physics steps, applying the captured commands at the same ticks (so it flies
the same trajectory). Both are timed in this process, one after the other.
"""

from __future__ import annotations

import time
from pathlib import Path

from testbench.config.loader import load_scenario
from testbench.sim.runner import build_engine
from testbench.sim.vehicle import initial_condition

SCENARIOS_DIR = Path(__file__).resolve().parents[2] / "scenarios"


def engine_overhead(scenario: str = "fixedwing_racetrack", duration_s: float = 120.0) -> dict[str, float]:
    """{'engine.overhead_ratio', 'engine.engine_step_us', 'engine.bare_step_us', ...}."""
    loaded = load_scenario(SCENARIOS_DIR / f"{scenario}.yaml", [f"duration_s={duration_s}"])
    engine, world, _ = build_engine(loaded)
    captured: list[list] = [[] for _ in engine.vehicles]
    for v, log in zip(engine.vehicles, captured):
        update = v.controller.update

        def logged(t_s, est, reference=None, _u=update, _log=log):
            cmd = _u(t_s, est, reference)
            _log.append(cmd)
            return cmd

        v.controller.update = logged
    res = engine.run()
    if res.aborted:
        raise RuntimeError(f"benchmark scenario aborted: {res.aborted}")
    n_steps = res.ticks

    # Bare JSBSim: fresh models at the same initial conditions, the captured commands.
    from testbench.dynamics.jsbsim_adapter import JSBSimDynamics

    bare = []
    for v in engine.vehicles:
        d = JSBSimDynamics(v.spec.aircraft, world.origin, loaded.scenario.physics_rate_hz, vehicle_id=v.id)
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
    bare_s = time.perf_counter() - t0
    engine_s = res.wall_time_s
    # Orchestration alone: the same run again with the controllers replaced by a replay of
    # the captured commands (the autopilot's own cost removed; sensors, navigator, truth
    # extraction, scheduling and recording remain).
    engine2, _, _ = build_engine(loaded)
    for v, cmds in zip(engine2.vehicles, captured):
        it = iter(cmds)
        v.controller.update = lambda t_s, est, reference=None, _it=it: next(_it)
    res2 = engine2.run()
    return {
        "engine.overhead_ratio": engine_s / bare_s,
        "engine.orchestration_ratio": res2.wall_time_s / bare_s,
        "engine.engine_step_us": engine_s / n_steps * 1e6,
        "engine.bare_step_us": bare_s / n_steps * 1e6,
        "engine.real_time_factor": res.sim_time_s / engine_s,
    }


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
