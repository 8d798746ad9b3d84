"""Filter consistency over a batch: the average NEES across runs at each record time.

For N independent runs of a consistent filter with a d-dimensional error, N times the average
NEES at one instant is chi-square with N d degrees of freedom (Bar-Shalom, Li & Kirubarajan,
"Estimation with Applications to Tracking and Navigation", 2001, sec. 5.4.2). The batch check
is the fraction of record times at which the average lies inside the two-sided 95 % bounds;
a consistent filter keeps it near 95 %, an over-confident one falls above the upper bound.

Only vehicles with a covariance (an EKF, not the truth pass-through) and only runs that
finished contribute; rows are matched across runs by (vehicle id, record time).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from testbench.navigation.ins.consistency import average_nees_bounds
from testbench.scoring.metrics_nav import position_nees

POSITION_DOF = 3


@dataclass(frozen=True)
class NeesConsistency:
    """Average position NEES over runs, per record time (all vehicles pooled as instants).

    runs: runs that contributed; dof: error dimension (3, NED position); bounds: (low, high)
    95 % bounds of the N-run average; samples: instants with every run present;
    fraction_within: share of those instants inside the bounds; fraction_above: above the
    upper bound (over-confidence); mean_of_average: the time mean of the average NEES.
    """

    runs: int
    dof: int
    bounds: tuple[float, float]
    samples: int
    fraction_within: float
    fraction_above: float
    mean_of_average: float

    def as_dict(self) -> dict[str, float]:
        return {
            "runs": self.runs, "dof": self.dof, "bound_low": self.bounds[0], "bound_high": self.bounds[1],
            "samples": self.samples, "fraction_within": self.fraction_within,
            "fraction_above": self.fraction_above, "mean_of_average": self.mean_of_average,
        }


def position_nees_table(run_dirs: list[Path]) -> pd.DataFrame:
    """Position NEES of each run: a frame indexed by (vehicle_id, t_s), one column per run
    (NaN where a run has no usable covariance at that instant)."""
    columns = {}
    for k, d in enumerate(run_dirs):
        tel = pd.read_parquet(d / "telemetry.parquet")
        nees = position_nees(tel)
        s = pd.Series(nees, index=pd.MultiIndex.from_arrays([tel["vehicle_id"].astype(str), tel["t_s"].round(6)]))
        columns[k] = s[~s.index.duplicated()]
    return pd.DataFrame(columns)


def nees_consistency(run_dirs: list[Path], probability: float = 0.95) -> NeesConsistency | None:
    """Average position NEES over the given finished runs; None with fewer than 2 runs or no
    instant where every run has a covariance."""
    if len(run_dirs) < 2:
        return None
    table = position_nees_table(run_dirs).dropna(how="any")
    if table.empty:
        return None
    n = table.shape[1]
    lo, hi = average_nees_bounds(POSITION_DOF, n, probability)
    avg = table.to_numpy().mean(axis=1)
    return NeesConsistency(
        runs=n, dof=POSITION_DOF, bounds=(lo, hi), samples=int(avg.size),
        fraction_within=float(np.mean((avg >= lo) & (avg <= hi))),
        fraction_above=float(np.mean(avg > hi)),
        mean_of_average=float(np.mean(avg)),
    )
