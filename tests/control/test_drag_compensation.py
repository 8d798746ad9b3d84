"""The multirotor velocity loop's rotor-drag compensation (controller drag_compensation) on the
JSBSim quad flying into a steady head wind. The estimate is built from truth here, the wind's
included (tests only; in a run the wind estimate is the navigator's, NavEstimate.wind_ne_mps).
"""

import dataclasses

import numpy as np
import pytest

from testbench.control import evaluate as ev
from testbench.control.evaluate_multirotor import waypoint_mission
from testbench.control.multirotor import MultirotorController
from testbench.core.errors import InputError

pytest.importorskip("jsbsim")

HEAD_WIND_NED_MPS = (-5.0, 0.0, 0.0)  # 5 m/s from the north: the quad flies north into it at 4 m/s


def _ground_speed_into_wind(drag_compensation: bool) -> np.ndarray:
    """North velocity (m/s) at 50 Hz over 30-50 s of a flight north at 4 m/s into the wind."""
    from testbench.dynamics.jsbsim_adapter import AirMass, InitialCondition, JSBSimDynamics

    ctx = ev.make_context("q", physics_rate_hz=200.0)
    mission = waypoint_mission(ctx, points=[(1000.0, 0.0)])
    dyn = JSBSimDynamics("tb_quad", ev.ORIGIN, 200.0, air=AirMass(wind_ned_mps=HEAD_WIND_NED_MPS))
    truth = dyn.reset(InitialCondition(pos_ned_m=(0.0, 0.0, -100.0)))
    params = MultirotorController.Params(max_speed_mps=4.0, accel_mps2=0.5, drag_compensation=drag_compensation)
    ctl = MultirotorController(params, ctx=ctx, mission=mission, aircraft=dyn.aircraft_meta)
    v_north = []
    for _ in range(50 * 50):
        est = dataclasses.replace(ev.truth_to_estimate(truth, False), wind_ne_mps=np.asarray(truth.wind_ned_mps[:2]))
        truth = dyn.step(ctl.update(truth.t_s, est), 0.02)
        if truth.t_s >= 30.0:
            v_north.append(truth.vel_ned_mps[0])
    return np.array(v_north)


def test_drag_compensation_holds_the_commanded_speed_into_a_head_wind():
    """9 m/s through the air drags about 3 m/s^2, more than the integrator holds (3 m/s of
    integrated error times k_vel_i 0.56, 1.7 m/s^2): without the compensation the proportional
    term carries the rest and the quad flies 0.51 m/s short of its command; with it, 0.00003."""
    without = _ground_speed_into_wind(False)
    compensated = _ground_speed_into_wind(True)
    assert 4.0 - without.mean() > 0.3  # the saturated integrator's deficit (measured 0.51 m/s)
    assert abs(compensated.mean() - 4.0) < 0.1


def test_drag_compensation_needs_a_rotor_drag_model():
    from testbench.dynamics.catalog import aircraft_meta

    ctx = ev.make_context("q")
    mission = waypoint_mission(ctx)
    meta = {k: v for k, v in aircraft_meta("tb_quad").items() if k != "rotor_drag_coefficient"}
    with pytest.raises(InputError, match="controller.params.drag_compensation: the aircraft's sidecar has no rotor drag"):
        MultirotorController(MultirotorController.Params(drag_compensation=True), ctx=ctx, mission=mission, aircraft=meta)
