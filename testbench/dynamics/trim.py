"""Trim a JSBSim model with JSBSim's own trim (FGTrim), in SI units.

Fixed wing: JSBSim's full trim (tFull: alpha -> wdot, throttle -> udot, pitch trim -> qdot,
phi -> vdot, aileron -> pdot, rudder -> rdot, beta -> heading minus track) in straight flight
at a given true airspeed, altitude above mean sea level and flight-path angle.
Multirotor: hover. All motors get the same thrust command, found by a secant iteration on
wdot from the sidecar's `hover_throttle_norm` (JSBSim's local gravity differs from g0 by a
few parts per thousand, so the sidecar value is only the starting point).

Example::

    from testbench.dynamics.trim import trim, trimmed_exec
    t = trim("tb_fixedwing", 25.0, 1000.0)          # TrimResult
    fdm, t = trimmed_exec("tb_fixedwing", 25.0, 1000.0, dt_s=0.01)  # ready to fly
"""

from __future__ import annotations

import logging
import math
import os
from dataclasses import asdict, dataclass

os.environ.setdefault("JSBSIM_DEBUG", "0")  # no start-up banner on stdout

import jsbsim  # noqa: E402

from testbench.core.errors import InputError  # noqa: E402
from testbench.dynamics.catalog import aircraft_dir, aircraft_meta  # noqa: E402

log = logging.getLogger(__name__)

FT_TO_M = 0.3048
M_TO_FT = 1.0 / FT_TO_M
DEFAULT_DT_S = 1.0 / 120.0
"""JSBSim's own default step; trim and linearisation do not depend on it."""

_TRIM_FULL = 1  # JSBSim TrimMode tFull


@dataclass(frozen=True)
class TrimResult:
    """A trimmed flight condition.

    Angles in rad, speeds in m/s, altitude in m above mean sea level. Controls are the
    normalised JSBSim commands the adapter writes: throttle 0..1 (fcs/throttle-cmd-norm),
    elevator / aileron / rudder -1..1 (JSBSim signs: elevator > 0 trailing edge down, aileron
    > 0 rolls right, rudder > 0 yaws left). `elevator_norm` is elevator-cmd-norm plus the pitch
    trim JSBSim's trim moved (fcs/pitch-trim-cmd-norm), i.e. the elevator command that holds
    the trim with the pitch trim at zero; `trimmed_exec` leaves the model in that state.
    Residuals are the body accelerations left after trimming: u, v, w in m/s^2, p, q, r
    in rad/s^2. `motor_throttles_norm` holds one command per motor for a multirotor, and
    (throttle_norm,) for a fixed wing.
    """

    aircraft: str
    kind: str
    airspeed_mps: float
    altitude_m: float
    flight_path_rad: float
    alpha_rad: float
    beta_rad: float
    theta_rad: float
    phi_rad: float
    throttle_norm: float
    elevator_norm: float
    aileron_norm: float
    rudder_norm: float
    motor_throttles_norm: tuple[float, ...]
    udot_mps2: float
    vdot_mps2: float
    wdot_mps2: float
    pdot_rps2: float
    qdot_rps2: float
    rdot_rps2: float

    @property
    def residuals(self) -> dict[str, float]:
        """The six body-axis acceleration residuals by name."""
        return {k: getattr(self, k) for k in ("udot_mps2", "vdot_mps2", "wdot_mps2", "pdot_rps2", "qdot_rps2", "rdot_rps2")}

    @property
    def max_linear_residual_mps2(self) -> float:
        return max(abs(self.udot_mps2), abs(self.vdot_mps2), abs(self.wdot_mps2))

    @property
    def max_angular_residual_rps2(self) -> float:
        return max(abs(self.pdot_rps2), abs(self.qdot_rps2), abs(self.rdot_rps2))

    def to_dict(self) -> dict:
        d = asdict(self)
        d["motor_throttles_norm"] = list(self.motor_throttles_norm)
        return d


def new_exec(aircraft: str, dt_s: float = DEFAULT_DT_S) -> jsbsim.FGFDMExec:
    """A fresh FGFDMExec with `aircraft` loaded (project model or one bundled with jsbsim).

    The step is set BEFORE loading: JSBSim's FCS filters fix their coefficients with the step
    in force when the model is loaded. Raises InputError for an unknown aircraft (the message
    lists the available ones).
    """
    folder = aircraft_dir(aircraft)  # InputError listing the models when unknown
    fdm = jsbsim.FGFDMExec(None)  # root = the jsbsim package: its engines and systems
    fdm.set_debug_level(0)
    fdm.set_dt(float(dt_s))
    fdm.set_aircraft_path(str(folder))
    own_engines = folder / aircraft / "Engines"
    if own_engines.is_dir():
        fdm.set_engine_path(str(own_engines))
    if not fdm.load_model(aircraft):
        raise InputError(f"aircraft {aircraft!r}: JSBSim could not load {folder / aircraft / (aircraft + '.xml')}")
    fdm.set_dt(float(dt_s))
    return fdm


def set_flight_condition(
    fdm: jsbsim.FGFDMExec, airspeed_mps: float, altitude_m: float, flight_path_rad: float = 0.0
) -> None:
    """Initial condition: straight flight north at the equator, true airspeed, altitude above
    mean sea level (terrain at sea level), flight-path angle; then run_ic and start engines."""
    fdm["ic/terrain-elevation-ft"] = 0.0
    fdm["ic/lat-geod-deg"] = 0.0
    fdm["ic/long-gc-deg"] = 0.0
    fdm["ic/h-sl-ft"] = altitude_m * M_TO_FT
    fdm["ic/psi-true-rad"] = 0.0
    fdm["ic/phi-rad"] = 0.0
    fdm["ic/vt-fps"] = airspeed_mps * M_TO_FT
    fdm["ic/gamma-rad"] = flight_path_rad
    if not fdm.run_ic():
        raise InputError("JSBSim rejected the initial condition")
    fdm["propulsion/set-running"] = -1


def trim_exec(
    fdm: jsbsim.FGFDMExec,
    aircraft: str,
    airspeed_mps: float,
    altitude_m: float,
    *,
    flight_path_deg: float = 0.0,
) -> TrimResult:
    """Trim the loaded model `fdm` in place and return the trim. See `trim`."""
    meta = aircraft_meta(aircraft)
    kind = str(meta.get("kind", "fixed_wing"))
    if not math.isfinite(altitude_m) or altitude_m < 0.0:
        raise InputError(f"trim altitude {altitude_m!r} m: expected a finite altitude >= 0 m above sea level")
    gamma = math.radians(flight_path_deg)
    if kind == "multirotor":
        if airspeed_mps != 0.0:
            raise InputError(f"aircraft {aircraft!r} is a multirotor: its trim is hover, give airspeed 0 (got {airspeed_mps} m/s)")
        throttles = _trim_hover(fdm, meta, altitude_m)
    else:
        if not math.isfinite(airspeed_mps) or airspeed_mps <= 0.0:
            raise InputError(f"trim airspeed {airspeed_mps!r} m/s: expected > 0 for fixed-wing {aircraft!r}")
        set_flight_condition(fdm, airspeed_mps, altitude_m, gamma)
        try:
            fdm.do_trim(_TRIM_FULL)
        except jsbsim.TrimFailureError as exc:
            raise InputError(
                f"aircraft {aircraft!r}: JSBSim trim failed at {airspeed_mps:g} m/s, {altitude_m:g} m, "
                f"flight path {flight_path_deg:g} deg ({exc}); is that condition flyable?"
            ) from None
        # Hand the pitch trim over to the elevator command so that the adapter's elevator
        # command alone holds the trim (both are summed in the FCS of tb_fixedwing, c172x...).
        pitch_trim = fdm["fcs/pitch-trim-cmd-norm"]
        if pitch_trim != 0.0:
            fdm["fcs/elevator-cmd-norm"] = fdm["fcs/elevator-cmd-norm"] + pitch_trim
            fdm["fcs/pitch-trim-cmd-norm"] = 0.0  # same sum: the state and surfaces are unchanged
        throttles = (fdm["fcs/throttle-cmd-norm"],)
    return _read_trim(fdm, aircraft, kind, airspeed_mps, altitude_m, gamma, throttles)


def trim(
    aircraft: str,
    airspeed_mps: float,
    altitude_m: float,
    *,
    flight_path_deg: float = 0.0,
    dt_s: float = DEFAULT_DT_S,
) -> TrimResult:
    """Trim `aircraft` in straight flight (fixed wing) or hover (multirotor, airspeed 0).

    airspeed_mps: true airspeed; altitude_m: above mean sea level; flight_path_deg: climb
    angle (> 0 climbing). Raises InputError for an unknown aircraft or a condition JSBSim
    cannot trim.
    """
    return trimmed_exec(aircraft, airspeed_mps, altitude_m, flight_path_deg=flight_path_deg, dt_s=dt_s)[1]


def trimmed_exec(
    aircraft: str,
    airspeed_mps: float,
    altitude_m: float,
    *,
    flight_path_deg: float = 0.0,
    dt_s: float = DEFAULT_DT_S,
) -> tuple[jsbsim.FGFDMExec, TrimResult]:
    """A fresh FGFDMExec of `aircraft` trimmed at the condition, ready to `run()`, and the trim."""
    fdm = new_exec(aircraft, dt_s)
    result = trim_exec(fdm, aircraft, airspeed_mps, altitude_m, flight_path_deg=flight_path_deg)
    log.debug("trimmed %s: %s", aircraft, result)
    return fdm, result


# -- internals ------------------------------------------------------------------------------


def _set_motors(fdm: jsbsim.FGFDMExec, n: int, u: float) -> None:
    for i in range(n):
        fdm[f"fcs/throttle-cmd-norm[{i}]"] = u


def _trim_hover(fdm: jsbsim.FGFDMExec, meta: dict, altitude_m: float) -> tuple[float, ...]:
    """Equal thrust commands that zero wdot at rest: secant iteration on JSBSim's wdot."""
    n = len(meta.get("motors", ())) or 4
    u0 = float(meta.get("hover_throttle_norm", 0.5))

    def wdot(u: float) -> float:
        _set_motors(fdm, n, u)
        set_flight_condition(fdm, 0.0, altitude_m, 0.0)
        return fdm["accelerations/wdot-ft_sec2"] * FT_TO_M

    u_a, u_b = u0, u0 * 1.01
    f_a, f_b = wdot(u_a), wdot(u_b)
    for _ in range(8):
        if abs(f_b) < 1e-9 or f_b == f_a:
            break
        u_a, u_b, f_a = u_b, u_b - f_b * (u_b - u_a) / (f_b - f_a), f_b
        if not 0.0 < u_b < 1.0:
            raise InputError(f"multirotor cannot hover: thrust command {u_b:.3f} needed (0..1)")
        f_b = wdot(u_b)
    f_b = wdot(u_b)  # leave the model at the converged command
    return (u_b,) * n


def _read_trim(
    fdm: jsbsim.FGFDMExec,
    aircraft: str,
    kind: str,
    airspeed_mps: float,
    altitude_m: float,
    gamma_rad: float,
    throttles: tuple[float, ...],
) -> TrimResult:
    g = fdm.get_property_value

    def opt(name: str) -> float:
        try:
            return float(g(name))
        except Exception:  # property absent in this model (e.g. no elevator on a quad)
            return 0.0

    return TrimResult(
        aircraft=aircraft,
        kind=kind,
        airspeed_mps=float(airspeed_mps),
        altitude_m=float(altitude_m),
        flight_path_rad=float(gamma_rad),
        alpha_rad=g("aero/alpha-rad"),
        beta_rad=g("aero/beta-rad"),
        theta_rad=g("attitude/theta-rad"),
        phi_rad=g("attitude/phi-rad"),
        throttle_norm=float(throttles[0]),
        elevator_norm=opt("fcs/elevator-cmd-norm") + opt("fcs/pitch-trim-cmd-norm"),
        aileron_norm=opt("fcs/aileron-cmd-norm") + opt("fcs/roll-trim-cmd-norm"),
        rudder_norm=opt("fcs/rudder-cmd-norm") + opt("fcs/yaw-trim-cmd-norm"),
        motor_throttles_norm=tuple(float(u) for u in throttles),
        udot_mps2=g("accelerations/udot-ft_sec2") * FT_TO_M,
        vdot_mps2=g("accelerations/vdot-ft_sec2") * FT_TO_M,
        wdot_mps2=g("accelerations/wdot-ft_sec2") * FT_TO_M,
        pdot_rps2=g("accelerations/pdot-rad_sec2"),
        qdot_rps2=g("accelerations/qdot-rad_sec2"),
        rdot_rps2=g("accelerations/rdot-rad_sec2"),
    )
