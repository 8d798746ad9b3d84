"""Batch statistics: per-metric mean with a 95 % confidence interval, spread and quantiles;
run status counts and the threshold pass rate with a Wilson interval."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy import stats

_NOT_METRICS = {"run", "exit_status", "worker_wall_s"}


def metric_columns(rows: list[dict[str, Any]]) -> list[str]:
    """Numeric metric keys present in the rows (varied parameters and bookkeeping excluded)."""
    keys: dict[str, None] = {}
    for r in rows:
        for k, v in r.items():
            if k in _NOT_METRICS or k.startswith("vary.") or k.startswith("seed"):
                continue
            if isinstance(v, (int, float)) and not isinstance(v, bool):
                keys[k] = None
    return sorted(keys)


def describe(values: np.ndarray) -> dict[str, float]:
    """n, mean, its 95 % t-interval, std, min, median, p95, max of the finite values."""
    x = values[np.isfinite(values)]
    n = int(x.size)
    if n == 0:
        return {"n": 0}
    mean = float(np.mean(x))
    std = float(np.std(x, ddof=1)) if n > 1 else 0.0
    half = float(stats.t.ppf(0.975, n - 1) * std / math.sqrt(n)) if n > 1 else math.nan
    return {
        "n": n, "mean": mean, "ci95_low": mean - half, "ci95_high": mean + half, "std": std,
        "min": float(np.min(x)), "median": float(np.median(x)), "p95": float(np.percentile(x, 95)), "max": float(np.max(x)),
    }


def wilson_interval(successes: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """95 % Wilson score interval of a proportion."""
    if n == 0:
        return (math.nan, math.nan)
    p = successes / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return (c - h, c + h)


def summarize(rows: list[dict[str, Any]], planned_runs: int) -> dict[str, Any]:
    """The batch's summary.json content."""
    status = [str(r.get("status")) for r in rows]
    counts = {s: status.count(s) for s in sorted(set(status))}
    finished = [r for r in rows if r.get("status") in ("passed", "threshold_failed")]
    passed = sum(1 for r in finished if r.get("status") == "passed")
    lo, hi = wilson_interval(passed, len(finished))
    return {
        "runs_planned": planned_runs,
        "runs_done": len(rows),
        "status_counts": counts,
        "threshold_pass_rate": {"value": passed / len(finished) if finished else math.nan, "ci95_low": lo, "ci95_high": hi, "n": len(finished)},
        "metrics": {k: describe(np.array([float(r.get(k, math.nan)) for r in finished or rows], float)) for k in metric_columns(rows)},
    }
