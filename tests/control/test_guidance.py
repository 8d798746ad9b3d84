"""Guidance geometry: L1 law on lines and arcs, racetrack geometry and switching, waypoints."""

import math

import numpy as np
import pytest

from testbench.control.guidance import PathFollower, l1_lateral_accel, predict_on_turn
from testbench.control.missions import OrbitMission, RacetrackMission, WaypointMission
from testbench.control.paths import ArcSegment, LineSegment, passed_end
from testbench.core.errors import InputError
from testbench.core.interfaces import BuildContext, GeodeticOrigin
from testbench.core.units import STANDARD_GRAVITY_MPS2 as G

CTX = BuildContext("v", ("v",), GeodeticOrigin(math.radians(34.0), math.radians(-117.0), 300.0))


def test_l1_on_line_zero_when_on_track_and_turns_back_towards_it():
    line = LineSegment(np.array([0.0, 0.0]), np.array([1000.0, 0.0]))
    f = PathFollower((line,), closed=False, period_s=12.0, damping=0.75, max_bank_rad=math.radians(45))
    out = f.update(np.array([100.0, 0.0]), np.array([25.0, 0.0]))
    assert out.accel_cmd_mps2 == pytest.approx(0.0, abs=1e-9)
    # 10 m right of track (east of a northbound line): command a left (negative) acceleration.
    out = f.update(np.array([200.0, 10.0]), np.array([25.0, 0.0]))
    assert out.cross_track_m == pytest.approx(10.0)
    assert out.accel_cmd_mps2 < 0.0
    l1 = 0.75 * 12.0 * 25.0 / math.pi
    eta = -math.asin(10.0 / l1)  # line of sight to the L1 point, velocity along the track
    assert out.accel_cmd_mps2 == pytest.approx(2 * 25.0**2 * math.sin(eta) / l1, rel=1e-9)


def test_l1_on_circle_commands_exact_centripetal_acceleration():
    r = 150.0
    for direction in (1, -1):
        arc = ArcSegment(np.array([0.0, 0.0]), r, 0.0, 2 * math.pi, direction)
        f = PathFollower((arc,), closed=True, max_bank_rad=math.radians(60))
        # On the circle at bearing 0 (north of the centre), flying along the tangent.
        v = 20.0 * np.array([0.0, float(direction)])
        out = f.update(np.array([r, 0.0]), v)
        assert out.accel_cmd_mps2 == pytest.approx(direction * 20.0**2 / r, rel=1e-9)
        assert out.bank_cmd_rad == pytest.approx(math.atan(direction * 20.0**2 / r / G), rel=1e-9)


def test_l1_accel_sign_and_bank_limit():
    a, eta = l1_lateral_accel(np.zeros(2), np.array([10.0, 0.0]), np.array([10.0, 10.0]), 14.142)
    assert eta == pytest.approx(math.pi / 4) and a > 0
    arc = ArcSegment(np.array([0.0, 0.0]), 20.0, 0.0, 2 * math.pi, 1)
    f = PathFollower((arc,), closed=True, max_bank_rad=math.radians(30))
    assert f.update(np.array([20.0, 0.0]), np.array([0.0, 25.0])).bank_cmd_rad == pytest.approx(math.radians(30))


def test_predict_on_turn_stays_on_circle():
    r, v = 100.0, 20.0
    p, vel = predict_on_turn(np.array([0.0, -r]), np.array([v, 0.0]), v / r, 3.0)  # right turn about origin
    assert np.hypot(*p) == pytest.approx(r, rel=1e-12)
    assert np.hypot(*vel) == pytest.approx(v)


def test_racetrack_geometry_and_leg_switching():
    m = RacetrackMission(RacetrackMission.Params(center={"north_m": 0, "east_m": 0}, leg_length_m=2000.0,
                                                 turn_bank_deg=30.0, heading_deg=90.0, altitude_m=800.0), ctx=CTX)
    segs = m.path(25.0)
    r = 25.0**2 / (G * math.tan(math.radians(30)))
    assert segs[1].radius_m == pytest.approx(r)
    assert segs[0].length_m == pytest.approx(2000.0) and segs[2].length_m == pytest.approx(2000.0)
    for a, b in zip(segs, segs[1:] + segs[:1]):  # closed, tangent joins
        assert np.allclose(a.end_ne_m, b.start_ne_m, atol=1e-9)
        assert np.allclose(a.tangent_at_end(), b.tangent_at_start(), atol=1e-9)
    assert segs[0].tangent == pytest.approx(np.array([0.0, 1.0]))  # heading 90 deg: eastbound
    # cw: the first leg is left of the centre (north of it when heading east).
    assert segs[0].start_ne_m[0] == pytest.approx(r)
    f = PathFollower(segs, closed=True)
    seen = []
    # Walk the exact path; the follower must step through 0, 1, 2, 3, 0.
    for seg in segs + segs[:1]:
        for frac in np.linspace(0.02, 0.98, 25):
            s = frac * seg.length_m
            if isinstance(seg, LineSegment):
                p, t = seg.start_ne_m + s * seg.tangent, seg.tangent
            else:
                ang = seg.start_rad + seg.direction * s / seg.radius_m
                p = seg.center_ne_m + seg.radius_m * np.array([math.cos(ang), math.sin(ang)])
                t = seg.direction * np.array([-math.sin(ang), math.cos(ang)])
            out = f.update(p, 25.0 * t)
            if not seen or seen[-1] != out.segment_index:
                seen.append(out.segment_index)
            assert abs(out.cross_track_m) < 1e-6
    assert seen == [0, 1, 2, 3, 0]


def test_switch_plane_at_waypoint_corner():
    a = LineSegment(np.array([0.0, 0.0]), np.array([100.0, 0.0]))
    b = LineSegment(np.array([100.0, 0.0]), np.array([100.0, 100.0]))
    assert not passed_end(a, b, np.array([90.0, 0.0]))
    assert passed_end(a, b, np.array([98.0, 5.0]))  # past the 45-degree bisector


def test_missions_lat_lon_and_altitude_synonym():
    o = CTX.origin
    m = WaypointMission(WaypointMission.Params(points=[{"lat_deg": math.degrees(o.lat_rad) + 0.001,
                                                        "lon_deg": math.degrees(o.lon_rad)},
                                                       {"north_m": 0.0, "east_m": 50.0, "altitude_m": 120.0}],
                                               altitude_agl_m=100.0), ctx=CTX)
    assert m.waypoints_ned_m[0, 0] == pytest.approx(110.9, abs=0.5)  # 0.001 deg of latitude
    assert m.waypoints_ned_m[0, 2] == -100.0 and m.waypoints_ned_m[1, 2] == -120.0
    with pytest.raises(Exception):
        WaypointMission.Params(points=[{"north_m": 1.0}])
    with pytest.raises(InputError):
        OrbitMission(OrbitMission.Params(center={"north_m": 0, "east_m": 0}, radius_m=100.0), ctx=CTX)
