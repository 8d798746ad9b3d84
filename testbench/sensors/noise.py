"""Stochastic error processes of inertial sensors, generated in blocks (shared by the in-loop
IMU and the vectorised static record, so both draw from exactly the same model).

One `TriadNoise` is the additive random error of a sensor triad (3 axes), the sum of:
- white noise of density N (angle/velocity random walk): sample sigma N / sqrt(dt);
- bias instability B: a bank of first-order Gauss-Markov processes with correlation times
  spaced by a decade, each with variance B^2 ln(10) / pi. Their Lorentzian spectra add up to a
  1/f (flicker) spectrum S(f) = B^2 / (2 pi f) between the shortest and longest correlation
  time, whose Allan deviation is the flat floor 0.664 B (IEEE Std 952, Annex C) with +-1.5 %
  ripple. The processes start from their stationary distribution, so a record shows the floor
  from its first sample;
- rate random walk K: a Wiener process with increments K sqrt(dt) (ADEV K sqrt(tau / 3)).

Units are the SI units of the measured quantity q (rad/s or m/s^2): N in q*sqrt(s),
B in q, K in q/sqrt(s). Draw order is fixed: `sample_block(n)` takes one
rng.standard_normal((n, 3 * n_states)) per call, row by row, so n calls of one sample give the
same numbers as one call of n samples.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

# Correlation times of the flicker bank (s): 0.3 s .. 30000 s, a decade apart. The Allan floor
# is flat within 2 % from tau ~ 1 s to ~ 1e4 s, which covers every record we analyse.
FLICKER_CORR_TIMES_S = 0.3 * 10.0 ** np.arange(6)
_FLICKER_VAR_PER_B2 = math.log(10.0) / math.pi


def flicker_sigma(bias_instability: float) -> float:
    """Standard deviation (q) of each Gauss-Markov process of the flicker bank for a bias
    instability B (q): B sqrt(ln 10 / pi), which gives the bank the flicker spectrum and the
    Allan floor of the module docstring."""
    return float(bias_instability) * math.sqrt(_FLICKER_VAR_PER_B2)


class TriadNoise:
    """Additive random error of one 3-axis sensor sampled every dt_s.

    white_density: N (q*sqrt(s)); bias_instability: B (q); rate_random_walk: K (q/sqrt(s)).
    State (shape (n_flicker, 3) Gauss-Markov states and (3,) random walk) is drawn from `rng`
    on the first `sample_block` call (stationary start), then evolves only there.
    """

    def __init__(self, white_density: float, bias_instability: float, rate_random_walk: float, dt_s: float):
        if dt_s <= 0:
            raise ValueError("dt_s must be positive")
        self.dt_s = float(dt_s)
        self.white_sigma = float(white_density) / math.sqrt(self.dt_s)
        self.gm_sigma = flicker_sigma(bias_instability)
        self.gm_a = np.exp(-self.dt_s / FLICKER_CORR_TIMES_S)  # (K,) AR(1) coefficients
        self.gm_drive = self.gm_sigma * np.sqrt(1.0 - self.gm_a**2)  # keeps the variance stationary
        self.rw_step = float(rate_random_walk) * math.sqrt(self.dt_s)
        self._gm: np.ndarray | None = None  # (K, 3)
        self._rw = np.zeros(3)

    @property
    def n_states(self) -> int:
        """Normal draws per axis per sample: white + flicker bank + random walk."""
        return 2 + len(FLICKER_CORR_TIMES_S)

    @property
    def bias_b(self) -> np.ndarray:
        """Current slowly varying bias (flicker bank + random walk), shape (3,)."""
        gm = np.zeros(3) if self._gm is None else self._gm.sum(axis=0)
        return gm + self._rw

    def _init_state(self, rng: np.random.Generator) -> None:
        self._gm = self.gm_sigma * rng.standard_normal((len(FLICKER_CORR_TIMES_S), 3))

    def sample_block(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """The next n samples of the additive error, shape (n, 3); advances the state n steps."""
        if self._gm is None:
            self._init_state(rng)
        k = len(FLICKER_CORR_TIMES_S)
        z = rng.standard_normal((n, 3 * self.n_states)).reshape(n, self.n_states, 3)
        out = self.white_sigma * z[:, 0, :]
        if n == 1:
            # One step of the same recursions as below, without lfilter's call overhead.
            self._gm = self.gm_a[:, None] * self._gm + self.gm_drive[:, None] * z[0, 1 : 1 + k, :]
            self._rw = self._rw + self.rw_step * z[0, 1 + k, :]
            return out + (self._gm.sum(axis=0) + self._rw)[None, :]
        for j in range(k):
            a = self.gm_a[j]
            # x[i] = a x[i-1] + w[i], started from the stored state.
            x = lfilter([1.0], [1.0, -a], self.gm_drive[j] * z[:, 1 + j, :], axis=0, zi=(a * self._gm[j])[None, :])[0]
            out += x
            self._gm[j] = x[-1]
        rw = self._rw + np.cumsum(self.rw_step * z[:, 1 + k, :], axis=0)
        out += rw
        self._rw = rw[-1].copy()
        return out
