"""Summary statistics of error samples and of normalised (chi-square) errors.

Each statistic is a frozen dataclass with `to_dict()` giving the nested dict of metrics.json.
Non-finite samples are dropped before summarising, so every figure is NaN-free; a summary
of no samples is None (and the metric is then absent, which a threshold reports as missing).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats as sps


@dataclass(frozen=True)
class ErrorStats:
    """Summary of non-negative error magnitudes (m, m/s, ms, %...: the unit of the samples).

    mean, rms, p95 (95th percentile, linear interpolation), max, n (sample count);
    cep50 / cep95 (empirical circular error probable: the radius holding 50 % / 95 % of
    horizontal errors) are set only for horizontal errors.
    """

    mean: float
    rms: float
    p95: float
    max: float
    n: int
    cep50: float | None = None
    cep95: float | None = None

    def to_dict(self) -> dict[str, float]:
        out = {"mean": self.mean, "rms": self.rms, "p95": self.p95, "max": self.max, "n": self.n}
        if self.cep50 is not None:
            out["cep50"] = self.cep50
            out["cep95"] = self.cep95
        return out


def error_stats(values, *, cep: bool = False) -> ErrorStats | None:
    """ErrorStats of |values| (any shape, flattened); None when no finite sample is left.

    values: error samples; signed errors are summarised by magnitude (rms is of the signed
    values, which is the same). cep: also give cep50/cep95 (for horizontal errors).
    """
    v = np.abs(np.asarray(values, dtype=float).ravel())
    v = v[np.isfinite(v)]
    if v.size == 0:
        return None
    extra = {}
    if cep:
        extra = {"cep50": float(np.percentile(v, 50.0)), "cep95": float(np.percentile(v, 95.0))}
    return ErrorStats(
        mean=float(np.mean(v)),
        rms=float(np.sqrt(np.mean(v * v))),
        p95=float(np.percentile(v, 95.0)),
        max=float(np.max(v)),
        n=int(v.size),
        **extra,
    )


def chi2_bounds(dof, prob: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    """Two-sided `prob` interval of a chi-square variable with `dof` degrees of freedom."""
    dof = np.asarray(dof, dtype=float)
    a = 0.5 * (1.0 - prob)
    return sps.chi2.ppf(a, dof), sps.chi2.ppf(1.0 - a, dof)


@dataclass(frozen=True)
class ChiSquareStats:
    """Consistency of normalised squared errors (NEES e^T P^-1 e, or NIS nu^T S^-1 nu).

    mean: mean of the samples (a consistent filter gives about dof);
    mean_per_dof: mean of sample/dof (about 1 when consistent, whatever the dimension);
    frac_in_95: fraction of samples inside their own two-sided 95 % chi-square interval
    (about 0.95 when consistent); frac_above_95: fraction above the upper bound
    (overconfidence); dof: the (mean) dimension; n: sample count.
    """

    mean: float
    mean_per_dof: float
    frac_in_95: float
    frac_above_95: float
    dof: float
    n: int

    def to_dict(self) -> dict[str, float]:
        return {
            "mean": self.mean,
            "mean_per_dof": self.mean_per_dof,
            "frac_in_95": self.frac_in_95,
            "frac_above_95": self.frac_above_95,
            "dof": self.dof,
            "n": self.n,
        }


def chi_square_stats(samples, dof) -> ChiSquareStats | None:
    """ChiSquareStats of `samples` (shape (n,)) with per-sample `dof` (scalar or (n,)).

    Samples that are not finite or whose dof < 1 are dropped; None when nothing is left.
    """
    x = np.asarray(samples, dtype=float).ravel()
    d = np.broadcast_to(np.asarray(dof, dtype=float), x.shape).astype(float)
    ok = np.isfinite(x) & np.isfinite(d) & (d >= 1)
    x, d = x[ok], d[ok]
    if x.size == 0:
        return None
    lo, hi = chi2_bounds(d, 0.95)
    return ChiSquareStats(
        mean=float(np.mean(x)),
        mean_per_dof=float(np.mean(x / d)),
        frac_in_95=float(np.mean((x >= lo) & (x <= hi))),
        frac_above_95=float(np.mean(x > hi)),
        dof=float(np.mean(d)),
        n=int(x.size),
    )


def rate(successes, trials) -> float | None:
    """successes / trials as a float, None when there were no trials."""
    return float(successes) / float(trials) if trials else None
