"""Closed-loop evaluation of the autopilots on JSBSim, without the engine (the control tests use it).

Flies the issue's two reference missions with the JSBSim adapter and an ideal navigation
estimate built from truth (this module is an evaluation harness, like a test: the controllers
themselves only ever see the NavEstimate), and measures the control targets:
- fixed wing, racetrack at 800 m, legs 2 km, 30 deg turns, 600 s: altitude error rms, true
  cross-track rms on the straight legs, airspeed error on legs, peak bank;
- multirotor through waypoints at 100 m: closest approach to each waypoint before it is
  switched, overshoot past each waypoint (along the incoming leg) and off the leg lines.
The engine reproduces these through the full pipeline (scenarios/fixedwing_racetrack.yaml,
multirotor_waypoints.yaml); this harness needs no engine.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from testbench.core.interfaces import BuildContext, GeodeticOrigin
from testbench.core.messages import NavEstimate, TruthState

ORIGIN = GeodeticOrigin(lat_rad=math.radians(34.0), lon_rad=math.radians(-117.0), alt_m=300.0)
_Z3 = np.zeros((3, 3))


def truth_to_estimate(truth: TruthState, with_airspeed: bool = True) -> NavEstimate:
    """An exact NavEstimate from truth (the truth pass-through, for evaluation only)."""
    return NavEstimate(
        t_s=truth.t_s, pos_ned_m=truth.pos_ned_m, vel_ned_mps=truth.vel_ned_mps, q_nb_wxyz=truth.q_nb_wxyz,
        rpy_rad=truth.rpy_rad, omega_b_rps=truth.omega_eb_b_rps, cov_pos_ned_m2=_Z3, cov_vel_ned_m2s2=_Z3,
        cov_att_rad2=_Z3, airspeed_mps=truth.airspeed_mps if with_airspeed else None,
    )


def make_context(vehicle_id: str = "uav0", physics_rate_hz: float = 100.0) -> BuildContext:
    return BuildContext(vehicle_id=vehicle_id, vehicle_ids=(vehicle_id,), origin=ORIGIN, physics_rate_hz=physics_rate_hz)


def make_dynamics(aircraft: str, physics_rate_hz: float = 100.0):
    from testbench.dynamics.jsbsim_adapter import JSBSimDynamics

    return JSBSimDynamics(aircraft, ORIGIN, physics_rate_hz)


def clear_trim_settings(dyn) -> None:
    """SurfaceCommand is absolute: remove the trim offsets JSBSim's trim leaves in the model's
    fcs/*-trim-cmd-norm properties (they would add to every command)."""
    for name in ("fcs/pitch-trim-cmd-norm", "fcs/roll-trim-cmd-norm", "fcs/yaw-trim-cmd-norm"):
        try:
            dyn.fdm[name] = 0.0
        except Exception:  # noqa: BLE001 - a model without the property
            pass


@dataclass
class Trace:
    """Per-control-tick record: time, truth and the controller's status."""

    t: list = field(default_factory=list)
    truth: list = field(default_factory=list)
    status: list = field(default_factory=list)
    cmd: list = field(default_factory=list)


def fly(dyn, controller, duration_s: float, control_rate_hz: float = 50.0, truth0: TruthState | None = None,
        with_airspeed: bool = True) -> Trace:
    """Close the loop for duration_s; the command is held for one control period."""
    tr = Trace()
    truth = truth0 if truth0 is not None else dyn.truth()
    dt = 1.0 / control_rate_hz
    n = int(round(duration_s * control_rate_hz))
    for _ in range(n):
        cmd = controller.update(truth.t_s, truth_to_estimate(truth, with_airspeed))
        tr.t.append(truth.t_s)
        tr.truth.append(truth)
        tr.status.append(controller.status())
        tr.cmd.append(cmd)
        truth = dyn.step(cmd, dt)
    return tr


def line_cross_track_m(p_ne: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Signed distance (right +) of p from the infinite line a -> b."""
    t = (b - a) / np.linalg.norm(b - a)
    d = p_ne - a
    return float(-d[0] * t[1] + d[1] * t[0])


def fixed_wing_metrics(tr: Trace, settle_s: float = 60.0) -> dict:
    """Scores from truth against the references in the status (after `settle_s`)."""
    alt_err, xt, v_err, bank = [], [], [], []
    for t, s, x in zip(tr.t, tr.status, tr.truth):
        bank.append(abs(float(x.rpy_rad[0])))
        if t < settle_s:
            continue
        alt_err.append(-float(x.pos_ned_m[2]) - s.alt_cmd_m)
        if s.on_leg:
            xt.append(line_cross_track_m(x.pos_ned_m[:2], np.array(s.line_start_ne_m), np.array(s.line_end_ne_m)))
            v_err.append(x.airspeed_mps - s.airspeed_cmd_mps)
    alt_err, xt, v_err = np.array(alt_err), np.array(xt), np.array(v_err)
    return {
        "altitude_error_m": {"rms": float(np.sqrt(np.mean(alt_err**2))), "max": float(np.max(np.abs(alt_err)))},
        "cross_track_error_m": {"rms": float(np.sqrt(np.mean(xt**2))), "max": float(np.max(np.abs(xt)))},
        "airspeed_error_on_legs_mps": {"rms": float(np.sqrt(np.mean(v_err**2))), "max": float(np.max(np.abs(v_err)))},
        "bank_max_deg": float(np.degrees(max(bank))),
        "settle_s": settle_s,
    }


def racetrack_mission(ctx: BuildContext, altitude_m: float = 800.0, leg_length_m: float = 2000.0, airspeed_mps: float = 25.0,
                      turn_bank_deg: float = 28.0):
    from testbench.control.missions import RacetrackMission

    p = RacetrackMission.Params(center={"north_m": 0.0, "east_m": 0.0}, leg_length_m=leg_length_m, turn_bank_deg=turn_bank_deg,
                                heading_deg=0.0, direction="cw", altitude_m=altitude_m, airspeed_mps=airspeed_mps)
    return RacetrackMission(p, ctx=ctx)


def evaluate_fixed_wing(duration_s: float = 600.0, aircraft: str = "tb_fixedwing", control_rate_hz: float = 50.0,
                        turn_bank_deg: float = 28.0, max_bank_deg: float = 30.0, **controller_params) -> dict:
    """Racetrack at 800 m, 2 km legs, 30 deg turns; starts on leg 0 at its start, trimmed."""
    from testbench.control.fixed_wing import FixedWingController
    from testbench.dynamics.jsbsim_adapter import InitialCondition

    ctx = make_context()
    mission = racetrack_mission(ctx, turn_bank_deg=turn_bank_deg)
    dyn = make_dynamics(aircraft)
    seg0 = mission.path(25.0)[0]  # start on leg 0's start, heading along it
    start = seg0.start_ne_m
    truth = dyn.reset(InitialCondition(pos_ned_m=(float(start[0]), float(start[1]), -800.0), heading_rad=0.0, airspeed_mps=25.0))
    clear_trim_settings(dyn)
    ctl = FixedWingController(FixedWingController.Params(max_bank_deg=max_bank_deg, **controller_params), ctx=ctx, mission=mission, aircraft=dyn.aircraft_meta)
    tr = fly(dyn, ctl, duration_s, control_rate_hz, truth)
    out = fixed_wing_metrics(tr, settle_s=min(60.0, 0.2 * duration_s))
    out["turn_bank_deg"], out["max_bank_limit_deg"] = turn_bank_deg, max_bank_deg
    out["turn_radius_m"] = mission.turn_radius_m(25.0)
    return out
