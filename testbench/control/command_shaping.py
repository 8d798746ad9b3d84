"""Shaping of a multirotor's horizontal velocity command, tick by tick: its speed rises at most
at an acceleration (eased in and out at a jerk: an S-curve), and its course turns at most at a
rate (rolled in and out at a turn acceleration). Decreases of speed pass unshaped: the
guidance's braking profile is their law.

A formation leader needs all of it: its followers see its speed and course only through their
relative estimates, and a follower r metres away must fly r times the turn rate faster than
the leader to keep its slot (MultirotorController's params give each limit's meaning).

Plain floats and tuples, as in the cascade that calls it every tick (multirotor.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

TWO_PI = 2.0 * math.pi


def clip(x: float, lo: float, hi: float) -> float:
    """x limited to [lo, hi] (scalar)."""
    return lo if x < lo else hi if x > hi else x


def wrap_pi(angle_rad: float) -> float:
    """Angle wrapped into [-pi, pi) (scalar core.rotations.wrap_pi)."""
    return (angle_rad + math.pi) % TWO_PI - math.pi


def eased_rate(rate: float, error: float, rate_max: float, rate_change_max: float, dt_s: float) -> float:
    """The rate of a shaped quantity one tick of dt_s later: towards the fastest rate that can
    still be brought to zero at the target (rate^2 <= 2 rate_change_max |error|, error = target
    - present, the sign the direction), within rate_max, changed by at most rate_change_max dt_s."""
    want = math.copysign(min(rate_max, math.sqrt(2.0 * rate_change_max * abs(error))), error)
    return rate + clip(want - rate, -rate_change_max * dt_s, rate_change_max * dt_s)


@dataclass(frozen=True)
class ShapingLimits:
    """accel_mps2: the speed's rise (None: a step); jerk_mps3: the change of that rise (None:
    none, needs accel_mps2); turn_rate_rps: the course's rate (None: a step); turn_accel_rps2:
    the change of that rate (None: none, needs turn_rate_rps)."""

    accel_mps2: float | None = None
    jerk_mps3: float | None = None
    turn_rate_rps: float | None = None
    turn_accel_rps2: float | None = None


class CommandShaper:
    """The shaped horizontal command and the rates it is moving at. `last` is the last command
    (NED m/s; None before the first), which the next is shaped from."""

    # Below this speed (m/s) the course is noise: it is not turn-limited.
    TURN_MIN_SPEED_MPS = 0.5

    def __init__(self, limits: ShapingLimits):
        self.limits = limits
        self.last: tuple[float, float, float] | None = None
        self._speed_rate = 0.0  # rate of rise of the speed (m/s^2), with jerk_mps3
        self._course_rate = 0.0  # rate of the course (rad/s), with turn_accel_rps2

    def shape(self, v: tuple[float, float, float], dt_s: float) -> tuple[float, float, float]:
        """v (3,) NED m/s within this tick's limits (its vertical part untouched)."""
        lim, prev = self.limits, self.last
        if prev is None or (lim.accel_mps2 is None and lim.turn_rate_rps is None):
            self.last = v
            return v
        speed, prev_speed = math.hypot(v[0], v[1]), math.hypot(prev[0], prev[1])
        if lim.accel_mps2 is not None:
            if lim.jerk_mps3 is None:
                speed = min(speed, prev_speed + lim.accel_mps2 * dt_s)
            elif speed > prev_speed:
                self._speed_rate = eased_rate(self._speed_rate, speed - prev_speed, lim.accel_mps2, lim.jerk_mps3, dt_s)
                speed = min(speed, prev_speed + self._speed_rate * dt_s)
            else:  # slowing (the braking profile's own law) or holding: no rise under way
                self._speed_rate = 0.0
        course = math.atan2(v[1], v[0])
        if lim.turn_rate_rps is not None and prev_speed > self.TURN_MIN_SPEED_MPS:
            prev_course = math.atan2(prev[1], prev[0])
            err = wrap_pi(course - prev_course)
            if lim.turn_accel_rps2 is None:
                step = lim.turn_rate_rps * dt_s
                course = prev_course + clip(err, -step, step)
            else:
                self._course_rate = eased_rate(self._course_rate, err, lim.turn_rate_rps, lim.turn_accel_rps2, dt_s)
                step = self._course_rate * dt_s
                course = prev_course + (err if abs(step) >= abs(err) and step * err >= 0 else step)
        self.last = (speed * math.cos(course), speed * math.sin(course), v[2])
        return self.last
