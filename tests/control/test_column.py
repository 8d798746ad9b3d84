"""Column followers (control/trail.py): the trail's arc length and interpolation, the column
score, and a follower that flies its predecessor's path around a bend, also while the
predecessor is hidden, where a rigid slot cuts across the bend."""

import math

import numpy as np
import pytest

from testbench.control.formation import FormationLaw, FormationParams
from testbench.control.trail import ColumnParams, Trail, TrailLaw, column_errors, followed_vehicle
from testbench.core.errors import InputError
from testbench.core.messages import NavEstimate
from testbench.core.rotations import euler_to_quat
from testbench.navigation.relative.types import RelativeEstimate

SLOTS = {"a": (0.0, 0.0, 0.0), "b": (-60.0, 0.0, 0.0), "c": (-120.0, 0.0, 0.0)}
Z3 = np.zeros((3, 3))


def _est(pos, vel, t):
    yaw = math.atan2(vel[1], vel[0]) if math.hypot(vel[0], vel[1]) > 0.1 else 0.0
    return NavEstimate(t, np.asarray(pos, float), np.asarray(vel, float), euler_to_quat([0.0, 0.0, yaw]),
                       np.array([0.0, 0.0, yaw]), np.zeros(3), Z3, Z3, Z3)


def _rel(peer, r, w, t):
    return RelativeEstimate(t, peer, np.asarray(r, float), np.asarray(w, float), np.eye(3) * 0.01, np.eye(3) * 0.01)


def test_trail_arc_length_interpolation_and_course():
    tr = Trail(crumb_m=1.0)
    for x in np.arange(0.0, 10.01, 0.5):  # 10 m north, then 10 m east
        tr.extend((x, 0.0, -5.0))
    for y in np.arange(0.5, 10.01, 0.5):
        tr.extend((10.0, y, -5.0))
    assert tr.length_m == pytest.approx(20.0)
    p, course = tr.point_at(5.0)
    np.testing.assert_allclose(p, (5.0, 0.0, -5.0), atol=1e-9)
    assert course == pytest.approx(0.0)
    p, course = tr.point_at(15.0)
    np.testing.assert_allclose(p, (10.0, 5.0, -5.0), atol=1e-9)
    assert course == pytest.approx(math.pi / 2)
    np.testing.assert_allclose(tr.point_at(-3.0)[0], (0.0, 0.0, -5.0))  # clamped to the trail
    tr.extend((10.0, 10.3, -5.0))  # closer than a crumb to the last point: not added
    assert tr.length_m == pytest.approx(20.0)
    seeded = Trail()
    seeded.seed((0.0, 0.0, 0.0), math.pi / 2, 50.0)  # a straight run ending at the origin, heading east
    np.testing.assert_allclose(seeded.point_at(seeded.length_m - 20.0)[0], (0.0, -20.0, 0.0), atol=1e-9)


def test_column_score_is_along_the_leaders_path():
    tr = Trail(crumb_m=0.5)
    tr.seed((0.0, 0.0, 0.0), 0.0, 200.0)  # the leader flew north to the origin ...
    for y in np.arange(1.0, 51.0, 1.0):  # ... then 50 m east
        tr.extend((0.0, y, 0.0))
    # b (60 m behind) belongs 10 m south of the corner, c 70 m south of it.
    pos = {"a": np.array([0.0, 50.0, 0.0]), "b": np.array([-10.0, 0.0, 0.0]), "c": np.array([-70.0, 3.0, 0.0])}
    e = column_errors(pos, tr, SLOTS, "a")
    np.testing.assert_allclose(e["b"], 0.0, atol=1e-9)
    np.testing.assert_allclose(e["c"], (0.0, 3.0, 0.0), atol=1e-9)


def test_followed_vehicle_is_the_nearest_slot_ahead():
    assert followed_vehicle(SLOTS, "c") == "b" and followed_vehicle(SLOTS, "b") == "a"
    with pytest.raises(InputError, match="no slot ahead"):
        followed_vehicle(SLOTS, "a")


def _a_at(t, speed=4.0, radius=100.0, straight=150.0):
    """The column's front 'a' flies north, turns right on a 100 m radius (90 deg) and flies
    east, at 4 m/s: position and velocity (NED) at t (s)."""
    s = speed * t
    arc = radius * math.pi / 2
    if s < straight:
        return np.array([s, 0.0, -80.0]), np.array([speed, 0.0, 0.0])
    if s < straight + arc:
        th = (s - straight) / radius
        return (np.array([straight + radius * math.sin(th), radius * (1 - math.cos(th)), -80.0]),
                speed * np.array([math.cos(th), math.sin(th), 0.0]))
    x = s - straight - arc
    return np.array([straight + radius, radius + x, -80.0]), np.array([0.0, speed, 0.0])


def _fly_bend(law, me="b", visible=lambda t: {"a", "b"}, t_end=120.0, dt=0.1, probe=None):
    """The follower `me` is a point mass whose velocity follows the command with a 1 s lag,
    starting in its slot; the vehicles ahead fly a's path, b 15 s (60 m) behind a. Its
    neighbour table holds, from truth, those of a and b ahead of it and in visible(t).
    probe(t, law, pos) is called every step. Returns the follower's distance from the path (m)
    per step after the start-up."""
    delay = {"a": 0.0, "b": 15.0}
    path = np.array([_a_at(t)[0] for t in np.arange(-40.0, t_end, 0.05)])
    behind = -SLOTS[me][0]
    pos, vel = np.array([-behind, 0.0, -80.0]), np.array([4.0, 0.0, 0.0])
    off = []
    for k in range(int(t_end / dt)):
        t = k * dt
        table = {}
        for peer, lag in delay.items():
            if peer != me and SLOTS[peer][0] > SLOTS[me][0] and peer in visible(t):
                pk, vk = _a_at(t - lag)
                table[peer] = _rel(peer, pk - pos, vk - vel, t)
        v_cmd = law.velocity_command(t, _est(pos, vel, t), table)
        vel = vel + (v_cmd - vel) * (dt / 1.0)
        pos = pos + vel * dt
        if probe is not None:
            probe(t, law, pos)
        if t > 20.0:
            off.append(float(np.min(np.hypot(path[:, 0] - pos[0], path[:, 1] - pos[1]))))
    return np.array(off)


def test_column_follower_flies_the_path_around_a_bend_where_a_rigid_slot_cuts_it():
    column = _fly_bend(TrailLaw(ColumnParams(slots=SLOTS, margin_m=15.0), "b"))
    rigid = _fly_bend(FormationLaw(FormationParams(slots=SLOTS, leader_id="a", margin_m=15.0), "b"))
    print(f"off the path: column max {column.max():.2f} m, rigid max {rigid.max():.2f} m")
    assert column.max() < 2.0, column.max()
    assert rigid.max() > 2.0 * column.max(), (rigid.max(), column.max())


def test_column_follower_goes_on_along_the_trail_while_the_predecessor_is_hidden():
    """Hidden for 12 s in the bend (40-52 s): the follower flies on along the trail it has."""
    law = TrailLaw(ColumnParams(slots=SLOTS, margin_m=15.0), "b")
    off = _fly_bend(law, visible=lambda t: set() if 40.0 <= t < 52.0 else {"a"})
    assert off.max() < 1.0, off.max()


def test_column_follower_takes_the_next_vehicle_ahead_while_its_predecessor_is_hidden():
    """c follows b; b hidden for 30 s in the bend (35-65 s) while a, two places ahead, is seen:
    c flies a's trail 120 m behind a and stays on the path."""
    law = TrailLaw(ColumnParams(slots=SLOTS, margin_m=15.0), "c")
    seen = []

    def probe(t, law, pos):
        if 40.0 <= t < 65.0:  # flying a's trail, 120 m behind a (a's place 30 s ago)
            seen.append((law.active, float(np.linalg.norm(pos[:2] - _a_at(t - 30.0)[0][:2]))))

    off = _fly_bend(law, me="c", visible=lambda t: {"a"} if 35.0 <= t < 65.0 else {"a", "b"}, probe=probe)
    assert {a for a, _ in seen} == {"a"} and max(d for _, d in seen) < 3.0, max(d for _, d in seen)
    assert law.active == "b" and off.max() < 1.0, (law.active, off.max())
    with pytest.raises(InputError, match="no slot ahead"):
        TrailLaw(ColumnParams(slots=SLOTS), "a")


def test_column_params_reject_a_follow_target_behind():
    with pytest.raises(InputError, match="must have its slot ahead"):
        TrailLaw(ColumnParams(slots=SLOTS, follow_id="c"), "b")
