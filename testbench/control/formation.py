"""Formation followers: hold a slot relative to the neighbours this vehicle ESTIMATES.

No vehicle reads another's state: a follower gets only its own NavEstimate and, as
`reference`, the NeighbourTable of its relative-navigation aid (id -> RelativeEstimate:
r_j = p_j - p_self in NED, its rate w_j, covariances).

Formation frame: forward along the formation course chi (the leader's course, which the
follower estimates from its neighbours' estimated velocities v_j = v_self + w_j), right,
down. R(chi) maps formation to NED: forward = (cos chi, sin chi, 0), right = (-sin chi,
cos chi, 0). Slots s_k (forward, right, down, m) are given per vehicle id.

Consensus law (over fresh neighbours j with weights a_j, leader weight configurable):
  e = sum_j a_j [r_j - R(chi) (s_j - s_self)] / sum_j a_j          (slot error, NED, m)
(j over the neighbours ahead, see ahead_only)
  v_ff = low-pass of sum_j a_j v_j / sum_j a_j                       (velocity feed-forward)
  v_rot = omega z x sum_j a_j R(chi) (s_self - s_j)                   (the slot's turn)
  v_cmd = v_ff + tau_ff a_ff + v_rot + k_slot e + sum_{j: |r_j| < margin} k_rep (|r_j| - margin) r_j / |r_j|
(a_ff the low-passed rate of v_ff; chi in R(chi) likewise carried forward by omega times its
filter's time constant: the low-passes must smooth the estimates, not delay them; with
course_accel_tau_s the course's acceleration alpha, the low-passed rate of omega, carries chi
forward too, for the lag the two low-passes leave in a turn's roll-in and roll-out)
omega is the low-passed rate of chi: while the formation turns, a slot d metres from the
neighbours followed moves omega d faster than they do (without v_rot a follower 300 m out lags
its slot by omega d / k_slot, 6.5 m at 0.5 deg/s).
then slew-limited to max_accel_mps2 (a jump of an estimate must not become a 40 degree tilt:
the vehicle's own cameras would lose their tracks, and its attitude errors enter the bearings).
The course chi: from the layout of the followed neighbours when they are spread enough
(geometry_course); when the neighbours ahead give no layout (one of them, or too close together)
and the leader is not among them, from the layout of those and the neighbours beside us (their
slots level with ours); else from the followed neighbours' low-passed velocity.
"Fresh" neighbours: estimates younger than max_age_s whose 1-sigma position uncertainty is
below max_sigma_m (an estimate held by ranges alone drifts across the line of sight).
With nobody fresh in sight it holds its last course and speed at its last altitude.
The multirotor follower turns its nose toward the course at most max_yaw_rate_deg_s.
The multirotor follower feeds v_cmd to the multirotor cascade's inner loops (velocity ->
attitude -> rate -> mixer) with the nose on the course; the fixed-wing follower turns v_cmd
into bank (course error), airspeed and altitude commands for the fixed-wing autopilot (both in
formation_followers.py; this module is the law, independent of the airframe).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pydantic

from testbench.core.errors import InputError
from testbench.core.messages import GuidanceStatus, NavEstimate
from testbench.core.registry import ParamsModel
from testbench.core.rotations import wrap_pi


def formation_rotation(course_rad: float) -> np.ndarray:
    """R (3, 3): formation (forward, right, down) -> NED for a course chi (rad)."""
    c, s = math.cos(course_rad), math.sin(course_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def geometry_course(neighbours, slots: dict, min_spread_m: float) -> float | None:
    """The formation's course chi (rad) from the layout of the neighbours we estimate: the 2-D
    rotation that best maps their slots (forward, right; about their mean) onto their estimated
    relative positions (north, east; about their mean), a Procrustes fit: chi = atan2(sum a x b,
    sum a . b). None with fewer than two neighbours or slots spread less than min_spread_m (RMS).

    In a turn the formation pivots about the leader, so the rows behind it do not fly the
    leader's course (the back row of a 300 m arrowhead turning right at 0.5 deg/s moves 40 deg
    left of it); their neighbours' velocities then point the wrong way, their layout does not.
    Our own position does not enter (it is what the slot law corrects)."""
    if len(neighbours) < 2:
        return None
    a = np.array([slots[e.peer_id][:2] for e in neighbours], float)
    b = np.array([np.asarray(e.pos_ned_m, float)[:2] for e in neighbours])
    a -= a.mean(axis=0)
    b -= b.mean(axis=0)
    if math.sqrt(float((a * a).sum()) / len(a)) < min_spread_m:
        return None
    cross = float((a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]).sum())
    dot = float((a * b).sum())
    return math.atan2(cross, dot)


def formation_errors(pos_ned_by_id: dict[str, np.ndarray], course_rad: float, slots: dict[str, Any],
                     leader_id: str) -> dict[str, np.ndarray]:
    """Slot error (NED, m) of every vehicle relative to the leader: p_k - p_leader - R(chi)
    (s_k - s_leader). A pure function for scoring (truth positions and the leader's course)."""
    R = formation_rotation(course_rad)
    p0, s0 = np.asarray(pos_ned_by_id[leader_id], float), np.asarray(slots[leader_id], float)
    return {k: np.asarray(p, float) - p0 - R @ (np.asarray(slots[k], float) - s0)
            for k, p in pos_ned_by_id.items() if k != leader_id and k in slots}


class FollowerParams(ParamsModel):
    """What every follower's law takes: slots (id -> (forward_m, right_m, down_m) in the
    formation frame, own id required); k_slot (1/s): gain on the slot error; max_age_s,
    max_sigma_m: neighbour estimates older or more uncertain (sqrt trace of the position
    covariance) than this are not used; margin_m, k_repulse (1/s): collision-avoidance margin
    and gain; max_speed_mps, max_climb_rate_mps; max_accel_mps2: slew limit of the velocity
    command."""

    slots: dict[str, tuple[float, float, float]]
    k_slot: float = pydantic.Field(0.4, gt=0)
    max_age_s: float = pydantic.Field(2.0, gt=0)
    max_sigma_m: float = pydantic.Field(3.0, gt=0)
    margin_m: float = pydantic.Field(15.0, ge=0)
    k_repulse: float = pydantic.Field(0.5, ge=0)
    max_speed_mps: float = pydantic.Field(10.0, gt=0)
    max_climb_rate_mps: float = pydantic.Field(2.0, gt=0)
    max_accel_mps2: float = pydantic.Field(1.5, gt=0)


class FormationParams(FollowerParams):
    """slots: id -> (forward_m, right_m, down_m) in the formation frame (own id required);
    leader_id, leader_weight: weight of the leader's term (others 1); k_slot (1/s): slot gain;
    ff_tau_s: low-pass time constant of the velocity feed-forward (seconds, not less: v_j is
    our own velocity plus a relative velocity the neighbour filter estimates with a lag, so a
    fast feed-forward feeds our own velocity back through that lag; with 1 s the back rows of
    the arrowhead swung 20-60 m about their slots); course_rate_tau_s: that of the course rate
    omega (v_rot; 0 leaves v_rot out), clamped to max_course_rate_deg_s;
    course_accel_tau_s: that of the course's acceleration alpha (0: none), the rate of omega,
    which leads chi by tau course_rate_tau_s alpha (tau the course's own low-pass,
    geometry_tau_s or ff_tau_s): the two first-order low-passes follow a ramp of the rate (the
    leader rolling into a turn) with that lag, and the rows of an arrowhead add it up; clamped
    to max_course_accel_deg_s2, and held at 0 below course_full_speed_mps (or
    course_min_speed_mps), where the course wanders by degrees;
    max_course_slew_deg_s: the course this follower holds turns at most this fast (set it a
    little above the leader's turn-rate limit; None: no limit). Why: the layout course jumps
    when the set of followed neighbours changes (one goes stale, or a new one turns fresh) and
    rotates when a neighbour ahead lags its slot; with a 100 m spread and a slot 130-170 m
    from the neighbours, every degree of that moves our target 2-3 m, so the rows of an
    arrowhead amplify the lag of the rows ahead (the back row ran 40 m behind in the start-up);
    course_coast_s: for this long after the last layout course, a follower left with fewer than
    two fresh neighbours, the leader not among them, carries its course on with its course
    rate instead of taking the velocity course: in a turn a neighbour off the pivot flies
    10 deg or more off the leader's course (the back row of the arrowhead, left with one
    neighbour for 6 s in a turn, took it, and was 29 m off its slot when the layout came
    back); 0 disables;
    min_geometry_spread_m: the followed neighbours' slots must spread this far (RMS about their
    mean) for their layout to give the course (geometry_course), low-passed with
    geometry_tau_s; course_min_speed_mps: below
    this the course is held; course_full_speed_mps: below this speed the velocity course is
    low-passed further, with a time constant ff_tau_s ((full / speed)^2 - 1) (None: not). Why:
    that course is the direction of our velocity plus a neighbour's relative velocity, whose
    error of 0.1-0.2 m/s is 3-10 deg of course at 1-3 m/s; its variance grows as 1/speed^2, so
    the averaging time must too. In the leader's start-up (0 to 4 m/s in 16 s) the first row's
    velocity course erred by 3-16 deg, and its slot, 100 m from the leader, by 4 m;
    margin_m, k_repulse (1/s): collision-avoidance margin and gain; max_age_s, max_sigma_m:
    estimates older or more uncertain (sqrt trace of the position covariance) than this are
    ignored; max_speed_mps, max_climb_rate_mps; max_accel_mps2: slew
    limit of the velocity command; ahead_only: follow only the neighbours whose slot lies ahead
    of ours (closer to the leader; all of them when none ahead is fresh), so that the lag of the
    followers behind does not drag the formation (a directed leader-follower chain)."""

    leader_id: str | None = None
    leader_weight: float = pydantic.Field(2.0, gt=0)
    ff_tau_s: float = pydantic.Field(4.0, ge=0)
    course_rate_tau_s: float = pydantic.Field(4.0, ge=0)
    course_accel_tau_s: float = pydantic.Field(0.0, ge=0)
    max_course_accel_deg_s2: float = pydantic.Field(0.1, gt=0)
    max_course_rate_deg_s: float = pydantic.Field(2.0, gt=0)
    max_course_slew_deg_s: float | None = pydantic.Field(None, gt=0)
    course_coast_s: float = pydantic.Field(0.0, ge=0)
    min_geometry_spread_m: float = pydantic.Field(30.0, gt=0)
    geometry_tau_s: float = pydantic.Field(2.0, ge=0)
    course_min_speed_mps: float = pydantic.Field(1.0, ge=0)
    course_full_speed_mps: float | None = pydantic.Field(None, gt=0)
    ahead_only: bool = True


class FollowerLaw:
    """What the followers' laws share: the limits on the velocity command (params p with
    max_speed_mps, max_climb_rate_mps, max_accel_mps2; the last output in v_out) and the
    GuidanceStatus of the slot estimated (error_ned_m, n_seen)."""

    p: Any
    v_out: np.ndarray | None
    error_ned_m: np.ndarray
    n_seen: int

    t_prev: float | None

    def _step_dt(self, t_s: float) -> float:
        """Seconds since the last command (0 at the first), t_s kept for the next."""
        dt = 0.0 if self.t_prev is None else max(t_s - self.t_prev, 0.0)
        self.t_prev = t_s
        return dt

    def _limit(self, v: np.ndarray, dt: float) -> np.ndarray:
        self.v_out = limit_velocity(v, self.v_out, dt, self.p.max_speed_mps, self.p.max_climb_rate_mps, self.p.max_accel_mps2)
        return self.v_out.copy()

    def status(self, t_s: float, pos: np.ndarray, airspeed_cmd: float = float("nan"), bank: float = float("nan"),
               error_ned_m: np.ndarray | None = None, n_seen: int | None = None) -> GuidanceStatus:
        return slot_status(t_s, pos, self.error_ned_m if error_ned_m is None else error_ned_m,
                           self.n_seen if n_seen is None else n_seen, airspeed_cmd, bank)


def add_repulsion(v: np.ndarray, neighbours, margin_m: float, k_repulse: float) -> None:
    """Collision avoidance, in place on v (3,) NED m/s: k_repulse (|r| - margin) r / |r| for
    every neighbour estimate with |r| < margin_m (r its relative position, NED m): away from it."""
    for en in neighbours:
        r = np.asarray(en.pos_ned_m, float)
        d = float(np.linalg.norm(r))
        if 1e-6 < d < margin_m:
            v += k_repulse * (d - margin_m) * r / d


class FormationLaw(FollowerLaw):
    """The consensus slot law (module docstring), independent of the airframe."""

    def __init__(self, p: FormationParams, self_id: str):
        if self_id not in p.slots:
            raise InputError(f"control.params.slots: no slot for this vehicle {self_id!r}")
        self.p = p
        self.self_id = self_id
        self.s_self = np.asarray(p.slots[self_id], float)
        self.course: float | None = None
        self.course_rate_rps = 0.0
        self.course_accel_rps2 = 0.0  # low-passed rate of course_rate_rps (course_accel_tau_s)
        self.course_lead: float | None = None  # course carried forward by its filter's lag
        self._course_lag_s = 0.0
        self._geometry_t_s: float | None = None  # when the layout last gave the course
        self.accel_ff = np.zeros(3)
        self.v_ff: np.ndarray | None = None
        self.hold_alt_down_m: float | None = None
        self.t_prev: float | None = None
        self.n_seen = 0
        self.error_ned_m = np.zeros(3)
        self.v_out: np.ndarray | None = None

    def velocity_command(self, t_s: float, est: NavEstimate, table: dict | None) -> np.ndarray:
        """v_cmd (3,) NED m/s from the own estimate and the NeighbourTable."""
        p = self.p
        pos, vel = np.asarray(est.pos_ned_m, float), np.asarray(est.vel_ned_mps, float)
        dt = self._step_dt(t_s)
        if self.course is None:
            self.course = self.course_lead = float(est.rpy_rad[2])
            self.v_ff = np.array([vel[0], vel[1], 0.0])
        if self.v_out is None:
            self.v_out = vel.copy()
        fresh = [e for k, e in (table or {}).items()
                 if k in p.slots and k != self.self_id and t_s - e.t_s <= p.max_age_s and e.sigma_m <= p.max_sigma_m]
        beside = fresh  # neighbours whose slot is not behind ours (the course's fallback layout)
        if p.ahead_only:
            ahead = [e for e in fresh if p.slots[e.peer_id][0] > self.s_self[0] + 1.0]
            beside = [e for e in fresh if p.slots[e.peer_id][0] > self.s_self[0] - 1.0]
            fresh = ahead or fresh
        self.n_seen = len(fresh)
        if not fresh:  # hold course, speed and altitude
            if self.hold_alt_down_m is None:
                self.hold_alt_down_m = float(pos[2])
            v = self.v_ff.copy()
            v[2] = float(np.clip(0.5 * (self.hold_alt_down_m - pos[2]), -p.max_climb_rate_mps, p.max_climb_rate_mps))
            self.error_ned_m = np.zeros(3)
            return self._limit(v, dt)
        self.hold_alt_down_m = None
        w = np.array([p.leader_weight if e.peer_id == p.leader_id else 1.0 for e in fresh])
        w /= w.sum()
        v_nb = np.array([vel + np.asarray(e.vel_ned_mps, float) for e in fresh])
        v_mean = w @ v_nb
        a = 1.0 if p.ff_tau_s <= 0 else min(1.0, dt / p.ff_tau_s)
        dv_ff = a * (v_mean - self.v_ff)
        self.v_ff = self.v_ff + dv_ff
        b = min(1.0, dt / p.course_rate_tau_s) if p.course_rate_tau_s > 0 else 0.0
        if dt > 0:
            self.accel_ff = self.accel_ff + b * (dv_ff / dt - self.accel_ff)
        course = None
        om_max = math.radians(p.max_course_rate_deg_s)
        geo = geometry_course(fresh, p.slots, p.min_geometry_spread_m)
        if geo is None and len(beside) > len(fresh) and all(e.peer_id != p.leader_id for e in fresh):
            # No layout from the neighbours ahead (one of them, or too close together), and the
            # leader not among them: the layout of those and the ones beside us still gives the
            # formation's orientation, where a neighbour's velocity does not
            # (in a turn it flies 20 deg off the leader's course at 173 m from it). The coast
            # below ran out after 20 s on one neighbour, and the course then swung to that
            # velocity at the slew limit (LED run: 15 m off the slot).
            geo = geometry_course(beside, p.slots, p.min_geometry_spread_m)
        if geo is not None:
            # The followed neighbours' layout gives the formation's orientation directly.
            g = min(1.0, dt / p.geometry_tau_s) if p.geometry_tau_s > 0 else 1.0
            course = self.course + g * wrap_pi(geo - self.course)
            self._course_lag_s = p.geometry_tau_s
            self._geometry_t_s = t_s
        elif (self._geometry_t_s is not None and t_s - self._geometry_t_s <= p.course_coast_s
              and all(e.peer_id != p.leader_id for e in fresh)):
            # Coast: the layout course turned at course_rate until a moment ago (the leader's
            # own velocity, when we see it, gives its course directly).
            course = self.course + float(np.clip(self.course_rate_rps, -om_max, om_max)) * dt
        elif (speed := math.hypot(self.v_ff[0], self.v_ff[1])) >= p.course_min_speed_mps:
            course = math.atan2(self.v_ff[1], self.v_ff[0])
            self._course_lag_s = p.ff_tau_s
            if p.course_full_speed_mps is not None and speed < p.course_full_speed_mps and p.ff_tau_s > 0:
                # (Not added to the lag the course is led by: at such speeds the course rate is
                # noise, and times tau it would move the course more than the smoothing saves.)
                tau = p.ff_tau_s * ((p.course_full_speed_mps / speed) ** 2 - 1.0)
                course = self.course + (1.0 - math.exp(-dt / tau)) * wrap_pi(course - self.course)
        if course is not None and p.max_course_slew_deg_s is not None:
            step = math.radians(p.max_course_slew_deg_s) * dt
            course = self.course + float(np.clip(wrap_pi(course - self.course), -step, step))
        if course is not None:
            if dt > 0 and b > 0:
                rate = wrap_pi(course - self.course) / dt
                rate_before = self.course_rate_rps
                self.course_rate_rps += b * (rate - self.course_rate_rps)
                if p.course_accel_tau_s > 0:
                    # Below course_full_speed_mps (the start-up) the course wanders by degrees,
                    # and its second difference is that wander, not a turn: alpha decays to 0.
                    slow = math.hypot(self.v_ff[0], self.v_ff[1]) < (p.course_full_speed_mps or p.course_min_speed_mps)
                    accel = 0.0 if slow else (self.course_rate_rps - rate_before) / dt
                    c = min(1.0, dt / p.course_accel_tau_s)
                    self.course_accel_rps2 += c * (accel - self.course_accel_rps2)
                    acc_max = math.radians(p.max_course_accel_deg_s2)
                    self.course_accel_rps2 = float(np.clip(self.course_accel_rps2, -acc_max, acc_max))
            self.course = course
        # Lead: a first-order low-pass lags a ramp by its time constant (2 deg of course at
        # 0.5 deg/s through 4 s, 3.5 m at 100 m), so the filtered course and velocity are carried
        # forward by their estimated rates times that lag. With the course's acceleration alpha
        # estimated too (course_accel_tau_s), the second-order lags go as well: for a course
        # chi(t) with constant alpha, the course low-passed by tau (the lag) and its rate
        # low-passed by tau_w give chi = course + tau w_hat + tau tau_w alpha and the rate now
        # w = w_hat + (tau + tau_w) alpha. Without them each row of the arrowhead lags its slot
        # across the course by about 7 s^2 times alpha times its distance from the neighbours it
        # follows, and the rows add up (paper_swarm_relnav: the back row 22 s^2 alpha per metre
        # behind the leader, 1.5-1.7 m RMS of its 2.3-2.6 m across the course).
        # The rate in v_rot is not led by alpha: measured so (w_hat + (tau + tau_w) alpha), the
        # course's wander in straight flight (alpha_hat 0.005-0.013 deg/s^2 RMS) went into every
        # follower's velocity command, and the arrowhead swung about its slots with a 15 s period
        # (LED, 300 s: slot-error rate 0.23-0.48 -> 0.40-0.69 m/s RMS, relnav mean 0.165 / 0.180 /
        # 0.161 -> 0.176 / 0.193 / 0.177 m); through the course, the slot loop filters it.
        lag_s, alpha = self._course_lag_s, self.course_accel_rps2
        om = float(np.clip(self.course_rate_rps, -om_max, om_max)) if p.course_rate_tau_s > 0 else 0.0
        rate_lead = self.course_rate_rps + alpha * p.course_rate_tau_s
        self.course_lead = self.course + (float(np.clip(rate_lead, -om_max, om_max)) * lag_s if p.course_rate_tau_s > 0 else 0.0)
        v_lead = self.v_ff + (p.ff_tau_s * self.accel_ff if p.course_rate_tau_s > 0 else 0.0)
        R = formation_rotation(self.course_lead)
        # Offsets of our slot from the followed neighbours' slots, in NED (weighted).
        d_slot = sum(wi * (R @ (self.s_self - np.asarray(p.slots[en.peer_id], float))) for wi, en in zip(w, fresh))
        e = sum(wi * np.asarray(en.pos_ned_m, float) for wi, en in zip(w, fresh)) + d_slot
        self.error_ned_m = np.asarray(e, float)
        v_rot = np.array([-om * d_slot[1], om * d_slot[0], 0.0])  # omega z x d (z down: course rate > 0 turns right)
        v = v_lead + v_rot + p.k_slot * self.error_ned_m
        add_repulsion(v, fresh, p.margin_m, p.k_repulse)
        return self._limit(v, dt)


def limit_velocity(v, v_last: np.ndarray | None, dt: float, max_speed_mps: float, max_climb_rate_mps: float,
                   max_accel_mps2: float) -> np.ndarray:
    """A follower's velocity command (3,) NED m/s within its limits: climb rate, horizontal
    speed, then the slew limit |v - v_last| <= max_accel dt from the last output (v_last None
    or dt 0: no slew limit). Returns a new array."""
    v = np.asarray(v, float).copy()
    v[2] = float(np.clip(v[2], -max_climb_rate_mps, max_climb_rate_mps))
    h = math.hypot(v[0], v[1])
    if h > max_speed_mps:
        v[:2] *= max_speed_mps / h
    if v_last is not None and dt > 0:
        dv = v - v_last
        n = float(np.linalg.norm(dv))
        lim = max_accel_mps2 * dt
        if n > lim:
            v = v_last + dv * (lim / n)
    return v


def slot_status(t_s: float, pos, error_ned_m, n_seen: int, airspeed_cmd: float = float("nan"),
                bank: float = float("nan")) -> GuidanceStatus:
    """A follower's GuidanceStatus: target_ned_m = the slot point this vehicle estimates (own
    position + slot error), leg_index = number of neighbours used, on_leg = at least one."""
    target = np.asarray(pos, float) + np.asarray(error_ned_m, float)
    return GuidanceStatus(t_s=t_s, leg_index=n_seen, on_leg=n_seen > 0, alt_cmd_m=float(-target[2]),
                          airspeed_cmd_mps=airspeed_cmd, target_ned_m=tuple(float(x) for x in target), bank_cmd_rad=bank)
