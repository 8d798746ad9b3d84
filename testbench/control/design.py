"""Fixed-wing gain design from the linear models (reproducible: `testbench aircraft design NAME`).

Method
1. Trim the aircraft in level flight at the design airspeed and altitude and linearise it
   with testbench.dynamics.linear (JSBSim trim + FGLinearization in SI: airspeed, alpha,
   theta, q, beta, phi, p, psi, r, altitude; inputs throttle, aileron, elevator, rudder in
   normalised command units, so gains apply directly to SurfaceCommand).
2. Longitudinal, LQR with integral action (LQI). The longitudinal model in (V, alpha, q,
   theta, h) is changed to the measurable states z = (V, gamma, q, theta, h), gamma = theta -
   alpha, by the similarity z = T^-1 x; it is augmented with the integrals of the V and h
   errors and `control.lqr` solves the Riccati equation with Bryson's-rule weights (the
   largest acceptable excursion of each state and input, LON_MAX_* below). The gain
   K_lon (2 x 7) multiplies (z - z_ref, integrals).
3. Roll, LQR on the roll-subsidence model p' = L_p p + L_da da, phi' = p, augmented with
   int(phi - phi_c): gives k_phi, k_p, k_i_phi (Bryson weights ROLL_MAX_*).
4. Yaw damper: k_r chosen by a root-locus scan on the FULL lateral model (beta, phi, p, r)
   with the roll loop closed and rudder = -k_r (r - g phi / V): the k_r that maximises the
   smallest damping ratio of the lateral closed loop (Dutch roll first of all).
5. The full closed loops (longitudinal 7 states; lateral with roll and yaw loops) are
   reported: eigenvalues, damping, bandwidth, so that the step-response tests can check the
   non-linear aircraft against the designed bandwidth.

The numbers stored in gains.DEFAULT_GAINS were produced by this module; their `source` names
the aircraft, trim point and date.
"""

from __future__ import annotations

import datetime
from dataclasses import asdict, dataclass

import control
import numpy as np

from testbench.control.gains import FixedWingGains
from testbench.core.units import STANDARD_GRAVITY_MPS2

# Bryson's rule: 1 / max^2 on the diagonal.
LON_MAX_STATE = {"V": 1.0, "gamma": 0.05, "q": 0.3, "theta": 0.15, "h": 3.0, "iV": 4.0, "ih": 15.0}
LON_MAX_INPUT = {"elevator": 0.15, "throttle": 0.25}
ROLL_MAX_STATE = {"iphi": 0.3, "phi": 0.2, "p": 1.5}
ROLL_MAX_INPUT = 0.5
YAW_DAMPER_SCAN = np.linspace(0.0, 1.0, 201)


@dataclass(frozen=True)
class LinearFixedWing:
    """SI linear model at a trim point: A (12, 12), B (12, 4) with names, and the trim."""

    A: np.ndarray
    B: np.ndarray
    x_names: tuple[str, ...]
    u_names: tuple[str, ...]
    airspeed_mps: float
    altitude_m: float
    trim: dict


@dataclass(frozen=True)
class DesignResult:
    gains: FixedWingGains
    lon_closed_loop_poles: np.ndarray
    lat_closed_loop_poles: np.ndarray
    roll_bandwidth_rps: float
    report: dict


def linearize(aircraft: str, airspeed_mps: float, altitude_m: float) -> LinearFixedWing:
    """Trim and linearise with testbench.dynamics.linear (JSBSim trim + FGLinearization, SI)."""
    from testbench.dynamics.linear import linearize as dyn_linearize

    lm = dyn_linearize(aircraft, airspeed_mps, altitude_m)
    t = lm.trim
    trim = {
        "throttle": t.throttle_norm, "elevator": t.elevator_norm, "aileron": t.aileron_norm,
        "rudder": t.rudder_norm, "theta_rad": t.theta_rad, "alpha_rad": t.alpha_rad,
    }
    return LinearFixedWing(np.asarray(lm.a), np.asarray(lm.b), tuple(lm.state_names), tuple(lm.input_names),
                           airspeed_mps, altitude_m, trim)


def _sub(lm: LinearFixedWing, xs: list[str], us: list[str]) -> tuple[np.ndarray, np.ndarray]:
    ix = [lm.x_names.index(n) for n in xs]
    iu = [lm.u_names.index(n) for n in us]
    return lm.A[np.ix_(ix, ix)], lm.B[np.ix_(ix, iu)]


def longitudinal_lqi(lm: LinearFixedWing) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """K (2, 7) for z = (V, gamma, q, theta, h, iV, ih), inputs (elevator, throttle).

    Returns (K, A_aug, B_aug, closed-loop poles).
    """
    A, B = _sub(lm, ["airspeed_mps", "alpha_rad", "q_rps", "theta_rad", "altitude_m"], ["elevator_norm", "throttle_norm"])
    # x = (V, alpha, q, theta, h) = T z with z = (V, gamma, q, theta, h): alpha = theta - gamma.
    T = np.eye(5)
    T[1, :] = [0.0, -1.0, 0.0, 1.0, 0.0]
    Ti = np.linalg.inv(T)
    Az, Bz = Ti @ A @ T, Ti @ B
    A_aug = np.zeros((7, 7))
    A_aug[:5, :5] = Az
    A_aug[5, 0] = 1.0  # d/dt int(V - V_r) = V - V_r
    A_aug[6, 4] = 1.0  # d/dt int(h - h_r) = h - h_r
    B_aug = np.vstack([Bz, np.zeros((2, 2))])
    Q = np.diag([1.0 / LON_MAX_STATE[k] ** 2 for k in ("V", "gamma", "q", "theta", "h", "iV", "ih")])
    R = np.diag([1.0 / LON_MAX_INPUT[k] ** 2 for k in ("elevator", "throttle")])
    K, _, poles = control.lqr(A_aug, B_aug, Q, R)
    return np.asarray(K), A_aug, B_aug, np.asarray(poles)


def roll_lqi(lm: LinearFixedWing) -> tuple[float, float, float, np.ndarray]:
    """(k_phi, k_p, k_i_phi, poles) from the roll-subsidence model with integral action."""
    L_p = lm.A[lm.x_names.index("p_rps"), lm.x_names.index("p_rps")]
    L_da = lm.B[lm.x_names.index("p_rps"), lm.u_names.index("aileron_norm")]
    # States (int(phi - phi_c), phi, p); aileron u = -K s with s the deviation from the command.
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, L_p]])
    B = np.array([[0.0], [0.0], [L_da]])
    Q = np.diag([1.0 / ROLL_MAX_STATE[k] ** 2 for k in ("iphi", "phi", "p")])
    R = np.array([[1.0 / ROLL_MAX_INPUT**2]])
    K, _, poles = control.lqr(A, B, Q, R)
    k_i, k_phi, k_p = (float(v) for v in np.asarray(K).ravel())
    # aileron = -k_i int(phi - phi_c) - k_phi (phi - phi_c) - k_p p
    #         = k_phi (phi_c - phi) - k_p p + k_i int(phi_c - phi)
    return k_phi, k_p, k_i, np.asarray(poles)


def roll_bandwidth_rps(lm: LinearFixedWing, k_phi: float, k_p: float, k_i: float) -> float:
    """-3 dB bandwidth (rad/s) of phi / phi_c for the roll-subsidence model with the roll loop."""
    L_p = lm.A[lm.x_names.index("p_rps"), lm.x_names.index("p_rps")]
    L_da = lm.B[lm.x_names.index("p_rps"), lm.u_names.index("aileron_norm")]
    # s = (int(phi - phi_c), phi, p); aileron = k_phi (phi_c - phi) - k_p p - k_i int(phi - phi_c)
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [-L_da * k_i, -L_da * k_phi, L_p - L_da * k_p]])
    B = np.array([[-1.0], [0.0], [L_da * k_phi]])
    C = np.array([[0.0, 1.0, 0.0]])
    return float(control.bandwidth(control.ss(A, B, C, 0.0)))


def lateral_closed_loop(lm: LinearFixedWing, k_phi: float, k_p: float, k_i: float, k_r: float) -> np.ndarray:
    """Closed-loop A of (beta, phi, p, r, int phi) with the roll loop (phi_c = 0) and the yaw damper."""
    A, B = _sub(lm, ["beta_rad", "phi_rad", "p_rps", "r_rps"], ["aileron_norm", "rudder_norm"])
    g_over_v = STANDARD_GRAVITY_MPS2 / lm.airspeed_mps
    # u = -F s, s = (beta, phi, p, r, iphi)
    F = np.array([
        [0.0, k_phi, k_p, 0.0, k_i],
        [0.0, -k_r * g_over_v, 0.0, k_r, 0.0],
    ])
    A5 = np.zeros((5, 5))
    A5[:4, :4] = A
    A5[4, 1] = 1.0
    B5 = np.vstack([B, np.zeros((1, 2))])
    return A5 - B5 @ F


def _min_damping(poles: np.ndarray) -> float:
    z = [(-p.real / abs(p)) for p in poles if abs(p) > 1e-6]
    return min(z) if z else 1.0


def design_fixed_wing(aircraft: str = "tb_fixedwing", airspeed_mps: float = 25.0, altitude_m: float = 800.0,
                      date: str | None = None) -> DesignResult:
    """Run the whole design at one trim point; returns the gains and the closed-loop figures."""
    lm = linearize(aircraft, airspeed_mps, altitude_m)
    K, _, _, lon_poles = longitudinal_lqi(lm)
    k_phi, k_p, k_i, roll_poles = roll_lqi(lm)
    # Yaw damper: root-locus scan of k_r (sign from the rudder's yaw effectiveness).
    n_dr = lm.B[lm.x_names.index("r_rps"), lm.u_names.index("rudder_norm")]
    best_kr, best_z = 0.0, -1.0
    for mag in YAW_DAMPER_SCAN:
        k_r = mag * np.sign(n_dr)  # rudder = -k_r r must oppose r: N_dr * (-k_r) r < 0
        z = _min_damping(np.linalg.eigvals(lateral_closed_loop(lm, k_phi, k_p, k_i, k_r)))
        if z > best_z + 1e-9:
            best_kr, best_z = float(k_r), z
    lat_poles = np.linalg.eigvals(lateral_closed_loop(lm, k_phi, k_p, k_i, best_kr))
    roll_bw = roll_bandwidth_rps(lm, k_phi, k_p, k_i)
    date = date or datetime.date.today().isoformat()
    source = f"design.py {date}: {aircraft} trimmed level at {airspeed_mps:g} m/s, {altitude_m:g} m"
    gains = FixedWingGains(
        k_lon=tuple(tuple(float(v) for v in row) for row in K),
        k_phi=k_phi, k_p=k_p, k_i_phi=k_i, k_r=best_kr,
        trim_airspeed_mps=airspeed_mps, trim_theta_rad=float(lm.trim["theta_rad"]),
        trim_elevator=float(lm.trim["elevator"]), trim_throttle=float(lm.trim["throttle"]),
        trim_aileron=float(lm.trim["aileron"]), trim_rudder=float(lm.trim["rudder"]),
        source=source,
    )
    report = {
        "source": source,
        "lon_poles": [[p.real, p.imag] for p in lon_poles],
        "roll_poles": [[p.real, p.imag] for p in roll_poles],
        "lat_poles": [[p.real, p.imag] for p in lat_poles],
        "lat_min_damping": _min_damping(lat_poles),
        "lon_min_damping": _min_damping(lon_poles),
        "trim": lm.trim,
    }
    return DesignResult(gains, lon_poles, lat_poles, roll_bw, report)


def gains_literal(g: FixedWingGains, name: str) -> str:
    """Python source for one DEFAULT_GAINS entry (paste into gains.py)."""
    d = asdict(g)
    d.pop("design_notes")
    body = ",\n    ".join(f"{k}={v!r}" for k, v in d.items())
    return f'DEFAULT_GAINS[{name!r}] = FixedWingGains(\n    {body},\n)\n'
