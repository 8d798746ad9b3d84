"""Planar path geometry for guidance: straight lines and circular arcs in local north-east metres.

Frames and signs
- Points are (north_m, east_m) in the local NED frame at the scenario origin (horizontal part).
- Cross-track error is positive when the vehicle is to the RIGHT of the direction of travel.
- An arc's `direction` is +1 for clockwise seen from above (right turn: the bearing from the
  centre increases, N -> E -> S -> W) and -1 for counter-clockwise (left turn).
- Bearings are atan2(east, north), radians.

A path is a tuple of segments joined end to start; a closed path (racetrack, orbit) wraps
around. Each segment answers: where the vehicle is along it (progress, m), how far it is off it
(cross-track, m), its tangent, and where a circle of radius L1 around the vehicle cuts it ahead
of the vehicle (the L1 reference point of Park, Deyst and How 2004).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

TWO_PI = 2.0 * math.pi


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.hypot(v[0], v[1]))
    return v / n if n > 0 else np.array([1.0, 0.0])


def bearing(v_ne: np.ndarray) -> float:
    """Bearing (rad, from north towards east) of a north-east vector."""
    return math.atan2(float(v_ne[1]), float(v_ne[0]))


@dataclass(frozen=True)
class LineSegment:
    """Straight segment from start_ne_m to end_ne_m (each (2,), metres)."""

    start_ne_m: np.ndarray
    end_ne_m: np.ndarray
    is_leg: bool = True

    @property
    def length_m(self) -> float:
        return float(np.hypot(*(self.end_ne_m - self.start_ne_m)))

    @property
    def tangent(self) -> np.ndarray:
        return _unit(self.end_ne_m - self.start_ne_m)

    def tangent_at_end(self) -> np.ndarray:
        return self.tangent

    def tangent_at_start(self) -> np.ndarray:
        return self.tangent

    def locate(self, p_ne: np.ndarray) -> tuple[float, float]:
        """(progress along the segment from its start (m), cross-track (m, right positive))."""
        t = self.tangent
        d = p_ne - self.start_ne_m
        along = float(d @ t)
        cross = float(-d[0] * t[1] + d[1] * t[0])  # d . right-normal, right normal = (-t_e, t_n)
        return along, cross

    def closest_point(self, p_ne: np.ndarray) -> np.ndarray:
        along, _ = self.locate(p_ne)
        return self.start_ne_m + self.tangent * float(np.clip(along, 0.0, self.length_m))

    def distance_m(self, p_ne: np.ndarray) -> float:
        return float(np.hypot(*(p_ne - self.closest_point(p_ne))))

    def l1_point(self, p_ne: np.ndarray, l1_m: float) -> tuple[np.ndarray, float] | None:
        """Forward intersection of the circle |x - p| = l1 with the (extended) line.

        Returns (point (2,), its progress along the segment in m) or None if the vehicle is
        farther than l1 from the line.
        """
        along, cross = self.locate(p_ne)
        if abs(cross) >= l1_m:
            return None
        s = along + math.sqrt(l1_m * l1_m - cross * cross)
        return self.start_ne_m + self.tangent * s, s


@dataclass(frozen=True)
class ArcSegment:
    """Circular arc about center_ne_m (2,) of radius_m, from bearing start_rad, sweeping
    sweep_rad (> 0, up to 2 pi for a full orbit) in `direction` (+1 cw / right, -1 ccw / left)."""

    center_ne_m: np.ndarray
    radius_m: float
    start_rad: float
    sweep_rad: float
    direction: int
    is_leg: bool = False

    @property
    def length_m(self) -> float:
        return self.radius_m * self.sweep_rad

    def _point(self, ang: float) -> np.ndarray:
        return self.center_ne_m + self.radius_m * np.array([math.cos(ang), math.sin(ang)])

    def _tangent(self, ang: float) -> np.ndarray:
        return self.direction * np.array([-math.sin(ang), math.cos(ang)])

    @property
    def end_ne_m(self) -> np.ndarray:
        return self._point(self.start_rad + self.direction * self.sweep_rad)

    @property
    def start_ne_m(self) -> np.ndarray:
        return self._point(self.start_rad)

    def tangent_at_start(self) -> np.ndarray:
        return self._tangent(self.start_rad)

    def tangent_at_end(self) -> np.ndarray:
        return self._tangent(self.start_rad + self.direction * self.sweep_rad)

    def _progress_angle(self, ang: float) -> float:
        """Swept angle from the start to bearing `ang` in the arc direction, in
        [-(2 pi - sweep)/2, sweep + (2 pi - sweep)/2): a point a little before the start is
        negative, not nearly 2 pi. For a full circle, in [0, 2 pi)."""
        a = (self.direction * (ang - self.start_rad)) % TWO_PI
        if self.sweep_rad < TWO_PI - 1e-9 and a > self.sweep_rad + 0.5 * (TWO_PI - self.sweep_rad):
            a -= TWO_PI
        return a

    def locate(self, p_ne: np.ndarray) -> tuple[float, float]:
        """(progress along the arc (m), cross-track (m, right of the direction of travel +))."""
        d = p_ne - self.center_ne_m
        r = float(np.hypot(d[0], d[1]))
        ang = math.atan2(d[1], d[0])
        # Right of travel is outward for a left (ccw) turn and inward for a right (cw) turn.
        cross = -self.direction * (r - self.radius_m)
        return self.radius_m * self._progress_angle(ang), cross

    def closest_point(self, p_ne: np.ndarray) -> np.ndarray:
        d = p_ne - self.center_ne_m
        ang = math.atan2(d[1], d[0])
        prog = self._progress_angle(ang)
        prog = min(max(prog, 0.0), self.sweep_rad)
        return self._point(self.start_rad + self.direction * prog)

    def distance_m(self, p_ne: np.ndarray) -> float:
        return float(np.hypot(*(p_ne - self.closest_point(p_ne))))

    def l1_point(self, p_ne: np.ndarray, l1_m: float) -> tuple[np.ndarray, float] | None:
        """Forward intersection of |x - p| = l1 with the (full) circle of the arc.

        Returns (point, its progress along the arc in m) or None when the circles do not cut.
        """
        d_vec = p_ne - self.center_ne_m
        d = float(np.hypot(d_vec[0], d_vec[1]))
        r = self.radius_m
        if d < 1e-6 or abs(d - r) >= l1_m or l1_m >= d + r:
            return None
        cos_a = (d * d + r * r - l1_m * l1_m) / (2.0 * d * r)
        alpha = math.acos(max(-1.0, min(1.0, cos_a)))
        ang = math.atan2(d_vec[1], d_vec[0]) + self.direction * alpha
        return self._point(ang), self.radius_m * self._progress_angle(ang)


Segment = LineSegment | ArcSegment


def passed_end(seg: Segment, nxt: Segment | None, p_ne: np.ndarray) -> bool:
    """True once the vehicle has finished `seg`.

    Arcs: the swept progress has reached the arc's length (a full circle never ends).
    Lines: the vehicle has crossed the switching plane through the end point whose normal is
    the bisector of this line's tangent and the next segment's start tangent (for tangent joins
    this is the normal plane at the join; at a waypoint corner it is the corner's bisector).
    """
    if isinstance(seg, ArcSegment):
        if seg.sweep_rad >= TWO_PI - 1e-9:
            return False
        return seg.locate(p_ne)[0] >= seg.length_m
    t1 = seg.tangent_at_end()
    n = t1 if nxt is None else t1 + nxt.tangent_at_start()
    if float(np.hypot(n[0], n[1])) < 1e-6:  # U-turn: use the incoming tangent
        n = t1
    return float((p_ne - seg.end_ne_m) @ _unit(n)) >= 0.0
