"""Linear models about a JSBSim trim, split into longitudinal and lateral-directional parts,
and the classical modes (short period, phugoid, roll subsidence, spiral, Dutch roll).

The Jacobians come from JSBSim's own linearisation (FGLinearization: central differences of
the model's state derivatives about the trim), converted to SI. Inputs are the normalised
commands the adapter writes (fcs/*-cmd-norm), so a gain designed on these models applies
directly to the commands.

Full model states (SI, in this order):   airspeed_mps, alpha_rad, theta_rad, q_rps,
    beta_rad, phi_rad, p_rps, psi_rad, r_rps, altitude_m  (+ propeller speeds prop<i>_rpm
    for models with JSBSim propellers); inputs throttle_norm, aileron_norm, elevator_norm,
    rudder_norm.
Longitudinal: states (airspeed_mps, alpha_rad, q_rps, theta_rad), inputs (elevator_norm,
    throttle_norm). Lateral: states (beta_rad, p_rps, r_rps, phi_rad), inputs (aileron_norm,
    rudder_norm). Both are python-control StateSpace objects with named signals and C = I.

Example::

    from testbench.dynamics.linear import linearize
    lm = linearize("tb_fixedwing", 25.0, 1000.0)
    lm.longitudinal            # control.StateSpace
    lm.mode("short_period").natural_frequency_rps
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import control
import jsbsim
import numpy as np

from testbench.core.errors import InputError
from testbench.dynamics.trim import DEFAULT_DT_S, FT_TO_M, TrimResult, trimmed_exec

# JSBSim FGStateSpace names -> (SI name, factor to SI)
_STATE_MAP = {
    "Vt": ("airspeed_mps", FT_TO_M),
    "Alpha": ("alpha_rad", 1.0),
    "Theta": ("theta_rad", 1.0),
    "Q": ("q_rps", 1.0),
    "Beta": ("beta_rad", 1.0),
    "Phi": ("phi_rad", 1.0),
    "P": ("p_rps", 1.0),
    "Psi": ("psi_rad", 1.0),
    "R": ("r_rps", 1.0),
    "Alt": ("altitude_m", FT_TO_M),
}
_INPUT_MAP = {"ThtlCmd": "throttle_norm", "DaCmd": "aileron_norm", "DeCmd": "elevator_norm", "DrCmd": "rudder_norm"}
_DROP = {"Latitude", "Longitude"}  # position on the Earth: not part of the flight dynamics

LON_STATES = ("airspeed_mps", "alpha_rad", "q_rps", "theta_rad")
LON_INPUTS = ("elevator_norm", "throttle_norm")
LAT_STATES = ("beta_rad", "p_rps", "r_rps", "phi_rad")
LAT_INPUTS = ("aileron_norm", "rudder_norm")


@dataclass(frozen=True)
class Mode:
    """One eigen-mode of a linear model.

    eigenvalue (rad/s) = eigenvalue_real + i eigenvalue_imag (the upper of a complex pair).
    Oscillatory: natural_frequency_rps = |lambda|, damping_ratio = -Re/|lambda|,
    period_s = 2 pi / Im, time_constant_s = 1 / (zeta omega_n) (envelope).
    Real (aperiodic): natural_frequency_rps = |lambda|, damping_ratio = 1 (or -1 when
    unstable), period_s = None, time_constant_s = -1 / lambda (negative when unstable: then
    time_to_double_s = ln 2 / lambda). An overdamped short period (two real roots) is
    reported as one mode with omega_n = sqrt(l1 l2), zeta = -(l1 + l2) / (2 omega_n).
    """

    name: str
    axis: str
    eigenvalue_real: float
    eigenvalue_imag: float
    natural_frequency_rps: float
    damping_ratio: float
    time_constant_s: float
    period_s: float | None
    stable: bool

    @property
    def eigenvalue(self) -> complex:
        return complex(self.eigenvalue_real, self.eigenvalue_imag)

    @property
    def time_to_double_s(self) -> float | None:
        """For an unstable mode, the time for the amplitude to double; else None."""
        return math.log(2.0) / self.eigenvalue_real if self.eigenvalue_real > 0.0 else None

    def to_dict(self) -> dict:
        d = asdict(self)
        d["time_to_double_s"] = self.time_to_double_s
        return d


@dataclass(frozen=True, eq=False)
class LinearModel:
    """Linearisation of one aircraft about one trim (see the module docstring for signals).

    a (n, n), b (n, m): the full SI model with names state_names / input_names;
    longitudinal, lateral: python-control StateSpace parts; modes: the identified modes.
    """

    trim: TrimResult
    a: np.ndarray
    b: np.ndarray
    state_names: tuple[str, ...]
    input_names: tuple[str, ...]
    longitudinal: control.StateSpace
    lateral: control.StateSpace
    modes: tuple[Mode, ...]

    def mode(self, name: str) -> Mode:
        """The mode called `name` (short_period, phugoid, roll, spiral, dutch_roll)."""
        for m in self.modes:
            if m.name == name:
                return m
        raise KeyError(f"no mode {name!r}; modes: {[m.name for m in self.modes]}")

    @property
    def full(self) -> control.StateSpace:
        """The full model as a StateSpace (C = I)."""
        n, m = self.b.shape
        return control.ss(self.a, self.b, np.eye(n), np.zeros((n, m)),
                          states=list(self.state_names), inputs=list(self.input_names),
                          outputs=list(self.state_names), name="full")

    def to_dict(self) -> dict:
        def part(sys: control.StateSpace) -> dict:
            return {
                "states": list(sys.state_labels),
                "inputs": list(sys.input_labels),
                "A": np.asarray(sys.A).tolist(),
                "B": np.asarray(sys.B).tolist(),
            }

        return {
            "trim": self.trim.to_dict(),
            "longitudinal": part(self.longitudinal),
            "lateral": part(self.lateral),
            "full": {"states": list(self.state_names), "inputs": list(self.input_names),
                     "A": self.a.tolist(), "B": self.b.tolist()},
            "modes": [m.to_dict() for m in self.modes],
        }


def linearize(
    aircraft: str,
    airspeed_mps: float,
    altitude_m: float,
    *,
    flight_path_deg: float = 0.0,
    dt_s: float = DEFAULT_DT_S,
) -> LinearModel:
    """Trim `aircraft` (fixed wing) at the condition with JSBSim's trim and linearise it there.

    Raises InputError for an unknown aircraft, a multirotor (JSBSim's linearisation needs
    an engine-driven model; hover dynamics are not modal in this sense) or an untrimmable
    condition.
    """
    fdm, trim_result = trimmed_exec(aircraft, airspeed_mps, altitude_m, flight_path_deg=flight_path_deg, dt_s=dt_s)
    if trim_result.kind != "fixed_wing":
        raise InputError(f"aircraft {aircraft!r} is a {trim_result.kind}: linear modes are computed for fixed-wing aircraft")
    return linearize_exec(fdm, trim_result)


def linearize_exec(fdm: jsbsim.FGFDMExec, trim_result: TrimResult) -> LinearModel:
    """Linearise a model already trimmed in `fdm` (e.g. by trim.trimmed_exec)."""
    dt_s = fdm.get_delta_t()
    lin = jsbsim.FGLinearization(fdm)
    # FGLinearization leaves the integration suspended (dt = 0): resume it so that `fdm`
    # can be flown on from the trim, e.g. to compare the linear and nonlinear responses.
    if fdm.integration_suspended():
        fdm.resume_integration()
    if fdm.get_delta_t() != dt_s:
        fdm.set_dt(dt_s)
    a_raw, b_raw, _c, _d = (np.asarray(m, dtype=float) for m in lin.state_space)
    names_raw = list(lin.x_names)
    keep = [i for i, n in enumerate(names_raw) if n not in _DROP]
    names, scale = [], []
    for i in keep:
        raw = names_raw[i]
        if raw in _STATE_MAP:
            si, k = _STATE_MAP[raw]
        elif raw.startswith("Rpm"):
            si, k = f"prop{raw[3:]}_rpm", 1.0
        else:
            si, k = raw.lower(), 1.0
        names.append(si)
        scale.append(k)
    t = np.diag(scale)
    t_inv = np.diag(1.0 / np.asarray(scale))
    # x_si = T x_raw:  A_si = T A T^-1, B_si = T B
    a = t @ a_raw[np.ix_(keep, keep)] @ t_inv
    b = t @ b_raw[keep, :]
    inputs = tuple(_INPUT_MAP.get(u, u) for u in lin.u_names)
    lon = _subsystem(a, b, names, inputs, LON_STATES, LON_INPUTS, "longitudinal")
    lat = _subsystem(a, b, names, inputs, LAT_STATES, LAT_INPUTS, "lateral")
    modes = identify_modes(lon, lat)
    return LinearModel(trim_result, a, b, tuple(names), inputs, lon, lat, modes)


def identify_modes(longitudinal: control.StateSpace, lateral: control.StateSpace) -> tuple[Mode, ...]:
    """Name the eigenvalues of the two 4-state parts.

    Longitudinal: of two complex pairs the faster is the short period, the slower the
    phugoid; with real roots the two fastest form an (overdamped) short period and the two
    slowest the phugoid. Lateral: the complex pair is the Dutch roll, the fastest real root
    the roll subsidence, the slowest the spiral.
    """
    modes: list[Mode] = []
    lon_eig = np.linalg.eigvals(np.asarray(longitudinal.A))
    pairs, reals = _split(lon_eig)
    pairs.sort(key=abs)
    reals.sort(key=abs)
    if len(pairs) == 2:
        modes += [_oscillatory("short_period", "longitudinal", pairs[1]), _oscillatory("phugoid", "longitudinal", pairs[0])]
    elif len(pairs) == 1:
        # one pair plus two real roots: the pair is whichever of the two it is closer to
        slow, fast = reals[0], reals[-1]
        if abs(pairs[0]) > math.sqrt(abs(slow * fast)):
            modes += [_oscillatory("short_period", "longitudinal", pairs[0]), _real_pair("phugoid", "longitudinal", slow, fast)]
        else:
            modes += [_real_pair("short_period", "longitudinal", reals[-2], reals[-1]), _oscillatory("phugoid", "longitudinal", pairs[0])]
    else:
        modes += [_real_pair("short_period", "longitudinal", reals[2], reals[3]), _real_pair("phugoid", "longitudinal", reals[0], reals[1])]

    lat_eig = np.linalg.eigvals(np.asarray(lateral.A))
    pairs, reals = _split(lat_eig)
    reals.sort(key=abs)
    if len(pairs) == 1 and len(reals) == 2:
        modes += [_real("roll", "lateral", reals[1]), _real("spiral", "lateral", reals[0]),
                  _oscillatory("dutch_roll", "lateral", pairs[0])]
    else:  # Dutch roll split into real roots (very unusual): name by speed
        reals_all = sorted([*reals, *(p for p in pairs), *(p.conjugate() for p in pairs)], key=abs)
        modes += [_real("roll", "lateral", reals_all[-1]), _real("spiral", "lateral", reals_all[0])]
        if len(reals_all) >= 4:
            modes.append(_real_pair("dutch_roll", "lateral", reals_all[1], reals_all[2]))
    return tuple(modes)


# -- internals ------------------------------------------------------------------------------


def _subsystem(a, b, names, inputs, states, ins, label) -> control.StateSpace:
    missing = [s for s in states if s not in names]
    if missing:
        raise InputError(f"JSBSim's linearisation of this model lacks the states {missing}")
    ix = [names.index(s) for s in states]
    iu = [inputs.index(u) for u in ins]
    n, m = len(ix), len(iu)
    return control.ss(a[np.ix_(ix, ix)], b[np.ix_(ix, iu)], np.eye(n), np.zeros((n, m)),
                      states=list(states), inputs=list(ins), outputs=list(states), name=label)


def _split(eig: np.ndarray) -> tuple[list[complex], list[float]]:
    """Upper members of complex pairs, and the real roots."""
    pairs = [complex(e) for e in eig if e.imag > 1e-9 * max(1.0, abs(e))]
    reals = [float(e.real) for e in eig if abs(e.imag) <= 1e-9 * max(1.0, abs(e))]
    return pairs, reals


def _oscillatory(name: str, axis: str, lam: complex) -> Mode:
    wn = abs(lam)
    zeta = -lam.real / wn
    tau = -1.0 / lam.real if lam.real != 0.0 else math.inf
    return Mode(name, axis, lam.real, abs(lam.imag), wn, zeta, tau, 2.0 * math.pi / abs(lam.imag), lam.real < 0.0)


def _real(name: str, axis: str, lam: float) -> Mode:
    tau = -1.0 / lam if lam != 0.0 else math.inf
    return Mode(name, axis, lam, 0.0, abs(lam), 1.0 if lam < 0 else -1.0, tau, None, lam < 0.0)


def _real_pair(name: str, axis: str, l1: float, l2: float) -> Mode:
    wn = math.sqrt(abs(l1 * l2))
    zeta = -(l1 + l2) / (2.0 * wn) if wn > 0 else 1.0
    slow = min((l1, l2), key=abs)
    tau = -1.0 / slow if slow != 0.0 else math.inf
    return Mode(name, axis, slow, 0.0, wn, zeta, tau, None, l1 < 0.0 and l2 < 0.0)
