"""Fixed-wing autopilot: L1 lateral guidance, LQI altitude/airspeed hold, roll loop with rate
damping and a turn-coordinating yaw damper.

Structure (all loops run at the controller's rate on the NavEstimate only)
- Guidance: `PathFollower` (guidance.py) on the mission's path gives the bank command,
  limited to max_bank.
- Longitudinal: linear-quadratic regulator with integral action (LQI) on the states
  x = (V, gamma, q, theta, h) of the longitudinal linear model and the integrals of the
  airspeed and altitude errors; inputs (elevator, throttle). All five states are measurable
  from a navigation solution (gamma = asin(-v_D / |v|), V = estimated airspeed or ground
  speed). The altitude reference h_r moves towards the commanded altitude at most at
  max_climb_rate (gamma_r = dh_r/dt / V), so large altitude changes do not saturate the loop.
  In a banked turn the references add the coordinated-turn pitch rate
  q_r = g sin(phi) tan(phi) / V.
- Roll: aileron = trim + k_phi (phi_c - phi) - k_p p + k_i int(phi_c - phi).
- Yaw: rudder = trim - k_r (r - r_c), r_c = g sin(phi) cos(theta) / V (coordinated turn).
Gains: gains.py / design.py (pole placement and LQR on the linear models).
"""

from __future__ import annotations

import math
from operator import mul

import numpy as np
import pydantic

from testbench.control.deferred_status import DeferredStatus
from testbench.control.gains import FixedWingGains, default_gains
from testbench.control.guidance import PathFollower
from testbench.control.paths import LineSegment
from testbench.core.interfaces import BuildContext, Controller
from testbench.core.messages import GuidanceStatus, NavEstimate, SurfaceCommand
from testbench.core.registry import ParamsModel, register
from testbench.core.units import DEG_TO_RAD, STANDARD_GRAVITY_MPS2

G = STANDARD_GRAVITY_MPS2
NAN2 = (float("nan"), float("nan"))


def _clip(x: float, lo: float, hi: float) -> float:
    return lo if x < lo else hi if x > hi else x


def _dot(a, b) -> float:
    """Dot product of two equal-length float sequences (no numpy: these are 7-vectors)."""
    return sum(map(mul, a, b))


def _floats(v) -> list[float]:
    """A short vector (ndarray or sequence) as a list of Python floats."""
    return v.tolist() if isinstance(v, np.ndarray) else [float(x) for x in v]


@register("controller", "fixed_wing")
class FixedWingController(DeferredStatus, Controller):
    """Guidance and autopilot of a fixed-wing aircraft (see the module docstring).

    Params: max_bank_deg (default: the sidecar's max_bank_deg, else 30); airspeed_mps (default:
    the mission's, else the sidecar's cruise_airspeed_mps); l1_period_s, l1_damping (L1 law);
    max_climb_rate_mps; altitude_error_clip_m; roll_lead_s (guidance evaluated this far ahead on
    the current turn to cancel the roll loop's lag, about 1/roll bandwidth plus the roll-in time) (altitude error fed to the LQI is clipped to this);
    gains_aircraft: name of a stored gain set (default: the vehicle's aircraft name; designed at
    start-up from the linear model when none is stored).
    """

    class Params(ParamsModel):
        max_bank_deg: float | None = pydantic.Field(default=None, gt=0.0, lt=80.0)
        airspeed_mps: float | None = pydantic.Field(default=None, gt=0.0)
        l1_period_s: float = pydantic.Field(default=12.0, gt=0.0)
        l1_damping: float = pydantic.Field(default=0.75, gt=0.0)
        max_climb_rate_mps: float = pydantic.Field(default=3.0, gt=0.0)
        altitude_error_clip_m: float = pydantic.Field(default=15.0, gt=0.0)
        roll_lead_s: float = pydantic.Field(default=0.0, ge=0.0)
        gains_aircraft: str | None = None

    def __init__(self, params: "FixedWingController.Params", *, ctx: BuildContext, mission, aircraft: dict, **_: object):
        self.params = params
        self.mission = mission
        self.meta = dict(aircraft or {})
        name = params.gains_aircraft or self.meta.get("name", "")
        gains = default_gains(name)
        if gains is None:
            from testbench.control.design import design_fixed_wing  # needs JSBSim: only when no stored set

            gains = design_fixed_wing(name).gains
        self.gains: FixedWingGains = gains
        max_bank_deg = params.max_bank_deg or float(self.meta.get("max_bank_deg", 30.0))
        self.max_bank_rad = max_bank_deg * DEG_TO_RAD
        self.airspeed_cmd_mps = float(
            params.airspeed_mps or getattr(mission, "airspeed_mps", None) or self.meta.get("cruise_airspeed_mps", gains.trim_airspeed_mps)
        )
        self.segments = mission.path(self.airspeed_cmd_mps)
        self.follower = PathFollower(
            self.segments, bool(getattr(mission, "closed", True)), period_s=params.l1_period_s,
            damping=params.l1_damping, max_bank_rad=self.max_bank_rad,
        )
        self._k_lon = gains.k_lon_array
        # The loops read plain floats each tick (pydantic/dataclass attribute access and numpy
        # on 7-vectors would cost more than the arithmetic).
        self._k_elevator, self._k_throttle = (tuple(float(k) for k in row) for row in gains.k_lon)
        self._roll_lead_s = float(params.roll_lead_s)
        self._max_climb_rate_mps = float(params.max_climb_rate_mps)
        self._alt_error_clip_m = float(params.altitude_error_clip_m)
        self._alt_cmd_by_segment = [self._alt_cmd(i) for i in range(len(self.segments))]
        # GuidanceStatus fields that are fixed per segment: on_leg and the leg's end points.
        self._leg_geometry = [self._segment_leg_geometry(seg) for seg in self.segments]
        self._t_prev: float | None = None
        self._h_ref: float | None = None
        self._int_v = 0.0
        self._int_h = 0.0
        self._int_phi = 0.0

    # -- helpers ---------------------------------------------------------------------------

    def _alt_cmd(self, seg_index: int) -> float:
        seg_alt = getattr(self.mission, "segment_altitude_m", None)
        return float(seg_alt(seg_index)) if seg_alt is not None and len(self.mission.waypoints_ned_m) else float(self.mission.altitude_m)

    @staticmethod
    def _segment_leg_geometry(seg) -> tuple[bool, tuple[float, float], tuple[float, float]]:
        """(on_leg, line_start_ne_m, line_end_ne_m) as GuidanceStatus reports them."""
        on_leg = isinstance(seg, LineSegment) and seg.is_leg
        if not on_leg:
            return False, NAN2, NAN2
        return True, tuple(float(c) for c in seg.start_ne_m), tuple(float(c) for c in seg.end_ne_m)

    def update(self, t_s: float, estimate: NavEstimate, reference=None) -> SurfaceCommand:
        """Surface/throttle command from the estimate (reference unused)."""
        p_n, p_e, _ = _floats(estimate.pos_ned_m)
        v_n, v_e, v_d = _floats(estimate.vel_ned_mps)
        phi = float(estimate.rpy_rad[0])
        ground_speed = math.sqrt(v_n * v_n + v_e * v_e + v_d * v_d)
        turn_rate = G * math.tan(_clip(phi, -1.2, 1.2)) / max(ground_speed, 5.0)
        out = self.follower.update_ne(p_n, p_e, v_n, v_e, lead_s=self._roll_lead_s, turn_rate_rps=turn_rate)
        h_cmd = self._alt_cmd_by_segment[out.segment_index]
        cmd = self.autopilot(t_s, estimate, out.bank_cmd_rad, h_cmd, self.airspeed_cmd_mps)
        self._defer_status(t_s, out.segment_index, h_cmd, out.bank_cmd_rad, out.cross_track_m)
        return cmd

    def _guidance_status(self, t_s: float, seg_index: int, h_cmd: float, bank_cmd: float, cross_track: float) -> GuidanceStatus:
        on_leg, line_start, line_end = self._leg_geometry[seg_index]
        return GuidanceStatus(
            t_s=t_s,
            leg_index=seg_index,
            on_leg=on_leg,
            alt_cmd_m=h_cmd,
            airspeed_cmd_mps=self.airspeed_cmd_mps,
            line_start_ne_m=line_start,
            line_end_ne_m=line_end,
            bank_cmd_rad=bank_cmd,
            cross_track_est_m=cross_track,
        )

    def autopilot(self, t_s: float, estimate: NavEstimate, phi_c: float, h_cmd: float, v_cmd: float) -> SurfaceCommand:
        """Inner loops: bank phi_c (rad), altitude h_cmd (m above origin), airspeed v_cmd (m/s)."""
        g = self.gains
        dt = 0.0 if self._t_prev is None else max(0.0, t_s - self._t_prev)
        self._t_prev = t_s
        v_n, v_e, v_d = _floats(estimate.vel_ned_mps)
        phi, theta, _ = _floats(estimate.rpy_rad)
        p, q, r = _floats(estimate.omega_b_rps)
        ground_speed = math.sqrt(v_n * v_n + v_e * v_e + v_d * v_d)
        v_air = float(estimate.airspeed_mps) if estimate.airspeed_mps is not None else ground_speed
        v_for_rates = max(v_air, 5.0)
        gamma = math.asin(_clip(-v_d / max(ground_speed, 1e-3), -1.0, 1.0))
        h = -float(estimate.pos_ned_m[2])

        # Altitude reference: rate-limited towards the command.
        if self._h_ref is None:
            self._h_ref = h
        step = self._max_climb_rate_mps * dt
        dh = _clip(h_cmd - self._h_ref, -step, step)
        self._h_ref += dh
        gamma_r = math.asin(_clip(dh / dt / v_for_rates, -0.5, 0.5)) if dt > 0 else 0.0

        # Longitudinal LQI: u = u_trim - K_lon x.
        sin_phi = math.sin(phi)
        q_r = G * sin_phi * math.tan(_clip(phi, -1.2, 1.2)) / v_for_rates
        e_v = v_air - v_cmd
        e_h = _clip(h - self._h_ref, -self._alt_error_clip_m, self._alt_error_clip_m)
        x = (e_v, gamma - gamma_r, q - q_r, theta - g.trim_theta_rad, e_h, self._int_v, self._int_h)
        elevator_u = g.trim_elevator - _dot(self._k_elevator, x)
        throttle_u = g.trim_throttle - _dot(self._k_throttle, x)
        elevator = _clip(elevator_u, -1.0, 1.0)
        throttle = _clip(throttle_u, 0.0, 1.0)
        # Integrate unless the actuator the integral mostly drives is saturated in that direction
        # (conditional integration anti-windup).
        if throttle == throttle_u:
            self._int_v = _clip(self._int_v + e_v * dt, -50.0, 50.0)
        if elevator == elevator_u:
            self._int_h = _clip(self._int_h + e_h * dt, -200.0, 200.0)

        # Roll loop and yaw damper.
        e_phi = phi_c - phi
        aileron_u = g.trim_aileron + g.k_phi * e_phi - g.k_p * p + g.k_i_phi * self._int_phi
        aileron = _clip(aileron_u, -1.0, 1.0)
        if aileron == aileron_u:
            self._int_phi = _clip(self._int_phi + e_phi * dt, -0.5, 0.5)
        r_c = G * sin_phi * math.cos(theta) / v_for_rates
        rudder = _clip(g.trim_rudder - g.k_r * (r - r_c), -1.0, 1.0)
        return SurfaceCommand(aileron=aileron, elevator=elevator, rudder=rudder, throttle=throttle)
