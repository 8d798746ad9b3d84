"""UWB ranging channel physics (paper eq. 20-24, DESIGN.md), vectorised over measurements.

Line of sight:      r = d + n,          n ~ N(0, sigma^2)            (sigma = 0.10 m)
Non-line of sight:  r = d + n + W,      W ~ Exp(mean c tau_rms)
                    tau_rms = T1 d_km^eps xi,  ln xi ~ N(0, sigma_ln_xi^2)
(Greenstein et al. 1997 delay-spread model: T1 is the median rms delay spread at d = 1 km,
so d enters in km; eps in [0.5, 1].)
Signal strength:    rss = P_tx - [PL0 + 10 n_p log10(d / d0) + S (+ L_nlos)],  S ~ N(0, sigma_S^2)

Draw order per measurement (fixed, whether LOS or not): three standard normals (range noise,
ln xi, shadowing), one standard exponential, one uniform (random-NLOS coin).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

C_MPS = 299_792_458.0


@dataclass(frozen=True)
class ChannelSpec:
    """sigma_m: LOS range noise; t1_s: median delay spread at 1 km (s); eps: distance exponent;
    sigma_ln_xi: std of ln xi; tx_power_dbm, pl0_db at d0_m, n_p, shadowing_db, nlos_loss_db:
    the path-loss model; nlos_probability: chance that an unblocked link is NLOS anyway."""

    sigma_m: float = 0.10
    t1_s: float = 19e-9
    eps: float = 0.5
    sigma_ln_xi: float = 0.5
    tx_power_dbm: float = -14.3
    pl0_db: float = 40.0
    d0_m: float = 1.0
    n_p: float = 2.0
    shadowing_db: float = 2.0
    nlos_loss_db: float = 10.0
    nlos_probability: float = 0.0


def nlos_mean_excess_m(d_m, spec: ChannelSpec, xi=1.0):
    """Mean NLOS excess range c tau_rms (m) at distance d_m for the delay-spread factor xi."""
    return C_MPS * spec.t1_s * (np.asarray(d_m, float) / 1000.0) ** spec.eps * xi


def draw(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The random numbers of n measurements: normals (n, 3), exponentials (n,), uniforms (n,)."""
    return rng.standard_normal((n, 3)), rng.standard_exponential(n), rng.random(n)


def measure_ranges(d_m, blocked, spec: ChannelSpec, rng: np.random.Generator):
    """Ranges and RSS of n links of true length d_m (n,), geometrically blocked (n,) bool.

    Returns (range_m (n,), rss_dbm (n,), nlos (n,) bool).
    """
    d = np.atleast_1d(np.asarray(d_m, float))
    z, e, u = draw(len(d), rng)
    nlos = np.atleast_1d(blocked) | (u < spec.nlos_probability)
    xi = np.exp(spec.sigma_ln_xi * z[:, 1])
    excess = np.where(nlos, nlos_mean_excess_m(d, spec, xi) * e, 0.0)
    rng_m = d + spec.sigma_m * z[:, 0] + excess
    loss = spec.pl0_db + 10.0 * spec.n_p * np.log10(np.maximum(d, 1e-3) / spec.d0_m) + spec.shadowing_db * z[:, 2]
    rss = spec.tx_power_dbm - loss - np.where(nlos, spec.nlos_loss_db, 0.0)
    return rng_m, rss, nlos


def nlos_error_cdf(x_m, d_m: float, spec: ChannelSpec, nodes: int = 40):
    """CDF of the NLOS range error r - d at distance d_m: Gaussian noise plus an exponential
    whose mean is log-normally spread by xi (Gauss-Hermite average of exponnorm CDFs)."""
    gh_x, gh_w = np.polynomial.hermite_e.hermegauss(nodes)  # weight exp(-x^2 / 2)
    gh_w = gh_w / gh_w.sum()
    x = np.asarray(x_m, float)
    out = np.zeros_like(x)
    for xk, wk in zip(gh_x, gh_w):
        mean = nlos_mean_excess_m(d_m, spec, np.exp(spec.sigma_ln_xi * xk))
        if spec.sigma_m > 0:
            out += wk * stats.exponnorm.cdf(x, mean / spec.sigma_m, loc=0.0, scale=spec.sigma_m)
        else:
            out += wk * stats.expon.cdf(x, scale=mean)
    return out
