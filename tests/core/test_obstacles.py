"""Obstacle boxes: inside test, line-of-sight cuts and the faces an eye sees."""

from __future__ import annotations

import numpy as np
import pytest

from testbench.core.obstacles import Obstacle, first_hit

BOX = Obstacle((10.0, -5.0, -40.0), (20.0, 5.0, 0.0), "hall")


def test_contains_and_segments():
    assert BOX.contains((15.0, 0.0, -10.0)) and BOX.contains((10.0, 5.0, 0.0))  # inside, on a corner
    assert not BOX.contains((15.0, 0.0, -41.0)) and not BOX.contains((9.9, 0.0, -10.0))
    # A line of sight through the box, one over its roof, one ending in front of it.
    assert BOX.hits_segment((0.0, 0.0, -10.0), (30.0, 0.0, -10.0))
    assert not BOX.hits_segment((0.0, 0.0, -50.0), (30.0, 0.0, -50.0))
    assert not BOX.hits_segment((0.0, 0.0, -10.0), (9.0, 0.0, -10.0))
    assert BOX.hits_segment((0.0, 0.0, -10.0), (12.0, 0.0, -10.0))  # ends inside
    other = Obstacle((100.0, 0.0, -5.0), (101.0, 1.0, 0.0), "post")
    assert first_hit((0.0, 0.0, -10.0), (30.0, 0.0, -10.0), [other, BOX]) is BOX
    assert first_hit((0.0, 0.0, -50.0), (30.0, 0.0, -50.0), [other, BOX]) is None


@pytest.mark.parametrize("eye, expected", [
    ((0.0, 0.0, -10.0), {(0, -1.0)}),                # south of it, below the roof: the south wall
    ((0.0, 0.0, -60.0), {(0, -1.0), (2, -1.0)}),     # and above the roof
    ((15.0, 20.0, -60.0), {(1, 1.0), (2, -1.0)}),    # east of it, above: the east wall and the roof
    ((15.0, 0.0, -60.0), {(2, -1.0)}),               # straight above: the roof alone
])
def test_faces_seen_from(eye, expected):
    faces = BOX.faces_seen_from(eye)
    assert {(axis, sign) for _, axis, sign in faces} == expected
    for corners, axis, sign in faces:
        # Each face's four corners lie on its plane and go once round it (no crossed edges).
        plane = BOX.max_ned_m[axis] if sign > 0 else BOX.min_ned_m[axis]
        assert np.allclose(corners[:, axis], plane)
        edges = np.roll(corners, -1, axis=0) - corners
        assert np.all(np.count_nonzero(np.abs(edges) > 1e-9, axis=1) == 1)  # each edge along one axis
