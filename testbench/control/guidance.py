"""L1 nonlinear path-following guidance on lines and arcs (Park, Deyst and How, "A New
Nonlinear Guidance Logic for Trajectory Tracking", AIAA GNC 2004).

The law: pick the reference point on the path at distance L1 ahead of the vehicle, let eta be
the angle from the ground-velocity vector to the line of sight to that point (right positive);
command the lateral acceleration

    a_cmd = 2 V^2 sin(eta) / L1          (V: ground speed, a_cmd right positive)

and fly it as the coordinated-turn bank phi_cmd = atan(a_cmd / g), limited to +-max_bank.
Linearised about a straight line the cross-track error obeys a PD law with natural frequency
omega = sqrt(2) V / L1 and damping 1/sqrt(2); following PX4 we choose L1 from a period T and a
damping zeta: L1 = zeta T V / pi. On a circle of radius R the reference point is a chord of
length L1, sin(eta) = L1 / (2 R), so a_cmd = V^2 / R exactly: no bias on arcs.

`PathFollower` walks a tuple of segments (paths.py): it switches to the next segment once the
vehicle passes the current one's end (passed_end), and looks ahead across the join: when the
L1 point falls beyond the end of the current segment it is taken on the next one, so the
vehicle rolls into and out of turns before the join instead of overshooting it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from testbench.control.paths import ArcSegment, LineSegment, Segment, passed_end
from testbench.core.units import STANDARD_GRAVITY_MPS2


def l1_distance_m(ground_speed_mps: float, period_s: float, damping: float) -> float:
    """L1 = zeta T V / pi (m)."""
    return damping * period_s * ground_speed_mps / math.pi


def l1_lateral_accel(pos_ne_m: np.ndarray, vel_ne_mps: np.ndarray, ref_ne_m: np.ndarray, l1_m: float) -> tuple[float, float]:
    """(a_cmd m/s^2 right positive, eta rad) for the reference point ref_ne_m.

    a_cmd = 2 V^2 sin(eta) / L1 with V the ground speed and eta the angle from the velocity to
    the line of sight (clipped to +-90 deg, as in PX4, so that a point behind does not flip).
    """
    v = float(np.hypot(vel_ne_mps[0], vel_ne_mps[1]))
    los = ref_ne_m - pos_ne_m
    # Signed angle from v to los in the NE plane: right (clockwise from above) positive.
    cross = vel_ne_mps[0] * los[1] - vel_ne_mps[1] * los[0]
    dot = vel_ne_mps[0] * los[0] + vel_ne_mps[1] * los[1]
    eta = math.atan2(cross, dot)
    eta = max(-0.5 * math.pi, min(0.5 * math.pi, eta))
    return 2.0 * v * v * math.sin(eta) / max(l1_m, 1e-3), eta


@dataclass(frozen=True)
class L1Output:
    """What the path follower decided at one tick.

    segment_index; accel_cmd_mps2 (right +); bank_cmd_rad (limited); cross_track_m (right +,
    on the active segment); ref_ne_m (2,) the L1 point; eta_rad.
    """

    segment_index: int
    accel_cmd_mps2: float
    bank_cmd_rad: float
    cross_track_m: float
    ref_ne_m: np.ndarray
    eta_rad: float


class PathFollower:
    """L1 guidance along a segment list (closed: wraps; open: stays on the last segment)."""

    def __init__(self, segments: tuple[Segment, ...], closed: bool, *, period_s: float = 15.0, damping: float = 0.75,
                 max_bank_rad: float = math.radians(30.0), min_speed_mps: float = 5.0):
        if not segments:
            raise ValueError("a path needs at least one segment")
        self.segments = segments
        self.closed = closed
        self.period_s = period_s
        self.damping = damping
        self.max_bank_rad = max_bank_rad
        self.min_speed_mps = min_speed_mps
        self.index: int | None = None

    def _next(self, i: int) -> int | None:
        if i + 1 < len(self.segments):
            return i + 1
        return 0 if self.closed else None

    def _initial_index(self, p: np.ndarray, v: np.ndarray) -> int:
        """The nearest segment, ties broken by heading agreement (a 100 m penalty for flying
        against the segment's direction)."""
        best, best_cost = 0, math.inf
        vh = v / max(float(np.hypot(*v)), 1e-6)
        for i, seg in enumerate(self.segments):
            q = seg.closest_point(p)
            tangent = seg.tangent if isinstance(seg, LineSegment) else _arc_tangent(seg, q)
            cost = seg.distance_m(p) + 50.0 * (1.0 - float(vh @ tangent))
            if cost < best_cost:
                best, best_cost = i, cost
        return best

    def update(self, pos_ne_m: np.ndarray, vel_ne_mps: np.ndarray, *, lead_s: float = 0.0,
               turn_rate_rps: float = 0.0) -> L1Output:
        """Advance the active segment and compute the L1 command at this position/velocity.

        lead_s > 0 evaluates the law at the position predicted lead_s ahead on the current
        turn (turn_rate_rps, right +): this cancels the lag of the roll loop, so the bank
        command leads the path's curvature changes by about the roll response time instead
        of trailing them. The reported cross-track is that of the present position.
        """
        p_now = np.asarray(pos_ne_m, float)[:2]
        p, v = predict_on_turn(p_now, np.asarray(vel_ne_mps, float)[:2], turn_rate_rps, lead_s)
        if self.index is None:
            self.index = self._initial_index(p, v)
        # Switch (possibly several times after a long gap) while the vehicle is past the end.
        for _ in range(len(self.segments)):
            nxt = self._next(self.index)
            if nxt is None or not passed_end(self.segments[self.index], self.segments[nxt], p):
                break
            self.index = nxt
        seg = self.segments[self.index]
        nxt = self._next(self.index)
        speed = max(float(np.hypot(*v)), self.min_speed_mps)
        l1 = l1_distance_m(speed, self.period_s, self.damping)
        if isinstance(seg, ArcSegment):
            # The L1 circle must cut the path circle (L1 < 2 R); on tight orbits shorten L1
            # (on the circle the command stays V^2 / R exactly, only the gain off it rises).
            l1 = min(l1, 1.5 * seg.radius_m)
        _, cross = seg.locate(p_now)
        ref = self._reference_point(seg, None if nxt is None else self.segments[nxt], p, l1)
        if float(np.hypot(*v)) < self.min_speed_mps:  # too slow for a direction: fly the path tangent
            v = speed * _tangent_at(seg, p)
        accel, eta = l1_lateral_accel(p, v, ref, l1)
        bank = math.atan2(accel, STANDARD_GRAVITY_MPS2)
        bank = max(-self.max_bank_rad, min(self.max_bank_rad, bank))
        return L1Output(self.index, accel, bank, cross, ref, eta)

    @staticmethod
    def _reference_point(seg: Segment, nxt: Segment | None, p: np.ndarray, l1: float) -> np.ndarray:
        hit = seg.l1_point(p, l1)
        if hit is not None:
            point, progress = hit
            if progress <= seg.length_m or nxt is None:
                return point
            hit_next = nxt.l1_point(p, l1)
            if hit_next is not None and hit_next[1] >= 0.0:
                return hit_next[0]
            return point
        # Farther than L1 from the path: head for the closest point (eta up to 90 deg).
        q = seg.closest_point(p)
        if isinstance(seg, ArcSegment):
            return q
        # On a line aim at the foot of the perpendicular a little ahead, so eta < 90 deg.
        return q + 0.1 * l1 * seg.tangent


def predict_on_turn(p_ne: np.ndarray, v_ne: np.ndarray, turn_rate_rps: float, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Position and velocity after dt_s on a constant-speed turn at turn_rate_rps (right +)."""
    if dt_s <= 0.0:
        return p_ne, v_ne
    a = turn_rate_rps * dt_s
    c, s = math.cos(a), math.sin(a)
    # Rotating a NE vector clockwise (right turn) by a: (n, e) -> (n c - e s, n s + e c).
    rot = np.array([[c, -s], [s, c]])
    if abs(turn_rate_rps) < 1e-6:
        disp = v_ne * dt_s
    else:
        # Integral of rot(w t) v over [0, dt]: (1/w) [[s, c - 1], [1 - c, s]] v.
        disp = np.array([[s, c - 1.0], [1.0 - c, s]]) @ v_ne / turn_rate_rps
    return p_ne + disp, rot @ v_ne


def _arc_tangent(seg: ArcSegment, q: np.ndarray) -> np.ndarray:
    d = q - seg.center_ne_m
    ang = math.atan2(d[1], d[0])
    return seg.direction * np.array([-math.sin(ang), math.cos(ang)])


def _tangent_at(seg: Segment, p: np.ndarray) -> np.ndarray:
    if isinstance(seg, LineSegment):
        return seg.tangent
    return _arc_tangent(seg, seg.closest_point(p))
