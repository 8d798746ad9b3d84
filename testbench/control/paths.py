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

Two faces of the same geometry: the array methods (locate, l1_point, ...; (2,) numpy vectors)
for callers and tests, and the scalar methods ending in `_ne` (north and east as separate
floats, results as tuples) that guidance calls every control tick: numpy's per-call overhead
on 2-vectors is tens of times the arithmetic. Each segment computes its fixed geometry
(end points, unit tangent, length) once, at construction, as plain floats.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

TWO_PI = 2.0 * math.pi


def _unit(v: np.ndarray) -> np.ndarray:
    n = math.hypot(float(v[0]), float(v[1]))
    return v / n if n > 0 else np.array([1.0, 0.0])


def unit_ne(n: float, e: float) -> tuple[float, float]:
    """Unit vector along (n, e); (1, 0) for the zero vector."""
    norm = math.hypot(n, e)
    return (n / norm, e / norm) if norm > 0 else (1.0, 0.0)


def bearing(v_ne: np.ndarray) -> float:
    """Bearing (rad, from north towards east) of a north-east vector."""
    return math.atan2(float(v_ne[1]), float(v_ne[0]))


def _ne_floats(v) -> tuple[float, float]:
    return float(v[0]), float(v[1])


class _ArrayFace:
    """The array face of a segment over its scalar one (locate_ne, closest_point_ne): p_ne is
    any (2,) sequence (north, east) in metres."""

    def locate(self, p_ne: np.ndarray) -> tuple[float, float]:
        """(progress along the segment from its start (m), cross-track (m, right of the
        direction of travel positive))."""
        return self.locate_ne(*_ne_floats(p_ne))

    def closest_point(self, p_ne: np.ndarray) -> np.ndarray:
        """The segment's point nearest p_ne, (2,) NE metres."""
        return np.array(self.closest_point_ne(*_ne_floats(p_ne)))

    def distance_m(self, p_ne: np.ndarray) -> float:
        """Distance (m) from p_ne to the segment."""
        p_n, p_e = _ne_floats(p_ne)
        q_n, q_e = self.closest_point_ne(p_n, p_e)
        return math.hypot(p_n - q_n, p_e - q_e)


@dataclass(frozen=True)
class LineSegment(_ArrayFace):
    """Straight segment from start_ne_m to end_ne_m (each (2,), metres)."""

    start_ne_m: np.ndarray
    end_ne_m: np.ndarray
    is_leg: bool = True

    def __post_init__(self) -> None:
        # Fixed geometry as floats (frozen dataclass: set through object.__setattr__).
        start, end = _ne_floats(self.start_ne_m), _ne_floats(self.end_ne_m)
        d_n, d_e = end[0] - start[0], end[1] - start[1]
        object.__setattr__(self, "start_ne", start)
        object.__setattr__(self, "end_ne", end)
        object.__setattr__(self, "tangent_ne", unit_ne(d_n, d_e))
        object.__setattr__(self, "_length_m", math.hypot(d_n, d_e))

    @property
    def length_m(self) -> float:
        return self._length_m

    @property
    def tangent(self) -> np.ndarray:
        return np.array(self.tangent_ne)

    def tangent_at_end(self) -> np.ndarray:
        return self.tangent

    def tangent_at_start(self) -> np.ndarray:
        return self.tangent

    @property
    def start_tangent_ne(self) -> tuple[float, float]:
        return self.tangent_ne

    @property
    def end_tangent_ne(self) -> tuple[float, float]:
        return self.tangent_ne

    # -- scalar face ---------------------------------------------------------------------

    def point_at_ne(self, progress_m: float) -> tuple[float, float]:
        """Point of the (extended) line at `progress_m` from the start."""
        t_n, t_e = self.tangent_ne
        return self.start_ne[0] + t_n * progress_m, self.start_ne[1] + t_e * progress_m

    def locate_ne(self, p_n_m: float, p_e_m: float) -> tuple[float, float]:
        """(progress along the segment from its start (m), cross-track (m, right positive))."""
        t_n, t_e = self.tangent_ne
        d_n, d_e = p_n_m - self.start_ne[0], p_e_m - self.start_ne[1]
        along = d_n * t_n + d_e * t_e
        cross = -d_n * t_e + d_e * t_n  # d . right-normal, right normal = (-t_e, t_n)
        return along, cross

    def closest_point_ne(self, p_n_m: float, p_e_m: float) -> tuple[float, float]:
        along, _ = self.locate_ne(p_n_m, p_e_m)
        return self.point_at_ne(min(max(along, 0.0), self._length_m))

    def tangent_at_ne(self, p_n_m: float, p_e_m: float) -> tuple[float, float]:
        """Unit tangent at the point of the segment closest to p."""
        return self.tangent_ne

    def l1_point_ne(self, p_n_m: float, p_e_m: float, l1_m: float) -> tuple[float, float, float] | None:
        """(north, east, progress m) of the forward cut of |x - p| = l1 with the (extended)
        line, or None if the vehicle is farther than l1 from the line."""
        along, cross = self.locate_ne(p_n_m, p_e_m)
        if abs(cross) >= l1_m:
            return None
        s = along + math.sqrt(l1_m * l1_m - cross * cross)
        return (*self.point_at_ne(s), s)

    # -- array face (locate, closest_point, distance_m: _ArrayFace) ---------------------

    def l1_point(self, p_ne: np.ndarray, l1_m: float) -> tuple[np.ndarray, float] | None:
        """Forward intersection of the circle |x - p| = l1 with the (extended) line.

        Returns (point (2,), its progress along the segment in m) or None if the vehicle is
        farther than l1 from the line.
        """
        hit = self.l1_point_ne(*_ne_floats(p_ne), l1_m)
        return None if hit is None else (np.array(hit[:2]), hit[2])


@dataclass(frozen=True)
class ArcSegment(_ArrayFace):
    """Circular arc about center_ne_m (2,) of radius_m, from bearing start_rad, sweeping
    sweep_rad (> 0, up to 2 pi for a full orbit) in `direction` (+1 cw / right, -1 ccw / left)."""

    center_ne_m: np.ndarray
    radius_m: float
    start_rad: float
    sweep_rad: float
    direction: int
    is_leg: bool = False

    def __post_init__(self) -> None:
        end_rad = self.start_rad + self.direction * self.sweep_rad
        is_full = self.sweep_rad >= TWO_PI - 1e-9
        object.__setattr__(self, "center_ne", _ne_floats(self.center_ne_m))
        object.__setattr__(self, "end_rad", end_rad)
        object.__setattr__(self, "is_full_circle", is_full)
        # Progress angles beyond the middle of the unswept gap count as "before the start".
        object.__setattr__(self, "_gap_middle_rad", math.inf if is_full else self.sweep_rad + 0.5 * (TWO_PI - self.sweep_rad))
        object.__setattr__(self, "start_ne", self.point_at_bearing_ne(self.start_rad))
        object.__setattr__(self, "end_ne", self.point_at_bearing_ne(end_rad))
        object.__setattr__(self, "start_tangent_ne", self.tangent_at_bearing_ne(self.start_rad))
        object.__setattr__(self, "end_tangent_ne", self.tangent_at_bearing_ne(end_rad))

    @property
    def length_m(self) -> float:
        return self.radius_m * self.sweep_rad

    @property
    def end_ne_m(self) -> np.ndarray:
        return np.array(self.end_ne)

    @property
    def start_ne_m(self) -> np.ndarray:
        return np.array(self.start_ne)

    def tangent_at_start(self) -> np.ndarray:
        return np.array(self.start_tangent_ne)

    def tangent_at_end(self) -> np.ndarray:
        return np.array(self.end_tangent_ne)

    # -- scalar face ---------------------------------------------------------------------

    def point_at_bearing_ne(self, bearing_rad: float) -> tuple[float, float]:
        """Point of the circle at a bearing from the centre."""
        return (self.center_ne[0] + self.radius_m * math.cos(bearing_rad),
                self.center_ne[1] + self.radius_m * math.sin(bearing_rad))

    def tangent_at_bearing_ne(self, bearing_rad: float) -> tuple[float, float]:
        """Unit tangent (direction of travel) at a bearing from the centre."""
        return self.direction * -math.sin(bearing_rad), self.direction * math.cos(bearing_rad)

    def _progress_angle(self, ang: float) -> float:
        """Swept angle from the start to bearing `ang` in the arc direction, in
        [-(2 pi - sweep)/2, sweep + (2 pi - sweep)/2): a point a little before the start is
        negative, not nearly 2 pi. For a full circle, in [0, 2 pi)."""
        a = (self.direction * (ang - self.start_rad)) % TWO_PI
        if a > self._gap_middle_rad:
            a -= TWO_PI
        return a

    def locate_ne(self, p_n_m: float, p_e_m: float) -> tuple[float, float]:
        """(progress along the arc (m), cross-track (m, right of the direction of travel +))."""
        d_n, d_e = p_n_m - self.center_ne[0], p_e_m - self.center_ne[1]
        r = math.hypot(d_n, d_e)
        ang = math.atan2(d_e, d_n)
        # Right of travel is outward for a left (ccw) turn and inward for a right (cw) turn.
        cross = -self.direction * (r - self.radius_m)
        return self.radius_m * self._progress_angle(ang), cross

    def _closest_bearing(self, p_n_m: float, p_e_m: float) -> float:
        ang = math.atan2(p_e_m - self.center_ne[1], p_n_m - self.center_ne[0])
        prog = min(max(self._progress_angle(ang), 0.0), self.sweep_rad)
        return self.start_rad + self.direction * prog

    def closest_point_ne(self, p_n_m: float, p_e_m: float) -> tuple[float, float]:
        return self.point_at_bearing_ne(self._closest_bearing(p_n_m, p_e_m))

    def tangent_at_ne(self, p_n_m: float, p_e_m: float) -> tuple[float, float]:
        """Unit tangent at the point of the arc closest to p."""
        q_n, q_e = self.closest_point_ne(p_n_m, p_e_m)
        return self.tangent_at_bearing_ne(math.atan2(q_e - self.center_ne[1], q_n - self.center_ne[0]))

    def l1_point_ne(self, p_n_m: float, p_e_m: float, l1_m: float) -> tuple[float, float, float] | None:
        """(north, east, progress m) of the forward cut of |x - p| = l1 with the (full)
        circle of the arc, or None when the circles do not cut."""
        d_n, d_e = p_n_m - self.center_ne[0], p_e_m - self.center_ne[1]
        d = math.hypot(d_n, d_e)
        r = self.radius_m
        if d < 1e-6 or abs(d - r) >= l1_m or l1_m >= d + r:
            return None
        cos_a = (d * d + r * r - l1_m * l1_m) / (2.0 * d * r)
        alpha = math.acos(max(-1.0, min(1.0, cos_a)))
        ang = math.atan2(d_e, d_n) + self.direction * alpha
        return (*self.point_at_bearing_ne(ang), self.radius_m * self._progress_angle(ang))

    # -- array face (locate, closest_point, distance_m: _ArrayFace) ---------------------

    def l1_point(self, p_ne: np.ndarray, l1_m: float) -> tuple[np.ndarray, float] | None:
        """Forward intersection of |x - p| = l1 with the (full) circle of the arc.

        Returns (point, its progress along the arc in m) or None when the circles do not cut.
        """
        hit = self.l1_point_ne(*_ne_floats(p_ne), l1_m)
        return None if hit is None else (np.array(hit[:2]), hit[2])


Segment = LineSegment | ArcSegment


def switching_normal_ne(seg: LineSegment, nxt: Segment | None) -> tuple[float, float]:
    """Unit normal of the plane through a line's end point past which the line is finished:
    the bisector of its tangent and the next segment's start tangent (the normal plane at a
    tangent join, the corner's bisector at a waypoint); the line's tangent for a U-turn or
    when nothing follows."""
    t_n, t_e = seg.end_tangent_ne
    if nxt is None:
        return unit_ne(t_n, t_e)
    n_n, n_e = t_n + nxt.start_tangent_ne[0], t_e + nxt.start_tangent_ne[1]
    if math.hypot(n_n, n_e) < 1e-6:  # U-turn: use the incoming tangent
        return unit_ne(t_n, t_e)
    return unit_ne(n_n, n_e)


def passed_end_ne(seg: Segment, p_n_m: float, p_e_m: float, normal_ne: tuple[float, float] | None) -> bool:
    """Scalar form of passed_end; normal_ne = switching_normal_ne(seg, nxt) for a line
    (ignored for an arc), so that callers can compute it once per segment."""
    if isinstance(seg, ArcSegment):
        if seg.is_full_circle:
            return False
        return seg.locate_ne(p_n_m, p_e_m)[0] >= seg.length_m
    return (p_n_m - seg.end_ne[0]) * normal_ne[0] + (p_e_m - seg.end_ne[1]) * normal_ne[1] >= 0.0


def passed_end(seg: Segment, nxt: Segment | None, p_ne: np.ndarray) -> bool:
    """True once the vehicle has finished `seg`.

    Arcs: the swept progress has reached the arc's length (a full circle never ends).
    Lines: the vehicle has crossed the switching plane through the end point whose normal is
    the bisector of this line's tangent and the next segment's start tangent (for tangent joins
    this is the normal plane at the join; at a waypoint corner it is the corner's bisector).
    """
    normal = switching_normal_ne(seg, nxt) if isinstance(seg, LineSegment) else None
    return passed_end_ne(seg, *_ne_floats(p_ne), normal)
