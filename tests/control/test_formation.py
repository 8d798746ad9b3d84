"""Formation followers: the command moves a follower toward its slot given neighbour
estimates; collision margin; hold without neighbours; a short closed loop on JSBSim where a
quad follower converges on its slot behind a leader flying a mission."""

import math

import numpy as np
import pytest

from testbench.control.formation import FormationLaw, FormationParams, formation_errors
from testbench.control.formation_followers import FormationFollower
from testbench.core.interfaces import BuildContext, GeodeticOrigin
from testbench.core.messages import NavEstimate
from testbench.core.rotations import euler_to_quat
from testbench.navigation.relative.types import RelativeEstimate

SLOTS = {"lead": (0.0, 0.0, 0.0), "f1": (-50.0, -30.0, 0.0), "f2": (-50.0, 30.0, 0.0)}
Z3 = np.zeros((3, 3))


def _est(pos, vel=(0.0, 0.0, 0.0), yaw=0.0, t=0.0):
    return NavEstimate(t, np.asarray(pos, float), np.asarray(vel, float), euler_to_quat([0.0, 0.0, yaw]),
                       np.array([0.0, 0.0, yaw]), np.zeros(3), Z3, Z3, Z3)


def _rel(peer, r, w=(0.0, 0.0, 0.0), t=0.0):
    return RelativeEstimate(t, peer, np.asarray(r, float), np.asarray(w, float), np.eye(3) * 0.01, np.eye(3) * 0.01)


def test_command_moves_follower_toward_slot():
    law = FormationLaw(FormationParams(slots=SLOTS, leader_id="lead", k_slot=0.4, margin_m=5.0), "f1")
    # Leader flies east at 5 m/s (course 90 deg); f1 sits 10 m too far behind and 5 m too high.
    course = math.pi / 2
    R = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1.0]])  # formation -> NED for course 90 deg
    slot_rel = R @ (np.array(SLOTS["lead"]) - np.array(SLOTS["f1"]))  # where the leader should be
    err = np.array([0.0, 10.0, 5.0])  # leader appears 10 m further east and 5 m lower than desired
    own_vel = np.array([0.0, 5.0, 0.0])
    v = None
    for k in range(50):  # the leader's velocity = own velocity + zero relative velocity
        v = law.velocity_command(0.1 * k, _est((0, 0, -100.0), own_vel, yaw=course, t=0.1 * k),
                                 {"lead": _rel("lead", slot_rel + err, t=0.1 * k)})
    assert law.course == pytest.approx(course, abs=1e-6)
    np.testing.assert_allclose(law.error_ned_m, err, atol=1e-9)
    # Feed-forward of the leader's velocity (5 m/s east) plus the slot correction toward err.
    assert v[1] > 5.0 and v[2] > 0.0 and abs(v[0]) < 1e-6
    assert np.dot(v - own_vel, err) > 0


def test_consensus_over_two_neighbours_and_repulsion():
    p = FormationParams(slots=SLOTS, leader_id="lead", leader_weight=1.0, margin_m=20.0, k_repulse=1.0, k_slot=0.1,
                        ahead_only=False)
    law = FormationLaw(p, "f1")
    # Exactly in slot relative to both: zero error, zero command at rest.
    est = _est((0, 0, -100.0), (1e-9, 0, 0))
    table = {"lead": _rel("lead", (50.0, 30.0, 0.0)), "f2": _rel("f2", (0.0, 60.0, 0.0))}
    v = law.velocity_command(0.0, est, table)
    np.testing.assert_allclose(law.error_ned_m, 0.0, atol=1e-12)
    np.testing.assert_allclose(v, 0.0, atol=1e-6)
    # f2 estimated 8 m to the east (inside the 20 m margin): pushed west despite the slot error.
    table["f2"] = _rel("f2", (0.0, 8.0, 0.0))
    v = law.velocity_command(0.1, est, table)
    assert v[1] < 0.0


def test_ahead_only_ignores_followers_alongside_and_slew_limit():
    law = FormationLaw(FormationParams(slots=SLOTS, leader_id="lead", k_slot=0.5, max_accel_mps2=1.0), "f1")
    est = _est((0, 0, -100.0), (1e-9, 0, 0))
    # f2 (alongside, not ahead) says f1 is 10 m off; the leader says f1 is in its slot.
    table = {"lead": _rel("lead", (50.0, 30.0, 0.0)), "f2": _rel("f2", (10.0, 60.0, 0.0))}
    law.velocity_command(0.0, est, table)
    np.testing.assert_allclose(law.error_ned_m, 0.0, atol=1e-12)
    assert law.n_seen == 1
    # Without the leader, the followers alongside are used.
    law.velocity_command(0.1, est, {"f2": table["f2"]})
    np.testing.assert_allclose(law.error_ned_m, [10.0, 0.0, 0.0], atol=1e-12)
    # The command moved by at most max_accel * dt from the previous one (0).
    v = law.velocity_command(0.2, est, {"f2": table["f2"]})
    assert np.linalg.norm(v) <= 1.0 * 0.2 + 1e-9


def test_uncertain_estimates_are_ignored():
    law = FormationLaw(FormationParams(slots=SLOTS, leader_id="lead", max_sigma_m=3.0), "f1")
    wide = RelativeEstimate(0.0, "lead", np.array([60.0, 30.0, 0.0]), np.zeros(3), np.eye(3) * 25.0, np.eye(3))
    law.velocity_command(0.0, _est((0, 0, -100.0)), {"lead": wide})
    assert law.n_seen == 0


def test_hold_course_speed_and_altitude_without_neighbours():
    law = FormationLaw(FormationParams(slots=SLOTS), "f2")
    v0 = law.velocity_command(0.0, _est((0, 0, -100.0), (3.0, 4.0, 0.0), yaw=0.9), {})
    v1 = law.velocity_command(1.0, _est((30, 40, -95.0), (3.0, 4.0, 0.0)), {"lead": _rel("lead", (1, 1, 1), t=-10.0)})
    np.testing.assert_allclose(v0[:2], [3.0, 4.0])
    np.testing.assert_allclose(v1[:2], [3.0, 4.0])
    assert v1[2] < 0  # back up to the altitude where it lost its neighbours


def test_formation_errors_for_scoring():
    pos = {"lead": np.array([100.0, 0, -50]), "f1": np.array([50.0, -30, -50]), "f2": np.array([52.0, 30, -50])}
    e = formation_errors(pos, 0.0, SLOTS, "lead")
    np.testing.assert_allclose(e["f1"], 0.0, atol=1e-12)
    np.testing.assert_allclose(e["f2"], [2.0, 0, 0])


@pytest.mark.slow
def test_quad_follower_holds_slot_behind_leader_on_jsbsim():
    pytest.importorskip("jsbsim")
    from testbench.control.evaluate import make_dynamics, truth_to_estimate
    from testbench.control.evaluate_multirotor import waypoint_mission
    from testbench.control.multirotor import MultirotorController
    from testbench.dynamics.jsbsim_adapter import InitialCondition

    origin = GeodeticOrigin(math.radians(34.0), math.radians(-117.0), 300.0)
    ctx_l = BuildContext("lead", ("lead", "f1"), origin, physics_rate_hz=200.0)
    ctx_f = BuildContext("f1", ("lead", "f1"), origin, physics_rate_hz=200.0)
    mission = waypoint_mission(ctx_l, 60.0, points=[(400.0, 0.0), (400.0, 400.0)])
    dl, df = make_dynamics("tb_quad", 200.0), make_dynamics("tb_quad", 200.0)
    tl = dl.reset(InitialCondition(pos_ned_m=(0.0, 0.0, -60.0), heading_rad=0.0, airspeed_mps=0.0))
    tf = df.reset(InitialCondition(pos_ned_m=(-30.0, -50.0, -55.0), heading_rad=0.0, airspeed_mps=0.0))
    lead = MultirotorController(MultirotorController.Params(max_speed_mps=4.0), ctx=ctx_l, mission=mission, aircraft=dl.aircraft_meta)
    fol = FormationFollower(FormationFollower.Params(slots=SLOTS, leader_id="lead", margin_m=10.0, max_speed_mps=8.0),
                            ctx=ctx_f, aircraft=df.aircraft_meta)
    rng = np.random.default_rng(0)
    errs = []
    for k in range(int(60.0 * 50)):  # 60 s at 50 Hz
        t = k / 50.0
        # The test builds the neighbour estimate from truth plus noise (the relnav aid's job).
        rel = tl.pos_ned_m - tf.pos_ned_m + rng.normal(0, 0.2, 3)
        table = {"lead": _rel("lead", rel, tl.vel_ned_mps - tf.vel_ned_mps, t)}
        cl = lead.update(t, truth_to_estimate(tl, False))
        cf = fol.update(t, truth_to_estimate(tf, False), table)
        tl, tf = dl.step(cl, 0.02), df.step(cf, 0.02)
        course = math.atan2(tl.vel_ned_mps[1], tl.vel_ned_mps[0])
        errs.append(np.linalg.norm(formation_errors({"lead": tl.pos_ned_m, "f1": tf.pos_ned_m}, course, SLOTS, "lead")["f1"]))
    errs = np.array(errs)
    print(f"formation error: start {errs[0]:.1f} m, last 10 s max {errs[-500:].max():.2f} m")
    assert errs[0] > 10.0
    assert errs[-500:].max() < 3.0  # last 10 s: on the slot within 3 m while the leader cruises


@pytest.mark.slow
def test_fixed_wing_follower_converges_on_a_straight_leg():
    pytest.importorskip("jsbsim")
    from testbench.control import evaluate as ev
    from testbench.control.fixed_wing import FixedWingController
    from testbench.control.formation_followers import FixedWingFormationFollower
    from testbench.dynamics.jsbsim_adapter import InitialCondition

    slots = {"lead": (0.0, 0.0, 0.0), "f1": (-60.0, -40.0, 0.0)}
    ctx_l = BuildContext("lead", ("lead", "f1"), ev.ORIGIN)
    ctx_f = BuildContext("f1", ("lead", "f1"), ev.ORIGIN)
    mission = ev.racetrack_mission(ctx_l, altitude_m=300.0, leg_length_m=3000.0)
    dl, df = ev.make_dynamics("tb_fixedwing"), ev.make_dynamics("tb_fixedwing")
    tl = dl.reset(InitialCondition(pos_ned_m=(0.0, 0.0, -300.0), heading_rad=0.0, airspeed_mps=25.0))
    tf = df.reset(InitialCondition(pos_ned_m=(-80.0, -20.0, -290.0), heading_rad=0.0, airspeed_mps=25.0))
    ev.clear_trim_settings(dl)
    ev.clear_trim_settings(df)
    lead = FixedWingController(FixedWingController.Params(), ctx=ctx_l, mission=mission, aircraft=dl.aircraft_meta)
    fol = FixedWingFormationFollower(FixedWingFormationFollower.Params(slots=slots, leader_id="lead", k_slot=0.1, margin_m=20.0),
                                     ctx=ctx_f, aircraft=df.aircraft_meta)
    errs = []
    for k in range(60 * 50):  # 60 s at 50 Hz, on the first straight leg after the entry
        t = k / 50.0
        table = {"lead": _rel("lead", tl.pos_ned_m - tf.pos_ned_m, tl.vel_ned_mps - tf.vel_ned_mps, t)}
        cl, cf = lead.update(t, ev.truth_to_estimate(tl)), fol.update(t, ev.truth_to_estimate(tf), table)
        tl, tf = dl.step(cl, 0.02), df.step(cf, 0.02)
        course = math.atan2(tl.vel_ned_mps[1], tl.vel_ned_mps[0])
        errs.append(np.linalg.norm(formation_errors({"lead": tl.pos_ned_m, "f1": tf.pos_ned_m}, course, slots, "lead")["f1"]))
    assert errs[0] > 20.0 and max(errs[-500:]) < 2.0


def test_geometry_course_recovers_the_formations_orientation():
    """The Procrustes fit of the followed neighbours' slots onto their estimated relative
    positions gives the formation course, wherever we are ourselves (our offset cancels)."""
    from testbench.control.formation import formation_rotation, geometry_course

    slots = {"a": (0.0, 0.0, 0.0), "b": (-86.6, -50.0, 0.0), "c": (-86.6, 50.0, 0.0), "me": (-173.2, 0.0, 0.0)}
    rng = np.random.default_rng(0)
    for chi in np.radians([0.0, 25.0, -140.0, 179.0]):
        R = formation_rotation(chi)
        own_error = np.array([7.0, -4.0, 0.0])  # we are off our slot: must not matter
        nbs = [_rel(k, R @ (np.asarray(slots[k]) - slots["me"]) - own_error + rng.normal(0, 0.3, 3)) for k in "abc"]
        got = geometry_course(nbs, slots, 30.0)
        assert abs(math.remainder(got - chi, 2 * math.pi)) < math.radians(0.5)
    assert geometry_course(nbs[:1], slots, 30.0) is None  # one neighbour: no orientation
    assert geometry_course(nbs[1:], slots, 80.0) is None  # b, c spread 50 m RMS < 80


def test_course_slew_limit_bounds_a_jump_of_the_layout_course():
    """The followed neighbours' layout turning 10 deg at once (a neighbour ahead lagging its
    slot, or the followed set changing) moves the course held by at most max_course_slew_deg_s
    per second; without the limit the course follows within a few geometry time constants."""
    from testbench.control.formation import formation_rotation

    slots = {"a": (0.0, 0.0, 0.0), "b": (0.0, 100.0, 0.0), "me": (-100.0, 50.0, 0.0)}

    def table(chi, t):
        R = formation_rotation(chi)
        return {k: _rel(k, R @ (np.asarray(slots[k]) - slots["me"]), t=t) for k in "ab"}

    courses = {}
    for slew in (None, 0.6):
        law = FormationLaw(FormationParams(slots=slots, leader_id="a", max_course_slew_deg_s=slew, geometry_tau_s=1.0), "me")
        for k in range(50):  # 1 s settled on course 0
            law.velocity_command(0.02 * k, _est((0, 0, -100.0), (1e-9, 0, 0), t=0.02 * k), table(0.0, 0.02 * k))
        assert abs(law.course) < 1e-9
        for k in range(50, 300):  # 5 s with the layout turned by 10 deg
            law.velocity_command(0.02 * k, _est((0, 0, -100.0), (1e-9, 0, 0), t=0.02 * k), table(math.radians(10.0), 0.02 * k))
        courses[slew] = math.degrees(law.course)
    assert courses[None] == pytest.approx(10.0, abs=0.1)
    assert courses[0.6] == pytest.approx(0.6 * 5.0, abs=0.05)  # slewing at the limit all along


def test_course_coasts_on_its_rate_when_the_layout_is_lost():
    """Two neighbours ahead give the layout course, turning at 0.5 deg/s; then one goes stale
    and the other flies 20 deg off the course (off the turn's pivot). With course_coast_s the
    course carries on at its rate; without, it swings to that neighbour's velocity."""
    from testbench.control.formation import formation_rotation

    slots = {"lead": (0.0, 0.0, 0.0), "a": (0.0, -50.0, 0.0), "b": (0.0, 50.0, 0.0), "me": (-100.0, 0.0, 0.0)}
    rate = math.radians(0.5)
    final = {}
    for coast in (0.0, 20.0):
        law = FormationLaw(FormationParams(slots=slots, leader_id="lead", course_coast_s=coast, ff_tau_s=0.5), "me")
        for k in range(1500):  # 30 s at 50 Hz; b is lost after 20 s
            t = 0.02 * k
            chi = rate * t
            R = formation_rotation(chi)
            v_a = 4.0 * np.array([math.cos(chi + math.radians(20.0)), math.sin(chi + math.radians(20.0)), 0.0])
            table = {"a": _rel("a", R @ (np.asarray(slots["a"]) - slots["me"]), w=v_a, t=t)}
            if t < 20.0:
                table["b"] = _rel("b", R @ (np.asarray(slots["b"]) - slots["me"]), w=v_a, t=t)
            law.velocity_command(t, _est((0, 0, -100.0), (1e-9, 0, 0), t=t), table)
        final[coast] = math.degrees(law.course_lead) - math.degrees(rate * 29.98)
    assert abs(final[20.0]) < 0.5  # coasting at the course rate
    assert final[0.0] == pytest.approx(20.0, abs=1.0)  # the neighbour's velocity course


def test_course_from_the_layout_beside_when_one_neighbour_is_ahead():
    """The formation turns at 0.5 deg/s. Of our neighbours only `a` is ahead, and it flies 20
    deg off the course (off the turn's pivot); `c` is beside us, in our row. The layout of `a`
    and `c` keeps the course for as long as the turn lasts; with `a` alone the coast runs out
    after course_coast_s and the course swings to a's velocity."""
    from testbench.control.formation import formation_rotation

    slots = {"lead": (0.0, 0.0, 0.0), "a": (-86.6, -50.0, 0.0), "c": (-173.2, 0.0, 0.0), "me": (-173.2, 100.0, 0.0)}
    rate = math.radians(0.5)
    final = {}
    for peers in ("ac", "a"):
        law = FormationLaw(FormationParams(slots=slots, leader_id="lead", course_coast_s=20.0, ff_tau_s=0.5,
                                           geometry_tau_s=1.0), "me")
        for k in range(3000):  # 60 s at 50 Hz
            t = 0.02 * k
            chi = rate * t
            R = formation_rotation(chi)
            v = 4.0 * np.array([math.cos(chi + math.radians(20.0)), math.sin(chi + math.radians(20.0)), 0.0])
            table = {p: _rel(p, R @ (np.asarray(slots[p]) - slots["me"]), w=v, t=t) for p in peers}
            law.velocity_command(t, _est((0, 0, -100.0), (1e-9, 0, 0), t=t), table)
        final[peers] = math.degrees(law.course_lead) - math.degrees(rate * 59.98)
    assert abs(final["ac"]) < 0.5
    assert abs(final["a"]) > 5.0


def test_velocity_course_is_smoothed_more_at_low_speed():
    """A follower whose only neighbour ahead is the leader takes the course from the leader's
    velocity (own velocity + relative velocity). The leader speeds up from 1 to 3 m/s along
    north while its relative velocity errs across by 0.15 m/s (correlated over 1 s): with
    course_full_speed_mps the velocity course is smoothed by (full / speed)^2 and errs far less;
    at or above that speed the two laws give the same course."""
    slots = {"lead": (0.0, 0.0, 0.0), "me": (-86.6, -50.0, 0.0)}
    rng = np.random.default_rng(3)
    a = math.exp(-0.02 / 1.0)
    noise = np.zeros(1500)
    for k in range(1, len(noise)):
        noise[k] = a * noise[k - 1] + 0.15 * math.sqrt(1 - a * a) * rng.standard_normal()

    def courses(full, speed_at):
        law = FormationLaw(FormationParams(slots=slots, leader_id="lead", ff_tau_s=2.0, course_full_speed_mps=full), "me")
        out = []
        for k in range(len(noise)):
            t = 0.02 * k
            table = {"lead": _rel("lead", (86.6, 50.0, 0.0), w=(0.0, noise[k], 0.0), t=t)}
            law.velocity_command(t, _est((0, 0, -100.0), (speed_at(t), 0.0, 0.0), t=t), table)
            out.append(law.course)
        return np.degrees(out)

    ramp = lambda t: 1.0 + 2.0 * min(t / 30.0, 1.0)  # noqa: E731 -- 1 -> 3 m/s over 30 s
    rms = {full: float(np.sqrt(np.mean(courses(full, ramp)[:500] ** 2))) for full in (None, 3.0)}  # 1-1.7 m/s
    assert rms[3.0] < 0.3 * rms[None], rms  # (with this noise 0.7 deg against 2.7 deg)
    cruise = lambda t: 3.0  # noqa: E731
    np.testing.assert_array_equal(courses(3.0, cruise), courses(None, cruise))


def test_course_acceleration_removes_the_second_order_lag_of_a_turn_entry():
    """The formation rolls into a 0.5 deg/s turn at 0.025 deg/s^2 (the leader's roll-in), holds
    it, and rolls out. We sit exactly on our slot, our neighbours on theirs with the velocities
    of the turning formation. The course low-pass and its rate's low-pass lag such a turn
    entry by (tau tau_w) alpha in course and (tau + tau_w) alpha in rate; estimating alpha
    (course_accel_tau_s) takes most of it out of the course, and so part of the velocity
    command's error (the rate in v_rot is left as it is)."""
    from testbench.control.formation import formation_rotation

    slots = {"lead": (0.0, 0.0, 0.0), "a": (-86.6, -50.0, 0.0), "b": (-86.6, 50.0, 0.0), "me": (-173.2, -100.0, 0.0)}
    alpha = math.radians(0.025)

    def course_and_rate(t):
        if t < 20.0:
            return 0.0, 0.0
        if t < 40.0:
            return 0.5 * alpha * (t - 20.0) ** 2, alpha * (t - 20.0)
        w = 20.0 * alpha
        if t < 80.0:
            return 10.0 * w + w * (t - 40.0), w
        if t < 100.0:
            return 50.0 * w + w * (t - 80.0) - 0.5 * alpha * (t - 80.0) ** 2, w - alpha * (t - 80.0)
        return 60.0 * w, 0.0

    def velocity(slot, chi, w):  # the rigid formation pivoting about the leader
        arm = formation_rotation(chi) @ (np.asarray(slot, float) - slots["lead"])
        return 4.0 * np.array([math.cos(chi), math.sin(chi), 0.0]) + w * np.array([-arm[1], arm[0], 0.0])

    rms = {}
    for tau_a in (0.0, 2.0):
        law = FormationLaw(FormationParams(slots=slots, leader_id="lead", geometry_tau_s=2.0, course_rate_tau_s=2.0,
                                           ff_tau_s=2.0, course_accel_tau_s=tau_a, k_slot=0.7, max_accel_mps2=10.0), "me")
        course_err, vel_err = [], []
        for k in range(6000):  # 120 s at 50 Hz
            t = 0.02 * k
            chi, w = course_and_rate(t)
            R = formation_rotation(chi)
            v_me = velocity(slots["me"], chi, w)
            table = {p: _rel(p, R @ (np.asarray(slots[p]) - slots["me"]), w=velocity(slots[p], chi, w) - v_me, t=t) for p in "ab"}
            v_cmd = law.velocity_command(t, _est((0, 0, -100.0), v_me, t=t), table)
            if t >= 20.0:
                course_err.append(math.remainder(law.course_lead - chi, 2 * math.pi))
                vel_err.append(float(np.linalg.norm((v_cmd - v_me)[:2])))
        rms[tau_a] = (math.degrees(math.sqrt(np.mean(np.square(course_err)))), math.sqrt(np.mean(np.square(vel_err))))
    assert rms[0.0][0] > 0.04 and rms[0.0][1] > 0.15  # degrees, m/s: the lag this removes is there
    assert rms[2.0][0] < 0.4 * rms[0.0][0]
    assert rms[2.0][1] < 0.75 * rms[0.0][1]


def test_course_acceleration_is_held_at_zero_below_the_full_speed():
    """Below course_full_speed_mps the course's second difference is the start-up's wander, not
    a turn: the estimated acceleration stays 0 while the layout turns at a growing rate."""
    from testbench.control.formation import formation_rotation

    slots = {"lead": (0.0, 0.0, 0.0), "a": (-86.6, -50.0, 0.0), "b": (-86.6, 50.0, 0.0), "me": (-173.2, 0.0, 0.0)}
    alpha = math.radians(0.05)
    for speed, expect_zero in ((1.5, True), (4.0, False)):
        law = FormationLaw(FormationParams(slots=slots, leader_id="lead", geometry_tau_s=2.0, course_rate_tau_s=2.0,
                                           course_accel_tau_s=2.0, course_full_speed_mps=3.0), "me")
        for k in range(1000):  # 20 s at 50 Hz, the layout's rate growing at alpha
            t = 0.02 * k
            R = formation_rotation(0.5 * alpha * t * t)
            vel = (speed, 0.0, 0.0)
            table = {p: _rel(p, R @ (np.asarray(slots[p]) - slots["me"]), t=t) for p in ("lead", "a", "b")}
            law.velocity_command(t, _est((0, 0, -100.0), vel, t=t), table)
        if expect_zero:
            assert law.course_accel_rps2 == 0.0
        else:
            assert law.course_accel_rps2 == pytest.approx(alpha, rel=0.2)
