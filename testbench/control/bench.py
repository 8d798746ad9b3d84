"""Benchmarks of the controllers' per-tick cost (for `testbench bench`).

control.fixed_wing_update_us: mean wall time of one FixedWingController.update on the
    racetrack (tb_fixedwing, 25 m/s, 800 m; legs and turns) at 50 Hz, status() at 10 Hz;
control.multirotor_update_us: the same for MultirotorController through the evaluation
    waypoints (tb_quad) at 100 Hz, status() at 10 Hz.
Method: fly the controller closed-loop on JSBSim once to record the estimates it sees, then
replay that sequence through fresh copies of the controller (best of `repeats`), so only the
controller is timed. The figures are per call, microseconds, one core.
"""

from __future__ import annotations

import copy
import math
import time

from testbench.control import evaluate as ev


def _record(dyn, controller, truth0, duration_s: float, rate_hz: float, with_airspeed: bool):
    """(an unused copy of the controller, [(t_s, NavEstimate), ...] it saw when flying)."""
    fresh = copy.deepcopy(controller)
    tr = ev.fly(dyn, controller, duration_s, rate_hz, truth0, with_airspeed=with_airspeed)
    return fresh, [(t, ev.truth_to_estimate(x, with_airspeed)) for t, x in zip(tr.t, tr.truth)]


def time_replay_us(controller, estimates, status_every: int = 1, repeats: int = 3) -> float:
    """Best-of-`repeats` mean time (us) of one update over the recorded estimates, with
    status() asked every `status_every` updates (the engine asks at the record rate)."""
    best = math.inf
    for _ in range(repeats):
        ctl = copy.deepcopy(controller)
        t0 = time.perf_counter()
        for k, (t_s, est) in enumerate(estimates):
            ctl.update(t_s, est)
            if k % status_every == 0:
                ctl.status()
        best = min(best, (time.perf_counter() - t0) / len(estimates))
    return best * 1e6


def fixed_wing_sequence(duration_s: float = 120.0, rate_hz: float = 50.0):
    from testbench.control.fixed_wing import FixedWingController
    from testbench.dynamics.jsbsim_adapter import InitialCondition

    ctx = ev.make_context()
    mission = ev.racetrack_mission(ctx)
    dyn = ev.make_dynamics("tb_fixedwing")
    start = mission.path(25.0)[0].start_ne_m
    truth = dyn.reset(InitialCondition(pos_ned_m=(float(start[0]), float(start[1]), -800.0), heading_rad=0.0, airspeed_mps=25.0))
    ev.clear_trim_settings(dyn)
    ctl = FixedWingController(FixedWingController.Params(), ctx=ctx, mission=mission, aircraft=dyn.aircraft_meta)
    return _record(dyn, ctl, truth, duration_s, rate_hz, with_airspeed=True)


def multirotor_sequence(duration_s: float = 60.0, rate_hz: float = 100.0):
    from testbench.control.evaluate_multirotor import waypoint_mission
    from testbench.control.multirotor import MultirotorController
    from testbench.dynamics.jsbsim_adapter import InitialCondition

    ctx = ev.make_context("quad0", physics_rate_hz=200.0)
    mission = waypoint_mission(ctx)
    dyn = ev.make_dynamics("tb_quad", physics_rate_hz=200.0)
    truth = dyn.reset(InitialCondition(pos_ned_m=(0.0, 0.0, -100.0), heading_rad=0.0, airspeed_mps=0.0))
    ctl = MultirotorController(MultirotorController.Params(), ctx=ctx, mission=mission, aircraft=dyn.aircraft_meta)
    return _record(dyn, ctl, truth, duration_s, rate_hz, with_airspeed=False)


def run_benchmarks() -> dict[str, float]:
    """Timings in microseconds per controller call (status recorded at 10 Hz, as the shipped
    scenarios do)."""
    return {
        "control.fixed_wing_update_us": time_replay_us(*fixed_wing_sequence(rate_hz=50.0), status_every=5),
        "control.multirotor_update_us": time_replay_us(*multirotor_sequence(rate_hz=100.0), status_every=10),
    }
