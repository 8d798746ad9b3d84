"""The controllers' scalar (plain-float) arithmetic against numpy/core.rotations references.

The per-tick code avoids numpy on 2- and 3-vectors for speed; these tests pin it to the
vectorised formulas it replaces (rotations, cross products, mixer allocation, turn
prediction, segment geometry), and check the status the controllers report.
"""

import math

import numpy as np
import pytest

from testbench.control import multirotor as mr
from testbench.control.fixed_wing import _dot
from testbench.control.guidance import PathFollower, predict_on_turn, predict_on_turn_ne
from testbench.control.mixer import Mixer, _max_scale
from testbench.control.paths import ArcSegment, LineSegment, passed_end, switching_normal_ne
from testbench.core.messages import GuidanceStatus, NavEstimate
from testbench.core.rotations import dcm_to_euler, euler_to_dcm, wrap_pi

RNG_SEED = 11


def _random_rpy(rng, n):
    return np.column_stack([rng.uniform(-1.4, 1.4, n), rng.uniform(-1.4, 1.4, n), rng.uniform(-math.pi, math.pi, n)])


def test_euler_helpers_match_core_rotations():
    rng = np.random.default_rng(RNG_SEED)
    for rpy in _random_rpy(rng, 200):
        R = euler_to_dcm(rpy)
        np.testing.assert_allclose(mr._body_z_axis_ned(*rpy), R[:, 2], rtol=0, atol=1e-15)
        cols = tuple(tuple(R[:, k]) for k in range(3))
        np.testing.assert_allclose(mr._euler_from_body_axes(*cols), dcm_to_euler(R), rtol=0, atol=1e-14)
        np.testing.assert_allclose(mr._euler_from_body_axes(*cols), rpy, rtol=0, atol=1e-12)  # round trip


def test_wrap_cross_normalize_dot_match_numpy():
    rng = np.random.default_rng(RNG_SEED)
    angles = np.concatenate([rng.uniform(-20, 20, 500), [-math.pi, math.pi, 0.0, 3 * math.pi, -3 * math.pi]])
    assert [mr._wrap_pi(float(a)) for a in angles] == [float(wrap_pi(a)) for a in angles]
    for _ in range(200):
        a, b = rng.normal(size=3), rng.normal(size=3)
        np.testing.assert_allclose(mr._cross(tuple(a), tuple(b)), np.cross(a, b), rtol=1e-14, atol=1e-15)
        np.testing.assert_allclose(mr._normalized(tuple(a)), a / np.linalg.norm(a), rtol=1e-15, atol=1e-15)
        k, x = rng.normal(size=7), rng.normal(size=7)
        assert _dot(tuple(k), tuple(x)) == pytest.approx(float(k @ x), rel=1e-12, abs=1e-14)


def _allocate_numpy(mixer: Mixer, thrust_n: float, moments) -> np.ndarray:
    """The allocation of mixer.py written with numpy arrays (the pre-scalar implementation)."""
    A, hi = mixer.allocation, mixer.max_thrust_n
    base = A[:, 0] * thrust_n
    rp = A[:, 1:3] @ np.asarray(moments[:2], float)
    yaw = A[:, 3] * float(moments[2])
    t = base + rp + yaw
    if np.all(t >= 0.0) and np.all(t <= hi):
        return t
    k_yaw = _max_scale(base + rp, yaw, hi)
    t = base + rp + k_yaw * yaw
    if np.all(t >= -1e-9) and np.all(t <= hi + 1e-9):
        return np.clip(t, 0.0, hi)
    k_rp = _max_scale(base, rp, hi)
    return np.clip(base + k_rp * rp, 0.0, hi)


def test_mixer_scalar_allocation_matches_numpy_including_saturation():
    from testbench.dynamics.catalog import aircraft_meta

    meta = aircraft_meta("tb_quad")
    mixer = Mixer(meta["motors"], meta["max_thrust_per_motor_n"], meta["yaw_torque_per_thrust_m"])
    rng = np.random.default_rng(RNG_SEED)
    hi = mixer.max_thrust_n
    saturated = 0
    for _ in range(300):
        thrust = rng.uniform(0.0, mixer.n * hi)
        m = rng.normal(0.0, [1.0, 1.0, 0.3])
        ref = _allocate_numpy(mixer, thrust, m)
        got = mixer.allocate(thrust, m)
        np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(mixer.commands(thrust, m), ref / hi, rtol=1e-12, atol=1e-12)
        saturated += not np.allclose(mixer.wrench(got), [thrust, *m], atol=1e-9)
    assert saturated > 30  # the saturation branches were exercised


def test_predict_on_turn_matches_rotation_matrix_form():
    rng = np.random.default_rng(RNG_SEED)
    for w in (0.0, 1e-8, 0.2, -0.35):
        p, v, dt = rng.normal(size=2) * 100, rng.normal(size=2) * 20, 0.7
        a = w * dt
        rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
        if abs(w) < 1e-6:
            disp = v * dt
        else:
            disp = np.array([[math.sin(a), math.cos(a) - 1.0], [1.0 - math.cos(a), math.sin(a)]]) @ v / w
        p1, v1 = predict_on_turn(p, v, w, dt)
        np.testing.assert_allclose(p1, p + disp, rtol=1e-13, atol=1e-12)
        np.testing.assert_allclose(v1, rot @ v, rtol=1e-13, atol=1e-12)
        np.testing.assert_allclose(predict_on_turn_ne(*p, *v, w, dt), [*p1, *v1], rtol=0, atol=0)


def test_segment_scalar_and_array_faces_agree_with_geometry():
    rng = np.random.default_rng(RNG_SEED)
    line = LineSegment(np.array([10.0, -5.0]), np.array([310.0, 395.0]))
    arc = ArcSegment(np.array([50.0, 20.0]), 120.0, 0.3, math.pi, -1)
    t = np.array([300.0, 400.0]) / 500.0
    for _ in range(100):
        p = rng.uniform(-300, 500, 2)
        d = p - line.start_ne_m
        along, cross = line.locate(p)
        assert along == pytest.approx(float(d @ t), abs=1e-9)
        assert cross == pytest.approx(float(t[0] * d[1] - t[1] * d[0]), abs=1e-9)  # right of travel positive
        for seg in (line, arc):
            assert seg.locate(p) == seg.locate_ne(*p)
            np.testing.assert_array_equal(seg.closest_point(p), seg.closest_point_ne(*p))
            hit = seg.l1_point(p, 80.0)
            if hit is not None:
                q, _ = hit
                assert np.hypot(*(q - p)) == pytest.approx(80.0, rel=1e-9)
                if seg is arc:
                    assert np.hypot(*(q - arc.center_ne_m)) == pytest.approx(arc.radius_m, rel=1e-12)
        q = arc.closest_point(p)
        assert arc.distance_m(p) <= np.hypot(*(p - arc.start_ne_m)) + 1e-9
        assert arc.distance_m(p) <= np.hypot(*(p - arc.end_ne_m)) + 1e-9
        assert np.hypot(*(q - arc.center_ne_m)) == pytest.approx(arc.radius_m)
    # Cached end points and tangents are the arc's own formulas.
    end_ang = arc.start_rad + arc.direction * arc.sweep_rad
    np.testing.assert_allclose(arc.end_ne_m, arc.center_ne_m + arc.radius_m * np.array([math.cos(end_ang), math.sin(end_ang)]))
    np.testing.assert_allclose(arc.tangent_at_end(), arc.direction * np.array([-math.sin(end_ang), math.cos(end_ang)]))


def test_switching_plane_is_the_corner_bisector_and_u_turn_falls_back():
    a = LineSegment(np.array([0.0, 0.0]), np.array([100.0, 0.0]))
    b = LineSegment(np.array([100.0, 0.0]), np.array([100.0, 100.0]))
    back = LineSegment(np.array([100.0, 0.0]), np.array([0.0, 0.0]))
    np.testing.assert_allclose(switching_normal_ne(a, b), [math.sqrt(0.5), math.sqrt(0.5)])
    assert switching_normal_ne(a, back) == (1.0, 0.0)
    assert switching_normal_ne(a, None) == (1.0, 0.0)
    assert passed_end(a, back, np.array([100.5, 50.0])) and not passed_end(a, back, np.array([99.5, -50.0]))
    half = ArcSegment(np.zeros(2), 100.0, 0.0, math.pi, 1)
    full = ArcSegment(np.zeros(2), 100.0, 0.0, 2 * math.pi, 1)
    assert passed_end(half, None, np.array([-100.0, -1.0])) and not passed_end(half, None, np.array([1.0, 100.0]))
    assert not passed_end(full, None, np.array([-100.0, -1.0]))


def test_path_follower_array_and_scalar_entries_agree():
    segs = (LineSegment(np.array([0.0, 0.0]), np.array([500.0, 0.0])), ArcSegment(np.array([500.0, 100.0]), 100.0, math.pi, math.pi, 1))
    f1, f2 = PathFollower(segs, closed=True), PathFollower(segs, closed=True)
    rng = np.random.default_rng(RNG_SEED)
    for k in range(60):
        p = np.array([10.0 * k, 0.0]) + rng.normal(0, 5, 2)
        v = np.array([25.0, 0.0]) + rng.normal(0, 2, 2)
        a = f1.update(np.r_[p, -800.0], np.r_[v, 0.1], lead_s=0.5, turn_rate_rps=0.05)
        b = f2.update_ne(*p, *v, lead_s=0.5, turn_rate_rps=0.05)
        assert (a.segment_index, a.accel_cmd_mps2, a.bank_cmd_rad, a.cross_track_m, a.eta_rad) == \
            (b.segment_index, b.accel_cmd_mps2, b.bank_cmd_rad, b.cross_track_m, b.eta_rad)
        np.testing.assert_array_equal(a.ref_ne_m, b.ref_ne_m)


def _estimate(t, pos, vel, rpy, omega, airspeed=None):
    z = np.zeros((3, 3))
    return NavEstimate(t, np.asarray(pos, float), np.asarray(vel, float), np.array([1.0, 0, 0, 0]), np.asarray(rpy, float),
                       np.asarray(omega, float), z, z, z, airspeed)


def test_multirotor_status_and_moments_match_the_cascade_equations():
    from testbench.control.evaluate import make_context
    from testbench.control.evaluate_multirotor import waypoint_mission
    from testbench.control.multirotor import MultirotorController
    from testbench.dynamics.catalog import aircraft_meta

    meta = aircraft_meta("tb_quad")
    ctx = make_context("q")
    ctl = MultirotorController(MultirotorController.Params(), ctx=ctx, mission=waypoint_mission(ctx, points=[(30.0, 0.0), (30.0, 30.0)]),
                               aircraft=meta)
    captured = {}
    ctl.mixer.commands = lambda thrust, moments: captured.update(thrust=thrust, moments=moments) or (0.5,) * 4
    pos, rpy, omega = np.array([2.0, 1.0, -99.0]), np.array([0.05, -0.03, 0.2]), np.array([0.1, -0.2, 0.05])
    ctl.update(0.0, _estimate(0.0, pos, [1.0, 0.5, 0.0], rpy, omega))
    st = ctl.status()
    assert isinstance(st, GuidanceStatus) and st.leg_index == 0 and st.on_leg
    assert st.target_ned_m == (30.0, 0.0, -100.0) and st.alt_cmd_m == 100.0
    assert st.line_start_ne_m == (2.0, 1.0) and st.line_end_ne_m == (30.0, 0.0)
    # The start point is on the line (zero cross-track); later points are measured from the
    # line start -> target, right positive.
    assert st.cross_track_est_m == pytest.approx(0.0, abs=1e-12)
    ctl.update(0.01, _estimate(0.01, [16.0, 0.5 + 1.0, -99.0], [1.0, 0.5, 0.0], rpy, omega))
    a_n, a_e = 28.0, -1.0
    assert ctl.status().cross_track_est_m == pytest.approx((-(16.0 - 2.0) * a_e / math.hypot(a_n, a_e) + 0.5 * a_n / math.hypot(a_n, a_e)),
                                                          rel=1e-12)
    # Rate loop: M = J k_rate (w_cmd - w) + w x J w with w_cmd from the reported bank command.
    J = ctl.inertia
    g = ctl.gains
    rpy_d_roll = ctl.status().bank_cmd_rad
    w_cmd_x = g.k_att * float(wrap_pi(rpy_d_roll - rpy[0]))
    expected_x = J[0, 0] * g.k_rate * (w_cmd_x - omega[0]) + np.cross(omega, J @ omega)[0]
    assert captured["moments"][0] == pytest.approx(expected_x, rel=1e-12)
    assert captured["thrust"] > 0.0


def test_status_setter_and_lazy_build_keep_subclass_contract():
    from testbench.control.evaluate import make_context, racetrack_mission
    from testbench.control.fixed_wing import FixedWingController
    from testbench.dynamics.catalog import aircraft_meta

    ctx = make_context()
    ctl = FixedWingController(FixedWingController.Params(), ctx=ctx, mission=racetrack_mission(ctx), aircraft=aircraft_meta("tb_fixedwing"))
    seg0 = ctl.segments[0]
    ctl.update(0.0, _estimate(0.0, [*seg0.start_ne_m, -800.0], [0.0, 25.0, 0.0], [0.0, 0.05, math.pi / 2], [0, 0, 0], 25.0))
    st = ctl.status()
    assert st.leg_index == 0 and st.on_leg and st.alt_cmd_m == 800.0 and st.airspeed_cmd_mps == 25.0
    assert st.line_start_ne_m == tuple(seg0.start_ne_m) and st.line_end_ne_m == tuple(seg0.end_ne_m)
    assert st.cross_track_est_m == pytest.approx(0.0, abs=1e-9)
    assert ctl.status() is st  # built once per tick
    replaced = GuidanceStatus(t_s=5.0, leg_index=7)
    ctl._status = replaced  # what a subclass (formation follower) does
    assert ctl.status() is replaced
