"""Multirotor guidance and cascaded control: waypoints -> velocity -> acceleration/attitude
-> body rate -> moments -> motor mixer.

Waypoint sequencing: the vehicle flies straight at the active waypoint with the speed profile
v = min(v_max, sqrt(v_end^2 + 2 a_brake d)) (d: distance to go), so it arrives at the corner
speed v_end (braking at a_brake, well inside its acceleration limit), and switches to the next
waypoint only once within the acceptance radius (1 m default). After the switch it keeps at
most v_end^2 / (2 a_max) of momentum past the point (< 1 m). The last waypoint is held
("hold") or the list loops. The command's speed rise and turn rate are limited (and eased) by
command_shaping.CommandShaper when the params set those limits.

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

from testbench.control.command_shaping import CommandShaper, ShapingLimits
from testbench.control.command_shaping import clip as _clip
from testbench.control.command_shaping import wrap_pi as _wrap_pi
from testbench.control.deferred_status import DeferredStatus
from testbench.control.mixer import Mixer
from testbench.core.errors import InputError
from testbench.core.interfaces import BuildContext, Controller
from testbench.core.messages import GuidanceStatus, NavEstimate, RotorCommand
from testbench.core.registry import ParamsModel, register
from testbench.core.rotor_drag import momentum_drag_per_s
from testbench.core.units import DEG_TO_RAD, STANDARD_GRAVITY_MPS2

G = STANDARD_GRAVITY_MPS2
# A start tilted less than this is level for the velocity loop's bumpless start
# (_start_from_present_tilt): 2 deg is the trim against a ~1 m/s wind.
START_TILT_LEVEL_RAD = math.radians(2.0)

# The loops below run on plain floats and tuples: numpy's per-call overhead on 3-vectors
# (np.cross, np.linalg.norm, small products) is tens of times the arithmetic itself.


def _floats(v) -> list[float]:
    """A short vector (ndarray or sequence) as a list of Python floats."""
    return v.tolist() if isinstance(v, np.ndarray) else [float(x) for x in v]


def _cross(a: tuple[float, float, float], b: tuple[float, float, float]) -> tuple[float, float, float]:
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


def _normalized(v: tuple[float, float, float]) -> tuple[float, float, float]:
    n = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return v[0] / n, v[1] / n, v[2] / n


def _body_z_axis_ned(roll_rad: float, pitch_rad: float, yaw_rad: float) -> tuple[float, float, float]:
    """Third column of R_nb (Z-Y-X Euler, as core.rotations.euler_to_dcm): body z in NED."""
    cr, sr = math.cos(roll_rad), math.sin(roll_rad)
    cp, sp = math.cos(pitch_rad), math.sin(pitch_rad)
    cy, sy = math.cos(yaw_rad), math.sin(yaw_rad)
    return cr * sp * cy + sr * sy, cr * sp * sy - sr * cy, cr * cp


def _euler_from_body_axes(x_b: tuple[float, float, float], y_b: tuple[float, float, float],
                          z_b: tuple[float, float, float]) -> tuple[float, float, float]:
    """Z-Y-X Euler angles (roll, pitch, yaw) of R_nb = [x_b y_b z_b] (body axes in NED as
    columns), as core.rotations.dcm_to_euler."""
    roll = math.atan2(y_b[2], z_b[2])
    pitch = -math.asin(max(-1.0, min(1.0, x_b[2])))
    yaw = math.atan2(x_b[1], x_b[0])
    return roll, pitch, yaw


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
class MultirotorController(DeferredStatus, Controller):
    """Waypoint guidance and cascaded control of a multirotor (see module docstring).

    Params: max_speed_mps (default: mission speed_mps, else sidecar cruise_airspeed_mps, else 5);
    max_climb_rate_mps; brake_accel_mps2 (speed-profile deceleration); corner_speed_mps (speed
    at each intermediate waypoint); max_tilt_deg (default: sidecar max_bank_deg);
    accel_mps2: the commanded horizontal speed rises at most this fast (None: a step, limited
    by the tilt alone); accel_jerk_mps3: with accel_mps2, that rate of rise itself changes at
    most this fast (an S-curve: the speed eases into its rise and out of it onto the new speed,
    where without it the acceleration steps from 0 to accel_mps2 and back; speed decreases
    keep the braking profile's law); turn_rate_deg_s: fly-by corners, the commanded course
    turns at most this fast and the next waypoint becomes active R tan(turn / 2) before the corner
    (R = speed / rate), so the track is an arc tangent to both legs (None: fly over each
    waypoint, then turn as fast as the loops allow); turn_accel_deg_s2: with turn_rate_deg_s,
    the turn rate itself changes at most this fast (a rolled-in, rolled-out arc; the turn then
    starts that much earlier). A formation leader needs all four: its
    followers see its speed and course only through their relative estimates, and a follower
    r metres away must fly r times the turn rate faster than the leader to keep its slot.
    drag_compensation: the velocity loop adds the horizontal acceleration that cancels the
    rotors' drag at the estimated velocity through the air, mu (v_hat - w_hat) (mu from the
    sidecar, core.rotor_drag; w_hat the navigator's wind estimate, NavEstimate.wind_ne_mps,
    zero where it estimates none). Without it the integrator carries the drag: 1.46 m/s^2 at
    4 m/s for tb_quad, 86 % of its range, wound up anew behind every change of speed or
    course; flying at 4 m/s into a 5 m/s wind it saturates, and the proportional term leaves the
    vehicle 0.51 m/s short of its command (0.00003 m/s with it; tests/control/test_drag_compensation.py).
    """

    class Params(ParamsModel):
        max_speed_mps: float | None = pydantic.Field(default=None, gt=0.0)
        max_climb_rate_mps: float = pydantic.Field(default=2.0, gt=0.0)
        brake_accel_mps2: float = pydantic.Field(default=1.5, gt=0.0)
        corner_speed_mps: float = pydantic.Field(default=1.0, ge=0.0)
        max_tilt_deg: float | None = pydantic.Field(default=None, gt=0.0, lt=60.0)
        accel_mps2: float | None = pydantic.Field(default=None, gt=0.0)
        accel_jerk_mps3: float | None = pydantic.Field(default=None, gt=0.0)
        turn_rate_deg_s: float | None = pydantic.Field(default=None, gt=0.0)
        turn_accel_deg_s2: float | None = pydantic.Field(default=None, gt=0.0)
        drag_compensation: bool = False

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
        self._int_v = (0.0, 0.0, 0.0)
        self._t_prev: float | None = None
        # Plain-float copies of what the loops read every tick.
        self._waypoints_ned = [tuple(float(c) for c in w) for w in wps]
        self._inertia_diag = tuple(float(j) for j in np.diag(self.inertia))
        self._corner_speed_mps = float(params.corner_speed_mps)
        self._brake_accel_mps2 = float(params.brake_accel_mps2)
        self._max_climb_rate_mps = float(params.max_climb_rate_mps)
        self._accel_h_max_mps2 = G * math.tan(self.max_tilt)  # tilt limit on horizontal acceleration
        if params.accel_jerk_mps3 is not None and params.accel_mps2 is None:
            raise InputError("control.params.accel_jerk_mps3: limits how fast the speed's rate of rise changes, "
                             "so it needs control.params.accel_mps2 (that rate's limit) too")
        self._turn_rate_rps = None if params.turn_rate_deg_s is None else params.turn_rate_deg_s * DEG_TO_RAD
        self._turn_accel_rps2 = None if params.turn_accel_deg_s2 is None else params.turn_accel_deg_s2 * DEG_TO_RAD
        # The speed-rise and turn limits of the horizontal command (command_shaping.py).
        self.shaper = CommandShaper(ShapingLimits(params.accel_mps2, params.accel_jerk_mps3,
                                                  self._turn_rate_rps, self._turn_accel_rps2))
        self._guidance_dt_s = 0.0
        # mu (1/s) of the drag the velocity loop cancels; None: no compensation.
        self._drag_mu_per_s = (momentum_drag_per_s(self.meta, "controller.params.drag_compensation")
                               if params.drag_compensation else None)
        self._comp_wind_ne: tuple[float, float] | None = None  # the compensation's wind part (m/s^2) last tick

    # -- guidance ------------------------------------------------------------------------

    def _velocity_command(self, pos) -> tuple[float, float, float]:
        """Velocity command (3,) NED m/s towards the active waypoint from the position pos
        ((3,) NED m); subclasses override it to fly other guidance through the cascade."""
        target = self._waypoints_ned[self.index]
        d = (target[0] - pos[0], target[1] - pos[1], target[2] - pos[2])
        dist = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        last = self.index == len(self._waypoints_ned) - 1 and not self.loop
        if self._reached and not last:
            # Switch one tick after arrival, so the tick inside the acceptance radius is
            # reported (GuidanceStatus) with the waypoint it reached.
            self._reached = False
            self._prev_pt = target
            self.index = (self.index + 1) % len(self._waypoints_ned)
            return self._velocity_command(pos)
        if not self.holding and (dist < self.acceptance_m or (not last and dist < self._flyby_distance_m())):
            if last:
                self.holding = True
            else:
                self._reached = True
        if self.holding or (last and dist < 3.0 * self.acceptance_m):
            k = self.gains.k_pos
            v = (k * d[0], k * d[1], k * d[2])
        else:
            v_end = 0.0 if last else self._corner_speed_mps
            speed = min(self.max_speed, math.sqrt(v_end**2 + 2.0 * self._brake_accel_mps2 * dist))
            scale = max(dist, 1e-6)
            v = (speed * d[0] / scale, speed * d[1] / scale, speed * d[2] / scale)
        # Respect the climb-rate limit by scaling the whole vector (keeps the straight line).
        if abs(v[2]) > self._max_climb_rate_mps:
            k = self._max_climb_rate_mps / abs(v[2])
            v = (v[0] * k, v[1] * k, v[2] * k)
        h = math.hypot(v[0], v[1])
        if h > self.max_speed:
            k = self.max_speed / h
            v = (v[0] * k, v[1] * k, v[2] * k)
        if self.holding:
            self.shaper.last = v
            return v
        return self.shaper.shape(v, self._guidance_dt_s)

    def _flyby_distance_m(self) -> float:
        """Distance before the active waypoint at which a fly-by turn starts (0 without a turn
        rate): R tan(turn / 2), R = max_speed / turn rate, turn = the course change there."""
        if self._turn_rate_rps is None or self.index + 1 >= len(self._waypoints_ned):
            return 0.0
        a = self._waypoints_ned[self.index]
        b = self._waypoints_ned[self.index + 1]
        p = self._prev_pt
        turn = abs(_wrap_pi(math.atan2(b[1] - a[1], b[0] - a[0]) - math.atan2(a[1] - p[1], a[0] - p[0])))
        d = self.max_speed / self._turn_rate_rps * math.tan(0.5 * min(turn, math.radians(150.0)))
        if self._turn_accel_rps2 is not None:  # the roll-in covers half its time's distance late
            d += 0.5 * self.max_speed * self._turn_rate_rps / self._turn_accel_rps2
        return d

    # -- control -------------------------------------------------------------------------

    def update(self, t_s: float, estimate: NavEstimate, reference=None) -> RotorCommand:
        dt = 0.0 if self._t_prev is None else max(0.0, t_s - self._t_prev)
        self._t_prev = t_s
        pos = _floats(estimate.pos_ned_m)
        roll, pitch, yaw = _floats(estimate.rpy_rad)
        if self._prev_pt is None:
            self._prev_pt = tuple(pos)
            self._yaw_sp = yaw
        self._guidance_dt_s = dt
        if self.shaper.last is None:  # the shaped command starts from the present velocity
            self.shaper.last = tuple(_floats(estimate.vel_ned_mps))
            self._start_from_present_tilt(roll, pitch, yaw, self._drag_compensation(estimate))
        v_cmd = self._velocity_command(pos)
        accel_cmd = self._velocity_loop(v_cmd, _floats(estimate.vel_ned_mps), dt, self._drag_compensation(estimate))
        thrust, rpy_d = self._thrust_and_attitude(accel_cmd, roll, pitch, yaw)
        moments = self._attitude_and_rate_loops(rpy_d, (roll, pitch, yaw), _floats(estimate.omega_b_rps))
        cmd = RotorCommand(motors=self.mixer.commands(thrust, moments))
        self._defer_status(t_s, self.index, not self.holding, float(self._prev_pt[0]), float(self._prev_pt[1]),
                          rpy_d[0], pos[0], pos[1])
        return cmd

    def _drag_compensation(self, estimate: NavEstimate) -> tuple[float, float]:
        """(north, east) m/s^2 that cancel the rotors' drag at the estimated velocity through
        the estimated air, mu (v_hat - w_hat); zeros without drag_compensation. It leaves the
        velocity loop the plant its gains were placed for, v' = a (multirotor_gains). (The
        command's drag, mu (v_cmd - w_hat), was tried first: it adds mu to the loop's gain to a
        step of the command and flew no better; docs/measurements.md, "The rotor-drag
        compensation".)

        A change of the wind estimate is handed over to the integrator, whose term moves by as
        much the other way, so the acceleration command stays continuous and the wind part
        replaces the integrator's load instead of adding to it. Why: the estimate converges
        from its prior in the first seconds (GNSS on, 3 m/s sigma), and fed forward at once
        that doubled the trimmed start's tilt; paper_swarm_relnav in a steady 5 m/s wind
        (oracle, 120 s) then had the back row up to 97 m off its slot at 4 s (14 m without the
        compensation)."""
        mu = self._drag_mu_per_s
        if mu is None:
            return 0.0, 0.0
        w = estimate.wind_ne_mps
        a_wn, a_we = (0.0, 0.0) if w is None else (-mu * float(w[0]), -mu * float(w[1]))
        if self._comp_wind_ne is not None and (a_wn, a_we) != self._comp_wind_ne:
            k_i = self.gains.k_vel_i
            i_n, i_e, i_d = self._int_v
            self._int_v = (_clip(i_n - (a_wn - self._comp_wind_ne[0]) / k_i, -3.0, 3.0),
                           _clip(i_e - (a_we - self._comp_wind_ne[1]) / k_i, -3.0, 3.0), i_d)
        self._comp_wind_ne = (a_wn, a_we)
        v = estimate.vel_ned_mps
        return mu * float(v[0]) + a_wn, mu * float(v[1]) + a_we

    def _start_from_present_tilt(self, roll: float, pitch: float, yaw: float,
                                 accel_drag_ne: tuple[float, float] = (0.0, 0.0)) -> None:
        """Bumpless start: the velocity loop's horizontal integrator takes the acceleration the
        present tilt gives at constant height, -g z_h / z_d (z the body down axis in NED), less
        the drag compensation's accel_drag_ne (m/s^2) at the start, so
        that a vehicle that starts tilted against a wind (the adapter trims it so) keeps that
        tilt instead of levelling and drifting off until the integrator has wound up again. A
        start within START_TILT_LEVEL_RAD of level leaves it at zero, as before (an estimate's
        tilt there is the alignment's error, ~0.05 deg, not a trim); the integrator's own limit
        applies. paper_swarm_relnav in a steady 5 m/s wind (oracle, 120 s; the vehicles start
        ~10 deg into the wind): formation RMS 12.3 -> 7.5 m, max 99 -> 21 m."""
        z_n, z_e, z_d = _body_z_axis_ned(roll, pitch, yaw)
        if z_d <= 0.5 or math.hypot(z_n, z_e) < math.sin(START_TILT_LEVEL_RAD):
            return  # beyond 60 deg: not a hover to carry on from; below the threshold: level
        k_i = self.gains.k_vel_i
        i_n = _clip((-G * z_n / z_d - accel_drag_ne[0]) / k_i, -3.0, 3.0)
        i_e = _clip((-G * z_e / z_d - accel_drag_ne[1]) / k_i, -3.0, 3.0)
        self._int_v = (i_n, i_e, self._int_v[2])

    def _velocity_loop(self, v_cmd, vel_ned_mps: list[float], dt: float,
                       accel_drag_ne: tuple[float, float] = (0.0, 0.0)) -> tuple[float, float, float]:
        """PI velocity loop: acceleration command (NED, m/s^2) for v_cmd (3,) NED m/s, plus the
        drag compensation's horizontal accel_drag_ne (m/s^2), with the tilt limit on its
        horizontal part (vertical has priority) and conditional integration."""
        g = self.gains
        i_n, i_e, i_d = self._int_v
        e_n, e_e, e_d = (float(v_cmd[0]) - vel_ned_mps[0], float(v_cmd[1]) - vel_ned_mps[1],
                         float(v_cmd[2]) - vel_ned_mps[2])
        a_n = g.k_vel * e_n + g.k_vel_i * i_n + accel_drag_ne[0]
        a_e = g.k_vel * e_e + g.k_vel_i * i_e + accel_drag_ne[1]
        a_d = g.k_vel * e_d + g.k_vel_i * i_d
        a_h = math.hypot(a_n, a_e)
        if a_h > self._accel_h_max_mps2:  # at most g tan(max_tilt) horizontally
            k = self._accel_h_max_mps2 / a_h
            a_n *= k
            a_e *= k
        else:
            self._int_v = (_clip(i_n + e_n * dt, -3.0, 3.0), _clip(i_e + e_e * dt, -3.0, 3.0), _clip(i_d + e_d * dt, -3.0, 3.0))
        return a_n, a_e, a_d

    def _thrust_and_attitude(self, accel_cmd_ned: tuple[float, float, float], roll: float, pitch: float,
                             yaw: float) -> tuple[float, tuple[float, float, float]]:
        """(thrust N, attitude setpoint (roll, pitch, yaw) rad) for an acceleration command:
        the thrust vector is m (a - g) in NED and the body -z axis must point along it; the
        thrust is its projection on the present body -z axis."""
        m = self.mass_kg
        a_n, a_e, a_d = accel_cmd_ned
        f = (m * a_n, m * a_e, min(m * (a_d - G), -0.2 * m * G))  # always some upward thrust
        z_b = _normalized((-f[0], -f[1], -f[2]))
        x_c = (math.cos(self._yaw_sp), math.sin(self._yaw_sp), 0.0)
        y_b = _normalized(_cross(z_b, x_c))
        x_b = _cross(y_b, z_b)
        z_now = _body_z_axis_ned(roll, pitch, yaw)
        thrust = max(-(f[0] * z_now[0] + f[1] * z_now[1] + f[2] * z_now[2]), 0.0)
        return thrust, _euler_from_body_axes(x_b, y_b, z_b)

    def _attitude_and_rate_loops(self, rpy_d: tuple[float, float, float], rpy: tuple[float, float, float],
                                 omega_b_rps: list[float]) -> tuple[float, float, float]:
        """Body moments (N m, FRD): attitude error (small-angle Euler error, adequate below
        ~35 deg tilt) -> rate command -> M = J k_rate (w_cmd - w) + w x J w (J diagonal)."""
        g = self.gains
        w_x, w_y, w_z = omega_b_rps
        wc_x = g.k_att * _wrap_pi(rpy_d[0] - rpy[0])
        wc_y = g.k_att * _wrap_pi(rpy_d[1] - rpy[1])
        wc_z = g.k_att_yaw * _wrap_pi(self._yaw_sp - rpy[2])
        j_x, j_y, j_z = self._inertia_diag
        gyro = _cross((w_x, w_y, w_z), (j_x * w_x, j_y * w_y, j_z * w_z))
        return (j_x * (g.k_rate * (wc_x - w_x)) + gyro[0],
                j_y * (g.k_rate * (wc_y - w_y)) + gyro[1],
                j_z * (g.k_rate * (wc_z - w_z)) + gyro[2])

    def _guidance_status(self, t_s: float, index: int, on_leg: bool, prev_n: float, prev_e: float, bank_cmd: float,
                         p_n: float, p_e: float) -> GuidanceStatus:
        target = self._waypoints_ned[index]
        # The commanded altitude is that of the straight 3-D leg at the vehicle's progress along
        # it (not the next waypoint's altitude, which would count a climb in progress as error).
        prev_d = self._waypoints_ned[index - 1][2] if index > 0 else target[2]
        d_n, d_e = target[0] - prev_n, target[1] - prev_e
        length2 = d_n * d_n + d_e * d_e
        frac = 1.0 if length2 < 1e-6 else min(1.0, max(0.0, ((p_n - prev_n) * d_n + (p_e - prev_e) * d_e) / length2))
        alt_cmd = -(prev_d + frac * (target[2] - prev_d))
        return GuidanceStatus(
            t_s=t_s, leg_index=index, on_leg=on_leg, alt_cmd_m=alt_cmd,
            line_start_ne_m=(prev_n, prev_e),
            line_end_ne_m=(target[0], target[1]),
            target_ned_m=target,
            bank_cmd_rad=bank_cmd,
            cross_track_est_m=_cross_track_m(p_n, p_e, prev_n, prev_e, target[0], target[1]),
        )


def _cross_track_m(p_n: float, p_e: float, a_n: float, a_e: float, b_n: float, b_e: float) -> float:
    """Cross-track (m, right +) of p from the line a -> b; nan when a and b coincide."""
    d_n, d_e = b_n - a_n, b_e - a_e
    n = math.hypot(d_n, d_e)
    if n < 1e-6:
        return float("nan")
    t_n, t_e = d_n / n, d_e / n
    e_n, e_e = p_n - a_n, p_e - a_e
    return -e_n * t_e + e_e * t_n


def _point_on(seg, frac: float) -> np.ndarray:
    from testbench.control.paths import ArcSegment

    if isinstance(seg, ArcSegment):
        ang = seg.start_rad + seg.direction * seg.sweep_rad * frac
        return seg.center_ne_m + seg.radius_m * np.array([math.cos(ang), math.sin(ang)])
    return seg.start_ne_m + frac * (seg.end_ne_m - seg.start_ne_m)
