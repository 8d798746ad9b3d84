"""Short closed-loop step responses on JSBSim against the designed bandwidths.

Fixed wing (tb_fixedwing, trimmed at 25 m/s, 800 m): bank, altitude and airspeed steps through
the autopilot's inner loops; multirotor (tb_quad): a short waypoint hop. The navigation
estimate is built from truth here (tests only; controllers never see truth otherwise).
"""

import math

import numpy as np
import pytest

from testbench.control import evaluate as ev
from testbench.control.design import linearize, roll_bandwidth_rps, roll_lqi
from testbench.control.fixed_wing import FixedWingController
from testbench.core.errors import InputError

pytest.importorskip("jsbsim")


@pytest.fixture(scope="module")
def roll_bw():
    lm = linearize("tb_fixedwing", 25.0, 800.0)
    k_phi, k_p, k_i, _ = roll_lqi(lm)
    return roll_bandwidth_rps(lm, k_phi, k_p, k_i)


def _fixed_wing():
    from testbench.dynamics.jsbsim_adapter import InitialCondition

    ctx = ev.make_context()
    mission = ev.racetrack_mission(ctx)
    dyn = ev.make_dynamics("tb_fixedwing")
    truth = dyn.reset(InitialCondition(pos_ned_m=(0.0, 0.0, -800.0), heading_rad=0.0, airspeed_mps=25.0))
    ev.clear_trim_settings(dyn)
    ctl = FixedWingController(FixedWingController.Params(), ctx=ctx, mission=mission, aircraft=dyn.aircraft_meta)
    return dyn, ctl, truth


def _step(dyn, ctl, truth, seconds, phi_c=0.0, dh=0.0, dv=0.0, rate=50.0):
    h0 = -truth.pos_ned_m[2]
    out = []
    for _ in range(int(seconds * rate)):
        cmd = ctl.autopilot(truth.t_s, ev.truth_to_estimate(truth), phi_c, h0 + dh, 25.0 + dv)
        truth = dyn.step(cmd, 1.0 / rate)
        out.append(truth)
    return out


def test_roll_step_within_designed_bandwidth(roll_bw):
    dyn, ctl, truth = _fixed_wing()
    phi_c = math.radians(20.0)
    tr = _step(dyn, ctl, truth, 4.0, phi_c=phi_c)
    t = np.array([x.t_s for x in tr]) - truth.t_s
    phi = np.array([x.rpy_rad[0] for x in tr])
    # A loop of bandwidth w reaches 90 % within about 2.2 / w (first order) plus the surface
    # saturation of a 20 deg step: allow 3 / w.
    t90 = t[np.argmax(phi >= 0.9 * phi_c)]
    assert 0.0 < t90 <= 3.0 / roll_bw + 0.2
    assert phi.max() <= phi_c * 1.15
    assert abs(phi[-1] - phi_c) < math.radians(1.5)


def test_altitude_step():
    dyn, ctl, truth = _fixed_wing()
    tr = _step(dyn, ctl, truth, 20.0, dh=5.0)
    dh = np.array([-x.pos_ned_m[2] for x in tr]) + truth.pos_ned_m[2]
    assert dh.max() < 5.0 + 1.0  # overshoot < 20 %
    assert abs(dh[-1] - 5.0) < 0.5
    assert abs(tr[-1].airspeed_mps - 25.0) < 0.5  # the LQI keeps airspeed through the climb


def test_airspeed_step():
    dyn, ctl, truth = _fixed_wing()
    tr = _step(dyn, ctl, truth, 20.0, dv=2.0)
    v = np.array([x.airspeed_mps for x in tr])
    assert v.max() < 27.0 + 0.6
    assert abs(v[-1] - 27.0) < 0.3
    assert abs(-tr[-1].pos_ned_m[2] + truth.pos_ned_m[2]) < 1.0


def test_multirotor_hop_reaches_waypoints_without_overshoot():
    from testbench.control.evaluate_multirotor import multirotor_metrics, waypoint_mission
    from testbench.control.multirotor import MultirotorController
    from testbench.dynamics.jsbsim_adapter import InitialCondition

    ctx = ev.make_context("q")
    mission = waypoint_mission(ctx, points=[(10.0, 0.0), (10.0, 10.0)])
    dyn = ev.make_dynamics("tb_quad", physics_rate_hz=200.0)
    truth = dyn.reset(InitialCondition(pos_ned_m=(0.0, 0.0, -100.0)))
    ctl = MultirotorController(MultirotorController.Params(), ctx=ctx, mission=mission, aircraft=dyn.aircraft_meta)
    tr = ev.fly(dyn, ctl, 25.0, 100.0, truth, with_airspeed=False)
    m = multirotor_metrics(tr, mission.waypoints_ned_m, np.array([0.0, 0.0, -100.0]))
    assert m["reach_max_m"] <= 1.0
    assert m["overshoot_max_m"] <= 3.0
    assert m["final_position_error_m"] < 0.5


def test_multirotor_fly_by_turn_is_a_rate_limited_arc():
    """With turn_rate_deg_s the course turns at most that fast, the turn starts R tan(turn/2)
    before the corner (R = speed / rate), so the track passes the corner on the inside by about
    R (1 / cos(turn/2) - 1) and needs no stop; accel_mps2 eases the start."""
    from testbench.control.evaluate_multirotor import waypoint_mission
    from testbench.control.multirotor import MultirotorController
    from testbench.dynamics.jsbsim_adapter import InitialCondition

    ctx = ev.make_context("q")
    mission = waypoint_mission(ctx, points=[(120.0, 0.0), (240.0, 120.0)])  # a 45 deg right turn
    dyn = ev.make_dynamics("tb_quad", physics_rate_hz=200.0)
    truth = dyn.reset(InitialCondition(pos_ned_m=(0.0, 0.0, -100.0)))
    params = MultirotorController.Params(max_speed_mps=5.0, corner_speed_mps=5.0, accel_mps2=0.5, turn_rate_deg_s=5.0)
    ctl = MultirotorController(params, ctx=ctx, mission=mission, aircraft=dyn.aircraft_meta)
    tr = ev.fly(dyn, ctl, 70.0, 100.0, truth, with_airspeed=False)
    t = np.array(tr.t)
    pos = np.array([x.pos_ned_m for x in tr.truth])
    vel = np.array([x.vel_ned_mps for x in tr.truth])
    speed = np.hypot(vel[:, 0], vel[:, 1])
    # Eased start: about 0.5 m/s^2 (the loops lag the shaped command a little).
    assert speed[t <= 4.0].max() < 2.5
    course = np.unwrap(np.arctan2(vel[:, 1], vel[:, 0]))
    moving = speed > 3.0
    rate = np.gradient(course[moving], t[moving])
    assert np.degrees(np.abs(rate)).max() < 5.0 * 1.3
    R = 5.0 / math.radians(5.0)
    inside = R * (1.0 / math.cos(math.radians(22.5)) - 1.0)  # 4.7 m
    d_corner = np.hypot(pos[:, 0] - 120.0, pos[:, 1]).min()
    assert 0.5 * inside < d_corner < 2.0 * inside
    far_from_end = np.hypot(pos[:, 0] - 240.0, pos[:, 1] - 120.0) > 20.0  # before braking for the end
    assert speed[(t > 15.0) & far_from_end].min() > 4.5  # no stop at the corner
    assert np.hypot(pos[-1, 0] - 240.0, pos[-1, 1] - 120.0) < 1.0


def test_turn_rate_of_the_shaped_command_rolls_in_and_out():
    """With turn_accel_deg_s2 the commanded course rate ramps up to turn_rate_deg_s and back to
    zero at that acceleration, and the course settles on the new direction without overshoot."""
    from testbench.control.evaluate_multirotor import waypoint_mission
    from testbench.control.multirotor import MultirotorController

    ctx = ev.make_context("q")
    mission = waypoint_mission(ctx, points=[(100.0, 0.0)])
    dyn = ev.make_dynamics("tb_quad", physics_rate_hz=200.0)
    params = MultirotorController.Params(max_speed_mps=4.0, turn_rate_deg_s=2.0, turn_accel_deg_s2=0.5)
    ctl = MultirotorController(params, ctx=ctx, mission=mission, aircraft=dyn.aircraft_meta)
    dt = 0.02
    ctl.shaper.last = (4.0, 0.0, 0.0)
    target = (4.0 * math.cos(math.radians(40.0)), 4.0 * math.sin(math.radians(40.0)), 0.0)  # 40 deg right
    courses = []
    for _ in range(2000):
        v = ctl.shaper.shape(target, dt)
        courses.append(math.degrees(math.atan2(v[1], v[0])))
    rate = np.diff(courses) / dt
    assert rate.max() <= 2.0 + 1e-6 and rate.max() > 1.9  # reaches the rate limit
    turning = np.asarray(courses[:-2]) < 40.0 - 0.05  # the last tick snaps onto the course
    assert np.abs(np.diff(rate) / dt)[turning].max() <= 0.5 + 1e-6  # rolls in and out at 0.5 deg/s^2
    assert max(courses) <= 40.0 + 1e-6 and courses[-1] == pytest.approx(40.0, abs=1e-6)


def test_speed_rise_of_the_shaped_command_is_an_s_curve():
    """With accel_jerk_mps3 the commanded speed's rate of rise ramps up to accel_mps2 and back
    to zero at that jerk, and the speed settles on the target without overshoot; without it the
    rate steps to accel_mps2 at once."""
    from testbench.control.evaluate_multirotor import waypoint_mission
    from testbench.control.multirotor import MultirotorController

    ctx = ev.make_context("q")
    mission = waypoint_mission(ctx, points=[(400.0, 0.0)])
    dyn = ev.make_dynamics("tb_quad", physics_rate_hz=200.0)
    dt = 0.02

    def speeds(**kw):
        params = MultirotorController.Params(max_speed_mps=4.0, accel_mps2=0.25, **kw)
        ctl = MultirotorController(params, ctx=ctx, mission=mission, aircraft=dyn.aircraft_meta)
        ctl.shaper.last = (0.0, 0.0, 0.0)
        return np.array([ctl.shaper.shape((4.0, 0.0, 0.0), dt)[0] for _ in range(2000)])

    s = speeds(accel_jerk_mps3=0.05)
    rate = np.diff(s) / dt
    assert rate.max() <= 0.25 + 1e-9 and rate.max() > 0.24  # reaches accel_mps2
    rising = s[1:-1] < 4.0 - 1e-3  # (the last tick snaps onto the speed)
    assert np.abs(np.diff(rate) / dt)[rising].max() <= 0.05 + 1e-6  # eases in and out at the jerk
    assert s[0] / dt <= 0.05 * dt + 1e-12  # no step at the start: the first tick rises at jerk dt
    assert s.max() <= 4.0 + 1e-9 and s[-1] == pytest.approx(4.0, abs=1e-9)
    assert np.all(np.diff(s) >= 0.0)
    # 0 -> 4 m/s at 0.25 m/s^2 takes 16 s; the two 5 s ramps add 5 s.
    # (20.7 s: in whole ticks the rise meets the speed with 0.016 m/s^2 of its rate left, and the
    # last tick snaps onto it.)
    assert np.argmax(s >= 4.0 - 1e-6) * dt == pytest.approx(21.0, abs=0.5)
    step = np.diff(speeds()) / dt
    assert step[0] == pytest.approx(0.25)  # without: the rate steps at once
    with pytest.raises(InputError, match="accel_jerk_mps3"):
        MultirotorController(MultirotorController.Params(max_speed_mps=4.0, accel_jerk_mps3=0.05), ctx=ctx,
                             mission=mission, aircraft=dyn.aircraft_meta)
