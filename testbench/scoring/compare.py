"""Compare two runs, or two Monte Carlo batches, metric by metric: which figures got better,
which got worse, and for batches whether the change stands out of the run-to-run scatter.

The question a change to an estimator raises is "is it better, or is that noise?". A single
run is deterministic under its seed, so two runs of the same scenario and seed differ only by
the code: any change beyond a relative tolerance is reported. Two batches are compared on their
per-run values: when both flew the same runs (same run numbers, seeds and varied parameters,
i.e. the same `testbench montecarlo` command on two versions of the code) the per-run
differences are tested with the Wilcoxon signed-rank test, otherwise the two samples with the
Mann-Whitney U test; both are rank tests, which the heavy tails of navigation errors do not
fool the way they fool a t-test. A change is "better" or "worse" only when p < alpha and the
means differ by more than a relative tolerance.

Direction comes from the metric's name: errors, latencies and wall times are better lower;
rates, recall, precision and real-time factors better higher, except what a spoofer got out of
the filter (the share of its fixes fused, how long it held it), which is better lower, as are a
scene matcher's longest gap between fixes, its fixes taken from overcast frames, its false fixes
(made, and taken) and a cold start's time to its first fix; anything
else (counts, NEES, bank angles, times of events) is only "changed". Timing figures (wall time, real-time factor,
latency, microseconds) depend on the machine and its load: they are reported but never make a
comparison fail unless asked (the project measures speed as ratios within one process, see
`testbench bench`).
"""

from __future__ import annotations

import fnmatch
import math
from dataclasses import asdict, dataclass
from typing import Mapping, Sequence

import numpy as np
import pandas as pd
from scipy import stats

# Direction by the words of a dotted key; the first rule that matches wins. A run's consistency
# figures (NEES, NIS, within-n-sigma shares) have a right value, not a better side; so do
# ambiguity shares (the geometry's, not the estimator's) and sample counts. A batch's share of
# time its average NEES stays inside the 95 % band (batch.nees_position.fraction_within) is
# better higher: too cautious a filter falls below the band as surely as a confident one above.
DIRECTION_RULES: tuple[tuple[str, int], ...] = (
    (".nees.", 0), (".nis.", 0), ("sigma", 0), ("ambiguous", 0),
    # A cold start's error before its first fix is the prior's draw, not the estimator's doing.
    ("error_before", 0),
    (".spoofed.gnss_accept_rate", -1), ("gnss_captured_s", -1), ("longest_gap_s", -1), ("overcast_accepted", -1),
    # Fixes more than 20 m from truth, made or taken, and a cold start's wait for its first fix.
    ("false_fixes", -1), ("first_fix_s", -1),
    ("error", -1), ("latency", -1), ("miss", -1), ("overshoot", -1), ("wall_time", -1), ("_us", -1),
    ("fix_rate", +1), ("correct_rate", +1), ("accept_rate", +1), ("pass_rate", +1), ("fraction_within", +1),
    ("finished_rate", +1),
    ("recall", +1), ("precision", +1), ("real_time_factor", +1),
)
NEUTRAL_LEAVES = {"n", "count", "dof"}
TIMING = ("wall_time", "real_time_factor", "latency", "_us")
NOT_METRICS = ("run", "exit_status", "worker_wall_s", "sim_time_s")


def direction(key: str) -> int:
    """-1: lower is better, +1: higher is better, 0: neither (DIRECTION_RULES on the key)."""
    if key.split(".")[-1] in NEUTRAL_LEAVES:
        return 0
    words = key.lower()
    for word, d in DIRECTION_RULES:
        if word in words:
            return d
    return 0


def is_timing(key: str) -> bool:
    """A figure of the machine's speed rather than of the navigation."""
    return any(w in key.lower() for w in TIMING)


@dataclass(frozen=True)
class MetricChange:
    """One metric compared. base / new: the value (runs) or the mean over runs (batches);
    delta = new - base; rel = delta / |base| (nan when base is 0); p: the test's p-value
    (batches; nan for runs); n: runs compared (1 for runs); verdict: "better", "worse",
    "changed" (a figure without a better side), "same", "missing" (in base only: a renamed or broken
    metric) or "new" (in new only)."""

    key: str
    base: float
    new: float
    delta: float
    rel: float
    p: float
    n: int
    verdict: str
    timing: bool

    def to_dict(self) -> dict:
        """Plain dict, nan as None (strict JSON)."""
        return {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in asdict(self).items()}


# How a run ended (metrics.json `status`: "completed" or "aborted"), best first. An aborted run
# (crash, NaN, divergence) did not fly to its end, and its figures cover only the time before
# the abort: they may even look better than the base's.
STATUS_RANK = {"completed": 0, "aborted": 1}


@dataclass(frozen=True)
class StatusChange:
    """How two runs ended: base / new status ("completed", "aborted"; None when a metrics.json
    gives none) and the verdict: "better" / "worse" by STATUS_RANK, "same", or "changed" (a
    status outside it)."""

    base: str | None
    new: str | None
    verdict: str

    def to_dict(self) -> dict:
        return {"key": "status", **asdict(self)}


def compare_status(base: str | None, new: str | None) -> StatusChange:
    """The verdict on two runs' statuses (StatusChange)."""
    if base == new:
        return StatusChange(base, new, "same")
    if base in STATUS_RANK and new in STATUS_RANK:
        return StatusChange(base, new, "worse" if STATUS_RANK[new] > STATUS_RANK[base] else "better")
    return StatusChange(base, new, "changed")


def _verdict(key: str, delta: float, counts: bool) -> str:
    """better / worse / changed for a change that counts, else same."""
    if not counts or delta == 0.0:
        return "same"
    d = direction(key)
    if d == 0:
        return "changed"
    return "better" if d * delta > 0 else "worse"


def _rel(base: float, delta: float) -> float:
    return delta / abs(base) if base != 0 and math.isfinite(base) else math.nan


def _select(keys, only: Sequence[str], ignore: Sequence[str]) -> list[str]:
    out = []
    for k in keys:
        if k in NOT_METRICS or k.startswith(("vary.", "seed")):
            continue
        if only and not any(fnmatch.fnmatchcase(k, pat) for pat in only):
            continue
        if any(fnmatch.fnmatchcase(k, pat) for pat in ignore):
            continue
        out.append(k)
    return sorted(out)


def _numeric(v) -> float | None:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    return float(v)


def compare_runs(base: Mapping[str, object], new: Mapping[str, object], rel_tol: float = 0.02,
                 only: Sequence[str] = (), ignore: Sequence[str] = ()) -> list[MetricChange]:
    """Two runs' flattened metrics ({"nav.horizontal_error_m.mean": 0.55, ...}), or any two
    sets of single numbers (a batch's own figures). A change counts when |new - base| >
    rel_tol |base| (or, at base 0, when new differs at all)."""
    out = []
    for k in _select(set(base) | set(new), only, ignore):
        b, x = _numeric(base.get(k)), _numeric(new.get(k))
        if k in base and k not in new:
            if b is not None:
                out.append(MetricChange(k, b, math.nan, math.nan, math.nan, math.nan, 1, "missing", is_timing(k)))
            continue
        if k in new and k not in base:
            if x is not None:
                out.append(MetricChange(k, math.nan, x, math.nan, math.nan, math.nan, 1, "new", is_timing(k)))
            continue
        if b is None or x is None:
            continue
        if not (math.isfinite(b) and math.isfinite(x)):
            # A figure that stops being a number broke (worse, where it has a direction); one that
            # becomes a number, or a neutral one either way, only changed.
            same = (math.isnan(b) and math.isnan(x)) or b == x
            verdict = "same" if same else ("worse" if math.isfinite(b) and direction(k) != 0 else "changed")
            out.append(MetricChange(k, b, x, math.nan, math.nan, math.nan, 1, verdict, is_timing(k)))
            continue
        delta = x - b
        counts = abs(delta) > rel_tol * abs(b) if b != 0 else delta != 0
        out.append(MetricChange(k, b, x, delta, _rel(b, delta), math.nan, 1, _verdict(k, delta, counts), is_timing(k)))
    return out


def _identity_columns(runs: pd.DataFrame) -> list[str]:
    """The columns that say which run a row is: its number, seed and varied values."""
    return [c for c in runs.columns if c == "run" or c.startswith(("seed", "vary."))]


def _numeric_columns(runs: pd.DataFrame) -> set[str]:
    return {c for c in runs.columns if pd.api.types.is_numeric_dtype(runs[c])}


def runs_are_paired(base: pd.DataFrame, new: pd.DataFrame) -> bool:
    """True when both batches flew the same runs: same run numbers, seeds and varied values."""
    ident = _identity_columns(base)
    if "run" not in ident or set(ident) != set(_identity_columns(new)):
        return False
    a = base[ident].sort_values("run").reset_index(drop=True)
    b = new[ident].sort_values("run").reset_index(drop=True)
    return a.shape == b.shape and a.astype(str).equals(b.astype(str))


def compare_batches(base: pd.DataFrame, new: pd.DataFrame, alpha: float = 0.05, rel_tol: float = 0.02,
                    only: Sequence[str] = (), ignore: Sequence[str] = ()) -> tuple[list[MetricChange], bool]:
    """Two batches' runs.parquet tables (finished runs are used). Returns the changes and
    whether the runs were paired. base / new of a change are the means over runs; a change
    counts when p < alpha (it stands out of the scatter) and the means differ by more than
    rel_tol of the base mean (it matters: with 100 paired runs a 0.1 % change can be
    significant)."""
    finished = ("passed", "threshold_failed")
    if "status" in base:
        base = base[base["status"].isin(finished)]
    if "status" in new:
        new = new[new["status"].isin(finished)]
    paired = runs_are_paired(base, new)
    if paired:
        base, new = base.sort_values("run").reset_index(drop=True), new.sort_values("run").reset_index(drop=True)
    out = []
    for k in _select(_numeric_columns(base) | _numeric_columns(new), only, ignore):
        if k not in new:
            out.append(MetricChange(k, float(base[k].mean()), math.nan, math.nan, math.nan, math.nan, 0, "missing", is_timing(k)))
            continue
        if k not in base:
            out.append(MetricChange(k, math.nan, float(new[k].mean()), math.nan, math.nan, math.nan, 0, "new", is_timing(k)))
            continue
        b, x = base[k].to_numpy(float), new[k].to_numpy(float)
        if paired:
            ok = np.isfinite(b) & np.isfinite(x)
            b, x = b[ok], x[ok]
        else:
            b, x = b[np.isfinite(b)], x[np.isfinite(x)]
        if b.size == 0 or x.size == 0:
            continue
        if paired:
            n, p = b.size, _wilcoxon_p(x - b)
        else:
            n = min(b.size, x.size)
            p = float(stats.mannwhitneyu(x, b, alternative="two-sided").pvalue) if np.ptp(np.r_[b, x]) > 0 else 1.0
        mb, mx = float(np.mean(b)), float(np.mean(x))
        delta = mx - mb
        matters = abs(delta) > rel_tol * abs(mb) if mb != 0 else delta != 0
        out.append(MetricChange(k, mb, mx, delta, _rel(mb, delta), p, n, _verdict(k, delta, p < alpha and matters), is_timing(k)))
    return out, paired


def _wilcoxon_p(d: np.ndarray) -> float:
    """Two-sided Wilcoxon signed-rank p-value of paired differences (1.0 when all are zero)."""
    if not np.any(d != 0):
        return 1.0
    return float(stats.wilcoxon(d, zero_method="wilcox", alternative="two-sided").pvalue)


def failed(changes: Sequence[MetricChange], timing_counts: bool = False) -> list[MetricChange]:
    """The changes that fail a comparison: worse, or a figure with a better side missing from the
    new one (a renamed or broken metric; a neutral one such as nav.lost_at_s is absent when
    nothing happened); timing figures, which measure the machine as much as the code, only when
    timing_counts."""
    return [c for c in changes
            if (c.verdict == "worse" or (c.verdict == "missing" and direction(c.key) != 0)) and (timing_counts or not c.timing)]


ORDER = {"worse": 0, "missing": 1, "better": 2, "changed": 3, "new": 4, "same": 5}


def sort_changes(changes: Sequence[MetricChange]) -> list[MetricChange]:
    """Worse first, then missing, better, changed, new, same; by key within each."""
    return sorted(changes, key=lambda c: (ORDER[c.verdict], c.key))
