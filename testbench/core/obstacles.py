"""Obstacles of the world: axis-aligned boxes in the local NED frame (buildings, towers, masts).

One geometry serves every part that meets an obstacle: the UWB radio (a box on the line between
two antennas makes the link NLOS), the GNSS receiver (a box, or the terrain, on the line to a
satellite hides it), the cameras (a box is drawn and hides what stands behind it) and the
dynamics (a vehicle inside a box has collided). The terrain's cut of a line of sight
(`segment_below_terrain`) is here too. The scenario gives them as
`world.obstacles` (config.schema.ObstacleBox); a box standing on the ground at the origin's
altitude runs from down = -height_m to down = 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# The six faces of a box: corner indices (corners() order) going once round the face, the
# axis of its outward normal and that normal's sign.
_FACES = (
    ((0, 2, 6, 4), 0, -1.0),  # north = min
    ((1, 5, 7, 3), 0, +1.0),  # north = max
    ((0, 4, 5, 1), 1, -1.0),  # east = min
    ((2, 3, 7, 6), 1, +1.0),  # east = max
    ((0, 1, 3, 2), 2, -1.0),  # down = min: the top
    ((4, 6, 7, 5), 2, +1.0),  # down = max: the bottom
)


@dataclass(frozen=True)
class Obstacle:
    """An axis-aligned box in local NED (m): min_ned_m and max_ned_m its corners (north, east,
    down), min < max on every axis; name: how messages and reports call it."""

    min_ned_m: tuple[float, float, float]
    max_ned_m: tuple[float, float, float]
    name: str = "obstacle"

    def contains(self, p_ned_m) -> bool:
        """Whether the point (3,) NED m lies inside the box or on its surface."""
        p = np.asarray(p_ned_m, float)
        return bool(np.all(p >= self.min_ned_m) and np.all(p <= self.max_ned_m))

    def hits_segment(self, p0_ned_m, p1_ned_m) -> bool:
        """Whether the segment p0 -> p1 (each (3,) NED m) crosses the box."""
        return segment_hits_box(np.asarray(p0_ned_m, float), np.asarray(p1_ned_m, float),
                                np.asarray(self.min_ned_m, float), np.asarray(self.max_ned_m, float))

    def corners(self) -> np.ndarray:
        """(8, 3) corners NED m; corner i takes max on axis k where bit k of i is set (north
        bit 0, east bit 1, down bit 2)."""
        lo, hi = np.asarray(self.min_ned_m, float), np.asarray(self.max_ned_m, float)
        bits = (np.arange(8)[:, None] >> np.arange(3)[None, :]) & 1
        return np.where(bits == 1, hi, lo)

    def faces_seen_from(self, eye_ned_m) -> list[tuple[np.ndarray, int, float]]:
        """The faces an eye at (3,) NED m sees (those whose outward side it is on): each as
        (corners (4, 3) NED m, normal axis 0/1/2, normal sign -1/+1)."""
        eye = np.asarray(eye_ned_m, float)
        c = self.corners()
        out = []
        for idx, axis, sign in _FACES:
            plane = self.max_ned_m[axis] if sign > 0 else self.min_ned_m[axis]
            if sign * (eye[axis] - plane) > 0.0:
                out.append((c[list(idx)], axis, sign))
        return out


def segment_hits_box(p0: np.ndarray, p1: np.ndarray, box_min: np.ndarray, box_max: np.ndarray) -> bool:
    """True if the segment p0 -> p1 (each (3,), one frame, m) crosses the axis-aligned box
    [box_min, box_max] (slab method: the segment's parameter interval inside every slab)."""
    d = p1 - p0
    t0, t1 = 0.0, 1.0
    for k in range(3):
        if abs(d[k]) < 1e-12:
            if p0[k] < box_min[k] or p0[k] > box_max[k]:
                return False
            continue
        a = (box_min[k] - p0[k]) / d[k]
        b = (box_max[k] - p0[k]) / d[k]
        t0, t1 = max(t0, min(a, b)), min(t1, max(a, b))
        if t0 > t1:
            return False
    return True


def segment_below_terrain(p0: np.ndarray, p1: np.ndarray, terrain_height_m, step_m: float) -> bool:
    """True if terrain rises above any interior point of the segment, sampled every step_m.

    terrain_height_m(north, east) -> height above the origin (up positive); NED down is -up.
    """
    length = float(np.linalg.norm(p1 - p0))
    n = max(2, int(np.ceil(length / step_m)))
    s = np.arange(1, n) / n
    pts = p0[None, :] + s[:, None] * (p1 - p0)[None, :]
    h = np.asarray(terrain_height_m(pts[:, 0], pts[:, 1]), float)
    return bool(np.any(h > -pts[:, 2]))


def first_hit(p0_ned_m, p1_ned_m, obstacles) -> Obstacle | None:
    """The first obstacle (in the given order) that the segment p0 -> p1 crosses, or None."""
    for ob in obstacles:
        if ob.hits_segment(p0_ned_m, p1_ned_m):
            return ob
    return None
