"""Formation followers on real airframes: the FormationLaw's velocity command (formation.py)
flown by the multirotor cascade (`formation_follower`) or by the fixed-wing autopilot
(`formation_follower_fw`). No vehicle reads another's state: the law gets the follower's own
NavEstimate and its relative-navigation aid's NeighbourTable."""

from __future__ import annotations

import math

import numpy as np
import pydantic

from testbench.control.fixed_wing import FixedWingController
from testbench.control.formation import FormationLaw, FormationParams
from testbench.control.multirotor import MultirotorController
from testbench.control.paths import LineSegment
from testbench.core.interfaces import BuildContext
from testbench.core.messages import GuidanceStatus, NavEstimate
from testbench.core.registry import register
from testbench.core.rotations import wrap_pi
from testbench.core.units import STANDARD_GRAVITY_MPS2

G = STANDARD_GRAVITY_MPS2


class _HoldMission:
    """Stand-in mission for the autopilots' constructors (the follower has no route)."""

    waypoints_ned_m = np.zeros((1, 3))
    altitude_m = 0.0
    closed = False

    def path(self, _speed):
        return (LineSegment(np.zeros(2), np.array([1.0e5, 0.0])),)


@register("controller", "formation_follower")
class FormationFollower(MultirotorController):
    """Multirotor follower: FormationLaw velocity command through the multirotor cascade
    (its velocity, attitude and rate loops and mixer), nose on the formation course.

    Params: FormationParams, plus max_tilt_deg (default: the sidecar's), max_yaw_rate_deg_s and
    drag_compensation (the cascade's, MultirotorController). A subclass flies
    another law with the same interface by setting law_class (trail.ColumnFollower)."""

    law_class = FormationLaw

    class Params(FormationParams):
        max_tilt_deg: float | None = pydantic.Field(default=None, gt=0.0, lt=60.0)
        max_yaw_rate_deg_s: float = pydantic.Field(15.0, gt=0)
        drag_compensation: bool = False

    def __init__(self, params: "FormationFollower.Params", *, ctx: BuildContext, aircraft: dict, mission=None, **_: object):
        base = MultirotorController.Params(max_speed_mps=params.max_speed_mps, max_climb_rate_mps=params.max_climb_rate_mps,
                                           max_tilt_deg=params.max_tilt_deg, drag_compensation=params.drag_compensation)
        super().__init__(base, ctx=ctx, mission=_HoldMission(), aircraft=aircraft)
        self.law = self.law_class(params, ctx.vehicle_id)
        self._v_cmd = np.zeros(3)
        self._fstatus = GuidanceStatus(t_s=0.0)
        self._fstatus_inputs: tuple | None = None
        self._max_yaw_rate = math.radians(params.max_yaw_rate_deg_s)
        self._t_yaw: float | None = None

    def _velocity_command(self, pos: np.ndarray) -> np.ndarray:  # called by the cascade
        return self._v_cmd

    def update(self, t_s: float, estimate: NavEstimate, reference=None):
        self._v_cmd = self.law.velocity_command(t_s, estimate, reference)
        if self._prev_pt is None:  # first tick: the cascade initialises from the estimate
            self._prev_pt = np.asarray(estimate.pos_ned_m, float).copy()
        # Nose toward the formation course, turning at most max_yaw_rate (smooth for the cameras).
        if self._yaw_sp is None or self._t_yaw is None:
            self._yaw_sp = self.law.course_lead
        else:
            step = self._max_yaw_rate * max(t_s - self._t_yaw, 0.0)
            self._yaw_sp = wrap_pi(self._yaw_sp + float(np.clip(wrap_pi(self.law.course_lead - self._yaw_sp), -step, step)))
        self._t_yaw = t_s
        cmd = super().update(t_s, estimate, reference)
        # Built only when asked (at the record rate), like the cascade's own status.
        self._fstatus_inputs = (t_s, np.array(estimate.pos_ned_m, float), self.law.error_ned_m.copy(), self.law.n_seen)
        return cmd

    def status(self) -> GuidanceStatus:
        if self._fstatus_inputs is not None:
            t_s, pos, err, n_seen = self._fstatus_inputs
            bank = super().status().bank_cmd_rad
            self._fstatus = self.law.status(t_s, pos, bank=bank, error_ned_m=err, n_seen=n_seen)
            self._fstatus_inputs = None
        return self._fstatus


@register("controller", "formation_follower_fw")
class FixedWingFormationFollower(FixedWingController):
    """Fixed-wing follower: FormationLaw velocity command -> course (bank = atan(V k_chi
    course error / g), limited), airspeed (current airspeed plus the ground-speed deficit,
    within [min_airspeed, max_speed]) and altitude (slot altitude) through the fixed-wing
    autopilot's inner loops. Params: FormationParams, k_course (1/s), min_airspeed_mps."""

    class Params(FormationParams):
        k_course: float = pydantic.Field(0.3, gt=0)
        min_airspeed_mps: float = pydantic.Field(15.0, gt=0)
        max_speed_mps: float = pydantic.Field(30.0, gt=0)
        max_bank_deg: float | None = pydantic.Field(default=None, gt=0.0, lt=80.0)
        gains_aircraft: str | None = None

    def __init__(self, params: "FixedWingFormationFollower.Params", *, ctx: BuildContext, aircraft: dict, mission=None, **_: object):
        base = FixedWingController.Params(max_bank_deg=params.max_bank_deg, max_climb_rate_mps=params.max_climb_rate_mps,
                                          gains_aircraft=params.gains_aircraft)
        super().__init__(base, ctx=ctx, mission=_HoldMission(), aircraft=aircraft)
        self.fparams = params
        self.law = FormationLaw(params, ctx.vehicle_id)

    def update(self, t_s: float, estimate: NavEstimate, reference=None):
        p = self.fparams
        v_cmd = self.law.velocity_command(t_s, estimate, reference)
        vel = np.asarray(estimate.vel_ned_mps, float)
        gs = math.hypot(vel[0], vel[1])
        chi = math.atan2(vel[1], vel[0]) if gs > 1.0 else float(estimate.rpy_rad[2])
        chi_c = math.atan2(v_cmd[1], v_cmd[0])
        v_air = float(estimate.airspeed_mps) if estimate.airspeed_mps is not None else gs
        bank = math.atan(max(v_air, 5.0) * p.k_course * wrap_pi(chi_c - chi) / G)
        bank = float(np.clip(bank, -self.max_bank_rad, self.max_bank_rad))
        airspeed = float(np.clip(v_air + (math.hypot(v_cmd[0], v_cmd[1]) - gs), p.min_airspeed_mps, p.max_speed_mps))
        down = self.law.hold_alt_down_m if self.law.hold_alt_down_m is not None else float(estimate.pos_ned_m[2] + self.law.error_ned_m[2])
        h_cmd = -float(down)
        cmd = self.autopilot(t_s, estimate, bank, h_cmd, airspeed)
        self._status = self.law.status(t_s, estimate.pos_ned_m, airspeed, bank)
        return cmd
