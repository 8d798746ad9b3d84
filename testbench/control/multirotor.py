"""Multirotor guidance and cascaded control: waypoints -> velocity -> acceleration/attitude
-> body rate -> moments -> motor mixer.

Waypoint sequencing: the vehicle flies straight at the active waypoint with the speed profile
v = min(v_max, sqrt(v_end^2 + 2 a_brake d)) (d: distance to go), so it arrives at the corner
speed v_end (braking at a_brake, well inside its acceleration limit), and switches to the next
waypoint only once within the acceptance radius (1 m default). After the switch it keeps at
most v_end^2 / (2 a_max) of momentum past the point (< 1 m). The last waypoint is held
("hold") or the list loops.

Gains (pole placement from the sidecar; `multirotor_gains` computes them):
- rate loop: J w' = M with a first-order motor lag tau: proportional gain k_w = 0.45 / tau
  (crossover a little below the motor pole 1/tau, ~24 deg of phase lost to the lag);
- attitude: angle'' = k_w (k_att (angle_d - angle) - angle') -> s^2 + k_w s + k_w k_att, with
  damping zeta_att = 0.85: k_att = k_w / (4 zeta^2);
- velocity: a = k_v (v_c - v) + k_vi int(...), bandwidth k_v = omega_att / 5 (time-scale
  separation; omega_att = sqrt(k_w k_att)); k_vi = k_v^2 / 8 (integral zero a decade below);
- position (hold): k_pos = k_v / 3.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pydantic

from testbench.control.mixer import Mixer
from testbench.core.interfaces import BuildContext, Controller
from testbench.core.messages import GuidanceStatus, NavEstimate, RotorCommand
from testbench.core.registry import ParamsModel, register
from testbench.core.rotations import dcm_to_euler, euler_to_dcm, wrap_pi
from testbench.core.units import DEG_TO_RAD, STANDARD_GRAVITY_MPS2

G = STANDARD_GRAVITY_MPS2


@dataclass(frozen=True)
class MultirotorGains:
    """k_rate (1/s), k_att (1/s), k_att_yaw (1/s), k_vel (1/s), k_vel_i (1/s^2), k_pos (1/s)."""

    k_rate: float
    k_att: float
    k_att_yaw: float
    k_vel: float
    k_vel_i: float
    k_pos: float


def multirotor_gains(meta: dict, zeta_att: float = 0.85) -> MultirotorGains:
    """Pole-placement gains from the motor time constant (see module docstring)."""
    tau = float(meta.get("motor_time_constant_s", 0.025))
    k_rate = 0.45 / tau
    k_att = k_rate / (4.0 * zeta_att**2)
    omega_att = math.sqrt(k_rate * k_att)
    k_vel = omega_att / 5.0
    return MultirotorGains(k_rate=k_rate, k_att=k_att, k_att_yaw=min(k_att, 2.0), k_vel=k_vel,
                           k_vel_i=k_vel**2 / 8.0, k_pos=k_vel / 3.0)


@register("controller", "multirotor")
class MultirotorController(Controller):
    """Waypoint guidance and cascaded control of a multirotor (see module docstring).

    Params: max_speed_mps (default: mission speed_mps, else sidecar cruise_airspeed_mps, else 5);
    max_climb_rate_mps; brake_accel_mps2 (speed-profile deceleration); corner_speed_mps (speed
    at each intermediate waypoint); max_tilt_deg (default: sidecar max_bank_deg).
    """

    class Params(ParamsModel):
        max_speed_mps: float | None = pydantic.Field(default=None, gt=0.0)
        max_climb_rate_mps: float = pydantic.Field(default=2.0, gt=0.0)
        brake_accel_mps2: float = pydantic.Field(default=1.5, gt=0.0)
        corner_speed_mps: float = pydantic.Field(default=1.0, ge=0.0)
        max_tilt_deg: float | None = pydantic.Field(default=None, gt=0.0, lt=60.0)

    def __init__(self, params: "MultirotorController.Params", *, ctx: BuildContext, mission, aircraft: dict, **_: object):
        self.params = params
        self.mission = mission
        self.meta = dict(aircraft)
        self.mass_kg = float(self.meta["mass_kg"])
        self.inertia = np.diag(np.asarray(self.meta.get("inertia_kg_m2", (0.03, 0.03, 0.05)), float))
        self.mixer = Mixer(self.meta["motors"], self.meta["max_thrust_per_motor_n"], self.meta["yaw_torque_per_thrust_m"])
        self.gains = multirotor_gains(self.meta)
        self.max_speed = float(params.max_speed_mps or getattr(mission, "speed_mps", None)
                               or self.meta.get("cruise_airspeed_mps", 5.0))
        self.max_tilt = (params.max_tilt_deg or float(self.meta.get("max_bank_deg", 30.0))) * DEG_TO_RAD
        wps = np.asarray(getattr(mission, "waypoints_ned_m", np.zeros((0, 3))), float)
        if len(wps) == 0:  # orbit/racetrack: sample the path into waypoints at the mission altitude
            segs = mission.path(self.max_speed)
            pts = []
            for seg in segs:
                for f in np.linspace(0.0, 1.0, 9)[:-1]:
                    pts.append(_point_on(seg, f))
            wps = np.array([[p[0], p[1], -mission.altitude_m] for p in pts])
        self.waypoints = wps
        self.acceptance_m = float(getattr(mission, "acceptance_radius_m", 1.0))
        self.loop = getattr(mission, "at_end", "hold") == "loop" or len(getattr(mission, "waypoints_ned_m", ())) == 0
        self.index = 0
        self.holding = False
        self._reached = False
        self._prev_pt: np.ndarray | None = None
        self._yaw_sp: float | None = None
        self._int_v = np.zeros(3)
        self._t_prev: float | None = None
        self._status = GuidanceStatus(t_s=0.0)

    # -- guidance ------------------------------------------------------------------------

    def _velocity_command(self, pos: np.ndarray) -> np.ndarray:
        target = self.waypoints[self.index]
        d = target - pos
        dist = float(np.linalg.norm(d))
        last = self.index == len(self.waypoints) - 1 and not self.loop
        if self._reached and not last:
            # Switch one tick after arrival, so the tick inside the acceptance radius is
            # reported (GuidanceStatus) with the waypoint it reached.
            self._reached = False
            self._prev_pt = target.copy()
            self.index = (self.index + 1) % len(self.waypoints)
            return self._velocity_command(pos)
        if not self.holding and dist < self.acceptance_m:
            if last:
                self.holding = True
            else:
                self._reached = True
        if self.holding or (last and dist < 3.0 * self.acceptance_m):
            v = self.gains.k_pos * d
        else:
            v_end = 0.0 if last else self.params.corner_speed_mps
            speed = min(self.max_speed, math.sqrt(v_end**2 + 2.0 * self.params.brake_accel_mps2 * dist))
            v = speed * d / max(dist, 1e-6)
        # Respect the climb-rate limit by scaling the whole vector (keeps the straight line).
        if abs(v[2]) > self.params.max_climb_rate_mps:
            v = v * (self.params.max_climb_rate_mps / abs(v[2]))
        h = float(np.hypot(v[0], v[1]))
        if h > self.max_speed:
            v = v * (self.max_speed / h)
        return v

    # -- control -------------------------------------------------------------------------

    def update(self, t_s: float, estimate: NavEstimate, reference=None) -> RotorCommand:
        g = self.gains
        dt = 0.0 if self._t_prev is None else max(0.0, t_s - self._t_prev)
        self._t_prev = t_s
        pos, vel = np.asarray(estimate.pos_ned_m, float), np.asarray(estimate.vel_ned_mps, float)
        rpy = np.asarray(estimate.rpy_rad, float)
        omega = np.asarray(estimate.omega_b_rps, float)
        if self._prev_pt is None:
            self._prev_pt = pos.copy()
            self._yaw_sp = float(rpy[2])

        v_cmd = self._velocity_command(pos)
        e_v = v_cmd - vel
        a_cmd = g.k_vel * e_v + g.k_vel_i * self._int_v
        # Tilt limit: horizontal acceleration at most g tan(max_tilt) (vertical has priority).
        a_h_max = G * math.tan(self.max_tilt)
        a_h = float(np.hypot(a_cmd[0], a_cmd[1]))
        saturated = a_h > a_h_max
        if saturated:
            a_cmd[:2] *= a_h_max / a_h
        if not saturated:
            self._int_v = np.clip(self._int_v + e_v * dt, -3.0, 3.0)
        # Thrust vector: m (a - g) in NED; the body -z axis must point along it.
        f = self.mass_kg * (a_cmd - np.array([0.0, 0.0, G]))
        f[2] = min(f[2], -0.2 * self.mass_kg * G)  # always some upward thrust
        z_b = -f / np.linalg.norm(f)
        x_c = np.array([math.cos(self._yaw_sp), math.sin(self._yaw_sp), 0.0])
        y_b = np.cross(z_b, x_c)
        y_b /= np.linalg.norm(y_b)
        x_b = np.cross(y_b, z_b)
        rpy_d = dcm_to_euler(np.column_stack([x_b, y_b, z_b]))
        R_nb = euler_to_dcm(rpy)
        thrust = float(-f @ R_nb[:, 2])  # project on the actual thrust axis
        thrust = max(thrust, 0.0)

        # Attitude -> body rates (small-angle Euler error, adequate below ~35 deg tilt).
        e_att = np.array([wrap_pi(rpy_d[0] - rpy[0]), wrap_pi(rpy_d[1] - rpy[1]), wrap_pi(self._yaw_sp - rpy[2])])
        w_cmd = np.array([g.k_att * e_att[0], g.k_att * e_att[1], g.k_att_yaw * e_att[2]])
        moments = self.inertia @ (g.k_rate * (w_cmd - omega)) + np.cross(omega, self.inertia @ omega)
        cmd = RotorCommand(motors=self.mixer.commands(thrust, moments))

        target = self.waypoints[self.index]
        self._status = GuidanceStatus(
            t_s=t_s, leg_index=self.index, on_leg=not self.holding, alt_cmd_m=float(-target[2]),
            line_start_ne_m=(float(self._prev_pt[0]), float(self._prev_pt[1])),
            line_end_ne_m=(float(target[0]), float(target[1])),
            target_ned_m=(float(target[0]), float(target[1]), float(target[2])),
            bank_cmd_rad=float(rpy_d[0]),
            cross_track_est_m=_cross_track(pos[:2], self._prev_pt[:2], target[:2]),
        )
        return cmd

    def status(self) -> GuidanceStatus:
        return self._status


def _cross_track(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    d = b - a
    n = float(np.hypot(d[0], d[1]))
    if n < 1e-6:
        return float("nan")
    t = d / n
    e = p - a
    return float(-e[0] * t[1] + e[1] * t[0])


def _point_on(seg, frac: float) -> np.ndarray:
    from testbench.control.paths import ArcSegment

    if isinstance(seg, ArcSegment):
        ang = seg.start_rad + seg.direction * seg.sweep_rad * frac
        return seg.center_ne_m + seg.radius_m * np.array([math.cos(ang), math.sin(ang)])
    return seg.start_ne_m + frac * (seg.end_ne_m - seg.start_ne_m)
