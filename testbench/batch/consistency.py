"""Filter consistency over a batch: the average NEES across runs at each record time.

For N independent runs of a consistent filter with a d-dimensional error, N times the average
NEES at one instant is chi-square with N d degrees of freedom (Bar-Shalom, Li & Kirubarajan,
"Estimation with Applications to Tracking and Navigation", 2001, sec. 5.4.2). The batch check
is the fraction of record times at which the average lies inside the two-sided 95 % bounds;
a consistent filter keeps it near 95 %, an over-confident one falls above the upper bound.

Only vehicles with a covariance (an EKF, not the truth pass-through) and only runs that
finished contribute; rows are matched across runs by (vehicle id, record time).

How far that fraction may fall below 95 % by chance depends on how long the errors stay
correlated: a navigation error that lasts tens of seconds gives a short batch only a dozen
independent looks at the bounds. `chance_shares` answers "would a consistent filter with
these errors' time correlation do as badly?": it takes the errors whitened by each run's own
covariance (unit variance per component if the filter is consistent), measures their
autocorrelation over the batch, and simulates batches of consistent filters with that
autocorrelation (stationary Gaussian errors of unit variance), giving the distribution of the
fraction a consistent filter would show and the chance of one as low as the batch's.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from testbench.navigation.ins.consistency import average_nees_bounds
from testbench.scoring.metrics_nav import position_errors_whitened

POSITION_DOF = 3
CHANCE_BATCHES = 1000
"""Simulated consistent batches behind the chance figures."""
CHANCE_MAX_INSTANTS = 300
"""The simulation runs on at most this many instants per vehicle (evenly strided): the share
over a strided grid has the same distribution as over the full one when the stride is short
against the errors' correlation time, and the cost grows with its square."""


@dataclass(frozen=True)
class NeesConsistency:
    """Average position NEES over runs, per record time (all vehicles pooled as instants).

    runs: runs that contributed; dof: error dimension (3, NED position); bounds: (low, high)
    95 % bounds of the N-run average; samples: instants with every run present;
    fraction_within: share of those instants inside the bounds; fraction_above: above the
    upper bound (over-confidence); mean_of_average: the time mean of the average NEES.
    chance_share_mean, chance_share_p05: mean and 5th percentile of fraction_within over
    CHANCE_BATCHES simulated batches of a consistent filter whose errors have this batch's
    autocorrelation (see the module docstring); chance_p_value: the share of those batches
    whose fraction is at most this batch's (small: worse than chance allows). NaN when the
    record times are not evenly spaced.
    series: per instant (rows: vehicle_id, t_s) the average NEES (`average_nees`, 3 dof) and
    the average squared whitened error per axis (`average_z2_north`, `_east`, `_down`, 1 dof
    each: above 1 the filter claims less than that axis errs); not part of as_dict.
    """

    runs: int
    dof: int
    bounds: tuple[float, float]
    samples: int
    fraction_within: float
    fraction_above: float
    mean_of_average: float
    chance_share_mean: float = float("nan")
    chance_share_p05: float = float("nan")
    chance_p_value: float = float("nan")
    series: pd.DataFrame | None = field(default=None, repr=False, compare=False)

    def as_dict(self) -> dict[str, float]:
        return {
            "runs": self.runs, "dof": self.dof, "bound_low": self.bounds[0], "bound_high": self.bounds[1],
            "samples": self.samples, "fraction_within": self.fraction_within,
            "fraction_above": self.fraction_above, "mean_of_average": self.mean_of_average,
            "chance_share_mean": self.chance_share_mean, "chance_share_p05": self.chance_share_p05,
            "chance_p_value": self.chance_p_value,
        }


def whitened_error_table(run_dirs: list[Path]) -> pd.DataFrame:
    """Whitened position errors of each run (scoring.metrics_nav.position_errors_whitened):
    a frame indexed by (vehicle_id, t_s) with columns (run index, component 0..2); NaN where a
    run has no usable covariance at that instant."""
    columns = {}
    for k, d in enumerate(run_dirs):
        tel = pd.read_parquet(d / "telemetry.parquet")
        z = position_errors_whitened(tel)
        index = pd.MultiIndex.from_arrays([tel["vehicle_id"].astype(str), tel["t_s"].round(6)])
        keep = ~index.duplicated()
        for c in range(POSITION_DOF):
            columns[(k, c)] = pd.Series(z[keep, c], index=index[keep])
    return pd.DataFrame(columns)


def nees_consistency(run_dirs: list[Path], probability: float = 0.95) -> NeesConsistency | None:
    """Average position NEES over the given finished runs; None with fewer than 2 runs or no
    instant where every run has a covariance."""
    if len(run_dirs) < 2:
        return None
    table = whitened_error_table(run_dirs).dropna(how="any")
    if table.empty:
        return None
    n = len(run_dirs)
    lo, hi = average_nees_bounds(POSITION_DOF, n, probability)
    z = table.to_numpy().reshape(len(table), n, POSITION_DOF)     # (instants, runs, component)
    z2 = (z**2).mean(axis=1)                                        # (instants, component)
    avg = z2.sum(axis=1)
    within = float(np.mean((avg >= lo) & (avg <= hi)))
    chance = chance_shares(table, n, (lo, hi))
    return NeesConsistency(
        runs=n, dof=POSITION_DOF, bounds=(lo, hi), samples=int(avg.size),
        fraction_within=within,
        fraction_above=float(np.mean(avg > hi)),
        mean_of_average=float(np.mean(avg)),
        chance_share_mean=float(np.mean(chance)) if chance is not None else float("nan"),
        chance_share_p05=float(np.percentile(chance, 5)) if chance is not None else float("nan"),
        chance_p_value=float(np.mean(chance <= within)) if chance is not None else float("nan"),
        series=pd.DataFrame({
            "vehicle_id": table.index.get_level_values(0).astype(str), "t_s": table.index.get_level_values(1),
            "average_nees": avg, "average_z2_north": z2[:, 0], "average_z2_east": z2[:, 1], "average_z2_down": z2[:, 2],
        }),
    )


def chance_shares(table: pd.DataFrame, runs: int, bounds: tuple[float, float], batches: int = CHANCE_BATCHES,
                  max_instants: int = CHANCE_MAX_INSTANTS, seed: int = 0) -> np.ndarray | None:
    """fraction_within of `batches` simulated batches of `runs` consistent filters (shape
    (batches,)), each vehicle's errors given the autocorrelation its whitened errors show in
    `table` (whitened_error_table without NaN), per component; None when some vehicle's record
    times are not evenly spaced. Seeded: the same table gives the same figures.

    The autocorrelation of each run's deviation from the runs' mean is pooled over runs and
    time (a stationary approximation) and made a valid correlation matrix by clipping negative
    eigenvalues and rescaling to unit variance."""
    rng = np.random.default_rng(seed)
    lo, hi = bounds
    nees_avg = []                                       # per vehicle: (batches, instants)
    for _, block in table.groupby(level=0, sort=True):
        t = block.index.get_level_values(1).to_numpy(float)
        if t.size >= 3:
            dt = np.diff(t)
            if np.max(np.abs(dt - dt[0])) > 1e-6 * max(abs(dt[0]), 1e-9):
                return None
        stride = max(1, -(-t.size // max_instants))
        z = block.to_numpy().reshape(t.size, runs, POSITION_DOF)[::stride]   # (m, runs, 3)
        m = z.shape[0]
        acc = np.zeros((batches, m))
        for c in range(POSITION_DOF):
            # Deviations from the runs' mean at each instant: an error common to every run
            # (a bias of the method) is an inconsistency to be found, not a correlation to be
            # allowed for; n / (n - 1) keeps the covariance estimate unbiased.
            x = z[:, :, c] - z[:, :, c].mean(axis=1, keepdims=True)
            acf = np.array([np.mean(x[: m - lag] * x[lag:]) for lag in range(m)]) * runs / (runs - 1)
            if not acf[0] > 0:
                return None
            corr = acf / acf[0]
            C = corr[np.abs(np.subtract.outer(np.arange(m), np.arange(m)))]
            w, V = np.linalg.eigh(C)
            L = V * np.sqrt(np.clip(w, 0.0, None))
            L /= np.sqrt((L**2).sum(axis=1))[:, None]   # unit variance at every instant
            for b0 in range(0, batches, 50):
                nb = min(50, batches - b0)
                sim = L @ rng.standard_normal((m, nb * runs))                # (m, nb * runs)
                acc[b0:b0 + nb] += (sim**2).reshape(m, nb, runs).mean(axis=2).T
        nees_avg.append(acc)
    if not nees_avg:
        return None
    avg = np.concatenate(nees_avg, axis=1)
    return np.mean((avg >= lo) & (avg <= hi), axis=1)
