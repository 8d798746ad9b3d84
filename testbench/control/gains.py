"""Autopilot gain sets and where they came from.

The fixed-wing numbers are computed by `testbench.control.design` from the linear models of
`testbench.dynamics.linear` (see that module's docstring for the method); the stored defaults
record the aircraft, trim point and date so that `testbench aircraft design NAME --airspeed V
--altitude H` can reproduce them. Multirotor gains are computed at construction from the sidecar geometry
(multirotor.py), so they need no stored table.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class FixedWingGains:
    """Gains of the fixed-wing autopilot (normalised surface/throttle commands, SI states).

    Longitudinal LQI: u = u_trim - K_lon @ [V - V_r, gamma - gamma_r, q - q_r, theta - theta_r,
    h - h_r, int(V - V_r), int(h - h_r)] with u = (elevator, throttle); V m/s, gamma/theta rad,
    q rad/s, h m (up), integrals in m and m s.
    Roll: aileron = aileron_trim + k_phi (phi_c - phi) - k_p p + k_i_phi int(phi_c - phi).
    Yaw damper / turn coordination: rudder = rudder_trim - k_r (r - r_c), r_c = g sin(phi) cos(theta) / V.
    Trim: the design point's airspeed, pitch and surface/throttle settings.
    """

    k_lon: tuple[tuple[float, ...], ...]
    k_phi: float
    k_p: float
    k_i_phi: float
    k_r: float
    trim_airspeed_mps: float
    trim_theta_rad: float
    trim_elevator: float
    trim_throttle: float
    trim_aileron: float = 0.0
    trim_rudder: float = 0.0
    source: str = ""
    design_notes: dict = field(default_factory=dict)

    @property
    def k_lon_array(self) -> np.ndarray:
        return np.asarray(self.k_lon, float)


# Filled by design.py (`testbench aircraft design NAME` prints this block).
DEFAULT_GAINS: dict[str, FixedWingGains] = {}

DEFAULT_GAINS['tb_fixedwing'] = FixedWingGains(
    k_lon=((-0.009154907556415317, -3.6154082075583753, -0.35129030196741445, -0.699056399105557, -0.07442657469076365, 0.010869134397687377, -0.009570740289286875), (0.2531379669792253, 0.9006699424944037, 0.03499999326885331, 0.11623834637088168, 0.03792572513850675, 0.059817126808042735, 0.004830726398972033)),
    k_phi=2.8822874536249388,
    k_p=0.2210328056034887,
    k_i_phi=1.6666666666666654,
    k_r=-0.875,
    trim_airspeed_mps=25.0,
    trim_theta_rad=0.06038654490539061,
    trim_elevator=-0.3517827565041531,
    trim_throttle=0.7834105108426238,
    trim_aileron=0.014685278996972745,
    trim_rudder=-0.0023413951231859853,
    source='design.py 2026-11-22: tb_fixedwing trimmed level at 25 m/s, 800 m',
)



def default_gains(aircraft: str) -> FixedWingGains | None:
    """Stored gains for a model name, or None (the controller then designs them at start-up)."""
    return DEFAULT_GAINS.get(aircraft)
