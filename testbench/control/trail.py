"""Column formation: each follower flies the path of the vehicle ahead of it, a fixed distance
behind it along that path (a convoy, a column along a corridor or a canyon).

A rigid formation turns its slots with the leader's course, so in a bend a vehicle 240 m back
is put 240 m behind the leader along the leader's CURRENT course: across the bend, into the
wall of a meandering canyon (swarm_canyon_nlos with rigid slots: the back of the column came
within 10 m of the terrain). A column follower instead keeps
a trail of where it has seen its predecessor and flies the point of that trail `spacing` metres
(arc length) behind the predecessor's latest position. When the predecessor is hidden (behind
a bend's wall, exactly where a column needs it most) the follower flies the trail of the next
vehicle ahead that it does see, at that vehicle's slot distance, and with none in sight goes on
along the trail it has, at the last speed, up to margin_m short of where it last saw one.

No vehicle reads another's state: the trail is the follower's own estimate of the predecessor
(its own position plus the relative estimate of its relative-navigation aid), in its own NED
frame. Its own INS drift enters only as the drift's change over the trail's delay
(spacing / speed, 15 s at 60 m and 4 m/s).

Scoring (column_errors) uses the same Trail on the leader's TRUE positions: each follower's
place is on the leader's path at its slot's distance behind the leader.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pydantic

from testbench.control.formation import FollowerLaw, FollowerParams, add_repulsion
from testbench.control.formation_followers import FormationFollower
from testbench.core.errors import InputError
from testbench.core.messages import NavEstimate
from testbench.core.registry import register


class Trail:
    """A polyline of NED points (m) with the horizontal arc length at each point.

    extend(p): add p if it lies at least crumb_m (horizontally) from the last point;
    point_at(s) -> (point (3,), course_rad): the point at arc length s (clamped to the trail;
    the course is the direction of the segment it falls on). Points more than keep_m behind
    the end are dropped (memory stays bounded over any flight)."""

    def __init__(self, crumb_m: float = 1.0, keep_m: float = 2000.0):
        self.crumb_m = float(crumb_m)
        self.keep_m = float(keep_m)
        self._pts: list[np.ndarray] = []
        self._s: list[float] = []

    def __len__(self) -> int:
        return len(self._pts)

    @property
    def length_m(self) -> float:
        """Arc length (m) at the trail's end (its start is 0, or where dropped points left it)."""
        return self._s[-1] if self._s else 0.0

    @property
    def end(self) -> np.ndarray:
        return self._pts[-1]

    def seed(self, p_ned_m, course_rad: float, back_m: float) -> None:
        """Start the trail with a straight run of back_m ending at p, along course (rad): before
        anyone has flown, the column's path behind the front is its initial line."""
        p = np.asarray(p_ned_m, float)
        d = np.array([math.cos(course_rad), math.sin(course_rad), 0.0])
        self._pts = [p - back_m * d, p.copy()]
        self._s = [0.0, float(back_m)]

    def extend(self, p_ned_m) -> None:
        p = np.asarray(p_ned_m, float)
        if not self._pts:
            self._pts, self._s = [p.copy()], [0.0]
            return
        ds = math.hypot(p[0] - self._pts[-1][0], p[1] - self._pts[-1][1])
        if ds < self.crumb_m:
            return
        self._pts.append(p.copy())
        self._s.append(self._s[-1] + ds)
        while len(self._s) > 2 and self._s[-1] - self._s[1] > self.keep_m:
            del self._pts[0], self._s[0]

    def point_at(self, s_m: float) -> tuple[np.ndarray, float]:
        if len(self._pts) < 2:
            raise ValueError("Trail.point_at needs at least two points")
        s = min(max(float(s_m), self._s[0]), self._s[-1])
        i = int(np.searchsorted(self._s, s, side="right")) - 1
        i = min(max(i, 0), len(self._s) - 2)
        a, b = self._pts[i], self._pts[i + 1]
        seg = self._s[i + 1] - self._s[i]
        f = (s - self._s[i]) / seg if seg > 0 else 1.0
        return a + f * (b - a), math.atan2(b[1] - a[1], b[0] - a[0])


def column_offset_ned(course_rad: float, slot_self, slot_ahead) -> np.ndarray:
    """NED offset (m) of our slot from the trail point: the slots' right and down differences
    turned by the trail's course (their forward difference is the arc length)."""
    d_right = float(slot_self[1]) - float(slot_ahead[1])
    d_down = float(slot_self[2]) - float(slot_ahead[2])
    return np.array([-math.sin(course_rad) * d_right, math.cos(course_rad) * d_right, d_down])


def column_errors(pos_ned_by_id: dict[str, np.ndarray], leader_trail: Trail, slots: dict[str, Any],
                  leader_id: str) -> dict[str, np.ndarray]:
    """Scoring (TRUTH): each follower's error (NED, m) from its place on the leader's path:
    the point slot distance behind the leader (leader forward - follower forward, arc length)
    plus the slots' right/down difference. leader_trail holds the leader's true path."""
    s0 = slots[leader_id]
    out = {}
    for k, p in pos_ned_by_id.items():
        if k == leader_id or k not in slots:
            continue
        behind = float(s0[0]) - float(slots[k][0])
        point, course = leader_trail.point_at(leader_trail.length_m - behind)
        out[k] = np.asarray(p, float) - point - column_offset_ned(course, slots[k], s0)
    return out


class ColumnParams(FollowerParams):
    """slots: id -> (forward_m, right_m, down_m), as for the rigid formation; the forward
    difference to the vehicle followed is the spacing along the path. follow_id: the only
    vehicle whose path we fly (default: the nearest vehicle ahead in sight, by slot); k_slot
    (1/s): gain on the error from our point of the trail; speed_tau_s: low-pass of the followed vehicle's
    estimated speed (the feed-forward along the trail); crumb_m: trail point spacing;
    max_age_s, max_sigma_m: estimates older or more uncertain than this are not used (nor
    put on the trail); margin_m, k_repulse: collision avoidance against every fresh neighbour;
    max_speed_mps, max_climb_rate_mps, max_accel_mps2 as for the rigid formation."""

    follow_id: str | None = None
    speed_tau_s: float = pydantic.Field(2.0, ge=0)
    crumb_m: float = pydantic.Field(2.0, gt=0)


def vehicles_ahead(slots: dict[str, Any], self_id: str) -> list[str]:
    """The vehicles whose slots lie ahead of self_id's, nearest first (smallest forward lead);
    InputError if none is ahead."""
    me = float(slots[self_id][0])
    ahead = sorted((float(s[0]) - me, k) for k, s in slots.items() if k != self_id and float(s[0]) > me + 1e-6)
    if not ahead:
        raise InputError(f"control.params.slots: no slot ahead of {self_id!r} to follow in a column")
    return [k for _, k in ahead]


def followed_vehicle(slots: dict[str, Any], self_id: str) -> str:
    """The vehicle whose slot is nearest ahead of self_id's; InputError if none is ahead."""
    return vehicles_ahead(slots, self_id)[0]


class _PeerTrail:
    """What a follower keeps of one vehicle ahead: the trail of its estimated positions and
    when, where and how fast it was last seen."""

    def __init__(self, crumb_m: float, keep_m: float):
        self.trail = Trail(crumb_m=crumb_m, keep_m=keep_m)
        self.last_seen: tuple[float, np.ndarray, np.ndarray] | None = None  # (t_s, pos NED m, vel NED m/s)


class TrailLaw(FollowerLaw):
    """The column law (module docstring); the same interface as formation.FormationLaw:
    velocity_command(t, est, table) -> v_cmd (3,) NED m/s; course_lead (rad) for the nose;
    error_ned_m (3,): our point of the trail minus our position; n_seen: 1 while a vehicle
    ahead is fresh, else 0.

    It keeps a trail of every vehicle ahead it estimates and flies that of the nearest one
    fresh, at that vehicle's slot distance: in a column the one right ahead is often hidden
    behind the one after it (their LED blobs merge on the column's line of sight) while the
    vehicle two places ahead is seen. follow_id, when given, is the only one followed."""

    def __init__(self, p: ColumnParams, self_id: str):
        if self_id not in p.slots:
            raise InputError(f"control.params.slots: no slot for this vehicle {self_id!r}")
        self.p = p
        self.self_id = self_id
        me = float(p.slots[self_id][0])
        if p.follow_id is not None:
            if p.follow_id not in p.slots:
                raise InputError(f"control.params.follow_id: {p.follow_id!r} has no slot")
            if float(p.slots[p.follow_id][0]) <= me:
                raise InputError(f"control.params: the followed vehicle {p.follow_id!r} must have its slot ahead of "
                                 f"{self_id!r}'s (forward {p.slots[p.follow_id][0]} vs {me})")
            self.ahead_ids = [p.follow_id]
        else:
            self.ahead_ids = vehicles_ahead(p.slots, self_id)
        self.follow_id = self.ahead_ids[0]
        self.spacing_by_id = {k: float(p.slots[k][0]) - me for k in self.ahead_ids}
        keep_m = max(4.0 * max(self.spacing_by_id.values()), 500.0)
        self.peers = {k: _PeerTrail(p.crumb_m, keep_m) for k in self.ahead_ids}
        self.active: str | None = None  # whose trail we fly
        self.target_s_m: float | None = None  # our arc length on that trail
        self.speed_ff_mps = 0.0
        self.course_lead: float | None = None
        self.error_ned_m = np.zeros(3)
        self.n_seen = 0
        self.t_prev: float | None = None
        self.v_out: np.ndarray | None = None
        self.hold_alt_down_m: float | None = None

    @property
    def trail(self) -> Trail:
        """The trail flown now (the nearest vehicle ahead's before any is seen)."""
        return self.peers[self.active or self.follow_id].trail

    def velocity_command(self, t_s: float, est: NavEstimate, table: dict | None) -> np.ndarray:
        p = self.p
        pos, vel = np.asarray(est.pos_ned_m, float), np.asarray(est.vel_ned_mps, float)
        dt = self._step_dt(t_s)
        if self.course_lead is None:
            self.course_lead = float(est.rpy_rad[2])
        if self.v_out is None:
            self.v_out = vel.copy()
        table = table or {}
        fresh = {k: e for k, e in table.items()
                 if k != self.self_id and t_s - e.t_s <= p.max_age_s and e.sigma_m <= p.max_sigma_m}
        chosen = None
        for k in self.ahead_ids:
            e = fresh.get(k)
            if e is None:
                continue
            p_k = pos + np.asarray(e.pos_ned_m, float)
            v_k = vel + np.asarray(e.vel_ned_mps, float)
            self._extend_trail(self.peers[k], t_s, pos, p_k, v_k, self.spacing_by_id[k])
            if chosen is None:
                chosen = (k, p_k, v_k)
        self.n_seen = int(chosen is not None)
        if chosen is not None:
            k, p_k, v_k = chosen
            a = 1.0 if p.speed_tau_s <= 0 else min(1.0, dt / p.speed_tau_s)
            self.speed_ff_mps += a * (math.hypot(v_k[0], v_k[1]) - self.speed_ff_mps)
            self.active = k
            # Our place: that vehicle's slot distance behind its latest position along its path
            # (the trail's end lies within crumb_m of that position).
            tr = self.peers[k].trail
            self.target_s_m = tr.length_m + math.hypot(p_k[0] - tr.end[0], p_k[1] - tr.end[1]) - self.spacing_by_id[k]
        elif self.target_s_m is not None:
            # None ahead in sight: go on along the trail at its last speed, short of where that
            # vehicle was last seen.
            self.target_s_m = min(self.target_s_m + self.speed_ff_mps * dt, self.trail.length_m - p.margin_m)
        if self.target_s_m is None:  # never seen: hold position and altitude
            if self.hold_alt_down_m is None:
                self.hold_alt_down_m = float(pos[2])
            v = np.zeros(3)
            v[2] = float(np.clip(0.5 * (self.hold_alt_down_m - pos[2]), -p.max_climb_rate_mps, p.max_climb_rate_mps))
            self.error_ned_m = np.zeros(3)
            return self._limit(v, dt)
        self.hold_alt_down_m = None
        point, course = self.trail.point_at(self.target_s_m)
        self.course_lead = course
        target = point + column_offset_ned(course, p.slots[self.self_id], p.slots[self.active])
        self.error_ned_m = target - pos
        v = self.speed_ff_mps * np.array([math.cos(course), math.sin(course), 0.0]) + p.k_slot * self.error_ned_m
        add_repulsion(v, fresh.values(), p.margin_m, p.k_repulse)
        return self._limit(v, dt)

    def _extend_trail(self, peer: _PeerTrail, t_s: float, pos: np.ndarray, p_k: np.ndarray, v_k: np.ndarray,
                      spacing_m: float) -> None:
        """Add a vehicle's estimated position to its trail. The first time, the path behind it is
        taken as the line from it through us (before anyone has flown, the column's line).
        After a gap (it was hidden, and moved more than two crumbs), the path it flew unseen is
        the cubic Hermite curve between where and how fast it went when last seen and now: in a
        bend the straight chord would cut the corner by R (1 - cos(theta / 2)), 2.9 m for 48 m
        hidden on a 100 m radius."""
        tr = peer.trail
        if len(tr) == 0:
            back = p_k - pos
            course0 = math.atan2(back[1], back[0]) if math.hypot(back[0], back[1]) > 1.0 else float(self.course_lead)
            tr.seed(p_k, course0, 2.0 * spacing_m)
        elif peer.last_seen is not None:
            t0, p0, v0 = peer.last_seen
            gap_s = t_s - t0
            if gap_s > 0 and math.hypot(p_k[0] - p0[0], p_k[1] - p0[1]) > 2.0 * self.p.crumb_m:
                for u in np.linspace(0.0, 1.0, 2 + int(gap_s * max(self.speed_ff_mps, 1.0) / self.p.crumb_m))[1:-1]:
                    h00, h10 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u
                    h01, h11 = -2 * u**3 + 3 * u**2, u**3 - u**2
                    tr.extend(h00 * p0 + h10 * gap_s * v0 + h01 * p_k + h11 * gap_s * v_k)
        tr.extend(p_k)
        peer.last_seen = (t_s, p_k, v_k)


@register("controller", "column_follower")
class ColumnFollower(FormationFollower):
    """Multirotor column follower: TrailLaw (module docstring) through the multirotor cascade,
    nose along the trail. Params: ColumnParams, plus max_tilt_deg, max_yaw_rate_deg_s and
    drag_compensation (FormationFollower's)."""

    law_class = TrailLaw

    class Params(ColumnParams):
        max_tilt_deg: float | None = pydantic.Field(default=None, gt=0.0, lt=60.0)
        max_yaw_rate_deg_s: float = pydantic.Field(15.0, gt=0)
        drag_compensation: bool = False
