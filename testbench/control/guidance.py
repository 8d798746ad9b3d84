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

from testbench.control.paths import ArcSegment, Segment, passed_end_ne, switching_normal_ne
from testbench.core.units import STANDARD_GRAVITY_MPS2

HALF_PI = 0.5 * math.pi


def l1_distance_m(ground_speed_mps: float, period_s: float, damping: float) -> float:
    """L1 = zeta T V / pi (m)."""
    return damping * period_s * ground_speed_mps / math.pi


def l1_lateral_accel_ne(p_n_m: float, p_e_m: float, v_n_mps: float, v_e_mps: float, ref_n_m: float, ref_e_m: float,
                        l1_m: float) -> tuple[float, float]:
    """Scalar form of l1_lateral_accel: (a_cmd m/s^2 right positive, eta rad)."""
    los_n, los_e = ref_n_m - p_n_m, ref_e_m - p_e_m
    # Signed angle from v to los in the NE plane: right (clockwise from above) positive.
    cross = v_n_mps * los_e - v_e_mps * los_n
    dot = v_n_mps * los_n + v_e_mps * los_e
    eta = max(-HALF_PI, min(HALF_PI, math.atan2(cross, dot)))
    v = math.hypot(v_n_mps, v_e_mps)
    return 2.0 * v * v * math.sin(eta) / max(l1_m, 1e-3), eta


def l1_lateral_accel(pos_ne_m: np.ndarray, vel_ne_mps: np.ndarray, ref_ne_m: np.ndarray, l1_m: float) -> tuple[float, float]:
    """(a_cmd m/s^2 right positive, eta rad) for the reference point ref_ne_m.

    a_cmd = 2 V^2 sin(eta) / L1 with V the ground speed and eta the angle from the velocity to
    the line of sight (clipped to +-90 deg, as in PX4, so that a point behind does not flip).
    """
    return l1_lateral_accel_ne(float(pos_ne_m[0]), float(pos_ne_m[1]), float(vel_ne_mps[0]), float(vel_ne_mps[1]),
                               float(ref_ne_m[0]), float(ref_ne_m[1]), l1_m)


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
        # Per segment: the following one (None at the end of an open path) and, for lines,
        # the normal of the plane that ends it (fixed geometry, computed once).
        n = len(segments)
        self._next_index = [i + 1 if i + 1 < n else (0 if closed else None) for i in range(n)]
        self._switch_normal_ne = [
            switching_normal_ne(seg, None if j is None else segments[j]) if not isinstance(seg, ArcSegment) else None
            for seg, j in zip(segments, self._next_index)
        ]

    def _next(self, i: int) -> int | None:
        return self._next_index[i]

    def _initial_index(self, p_n: float, p_e: float, v_n: float, v_e: float) -> int:
        """The nearest segment, ties broken by heading agreement (a 100 m penalty for flying
        against the segment's direction)."""
        best, best_cost = 0, math.inf
        v_norm = max(math.hypot(v_n, v_e), 1e-6)
        h_n, h_e = v_n / v_norm, v_e / v_norm
        for i, seg in enumerate(self.segments):
            q_n, q_e = seg.closest_point_ne(p_n, p_e)
            t_n, t_e = seg.tangent_at_ne(p_n, p_e)
            cost = math.hypot(p_n - q_n, p_e - q_e) + 50.0 * (1.0 - (h_n * t_n + h_e * t_e))
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
        pos_ne_m, vel_ne_mps: (2,) or longer (only north and east are used).
        """
        return self.update_ne(float(pos_ne_m[0]), float(pos_ne_m[1]), float(vel_ne_mps[0]), float(vel_ne_mps[1]),
                              lead_s=lead_s, turn_rate_rps=turn_rate_rps)

    def update_ne(self, p_n_m: float, p_e_m: float, v_n_mps: float, v_e_mps: float, *, lead_s: float = 0.0,
                  turn_rate_rps: float = 0.0) -> L1Output:
        """update() with the position (m) and ground velocity (m/s) as north and east floats."""
        p_n, p_e, v_n, v_e = predict_on_turn_ne(p_n_m, p_e_m, v_n_mps, v_e_mps, turn_rate_rps, lead_s)
        if self.index is None:
            self.index = self._initial_index(p_n, p_e, v_n, v_e)
        # Switch (possibly several times after a long gap) while the vehicle is past the end.
        for _ in range(len(self.segments)):
            nxt = self._next_index[self.index]
            if nxt is None or not passed_end_ne(self.segments[self.index], p_n, p_e, self._switch_normal_ne[self.index]):
                break
            self.index = nxt
        seg = self.segments[self.index]
        nxt = self._next_index[self.index]
        ground_speed = math.hypot(v_n, v_e)
        speed = max(ground_speed, self.min_speed_mps)
        l1 = l1_distance_m(speed, self.period_s, self.damping)
        if isinstance(seg, ArcSegment):
            # The L1 circle must cut the path circle (L1 < 2 R); on tight orbits shorten L1
            # (on the circle the command stays V^2 / R exactly, only the gain off it rises).
            l1 = min(l1, 1.5 * seg.radius_m)
        _, cross = seg.locate_ne(p_n_m, p_e_m)
        ref_n, ref_e = self._reference_point_ne(seg, None if nxt is None else self.segments[nxt], p_n, p_e, l1)
        if ground_speed < self.min_speed_mps:  # too slow for a direction: fly the path tangent
            t_n, t_e = seg.tangent_at_ne(p_n, p_e)
            v_n, v_e = speed * t_n, speed * t_e
        accel, eta = l1_lateral_accel_ne(p_n, p_e, v_n, v_e, ref_n, ref_e, l1)
        bank = math.atan2(accel, STANDARD_GRAVITY_MPS2)
        bank = max(-self.max_bank_rad, min(self.max_bank_rad, bank))
        return L1Output(self.index, accel, bank, cross, np.array((ref_n, ref_e)), eta)

    @staticmethod
    def _reference_point_ne(seg: Segment, nxt: Segment | None, p_n: float, p_e: float, l1: float) -> tuple[float, float]:
        hit = seg.l1_point_ne(p_n, p_e, l1)
        if hit is not None:
            if hit[2] <= seg.length_m or nxt is None:
                return hit[0], hit[1]
            hit_next = nxt.l1_point_ne(p_n, p_e, l1)
            if hit_next is not None and hit_next[2] >= 0.0:
                return hit_next[0], hit_next[1]
            return hit[0], hit[1]
        # Farther than L1 from the path: head for the closest point (eta up to 90 deg).
        q_n, q_e = seg.closest_point_ne(p_n, p_e)
        if isinstance(seg, ArcSegment):
            return q_n, q_e
        # On a line aim at the foot of the perpendicular a little ahead, so eta < 90 deg.
        t_n, t_e = seg.tangent_ne
        return q_n + 0.1 * l1 * t_n, q_e + 0.1 * l1 * t_e


def predict_on_turn_ne(p_n: float, p_e: float, v_n: float, v_e: float, turn_rate_rps: float,
                       dt_s: float) -> tuple[float, float, float, float]:
    """Scalar form of predict_on_turn: (p_n, p_e, v_n, v_e) after dt_s (m, m/s)."""
    if dt_s <= 0.0:
        return p_n, p_e, v_n, v_e
    a = turn_rate_rps * dt_s
    c, s = math.cos(a), math.sin(a)
    if abs(turn_rate_rps) < 1e-6:
        d_n, d_e = v_n * dt_s, v_e * dt_s
    else:
        # Integral of rot(w t) v over [0, dt]: (1/w) [[s, c - 1], [1 - c, s]] v.
        d_n = (s * v_n + (c - 1.0) * v_e) / turn_rate_rps
        d_e = ((1.0 - c) * v_n + s * v_e) / turn_rate_rps
    # Rotating a NE vector clockwise (right turn) by a: (n, e) -> (n c - e s, n s + e c).
    return p_n + d_n, p_e + d_e, c * v_n - s * v_e, s * v_n + c * v_e


def predict_on_turn(p_ne: np.ndarray, v_ne: np.ndarray, turn_rate_rps: float, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Position and velocity after dt_s on a constant-speed turn at turn_rate_rps (right +)."""
    if dt_s <= 0.0:
        return p_ne, v_ne
    p_n, p_e, v_n, v_e = predict_on_turn_ne(float(p_ne[0]), float(p_ne[1]), float(v_ne[0]), float(v_ne[1]),
                                            turn_rate_rps, dt_s)
    return np.array((p_n, p_e)), np.array((v_n, v_e))
