"""Orchestration of a Monte Carlo batch in a folder DIR:

DIR/batch.json      what the batch is (scenario, runs, seed, overrides, varied keys)
DIR/runs/run_NNNNN/ each run's own output contract plus result.json when it finished
DIR/runs.parquet    one row per finished run (seed, varied parameters, every scalar metric,
                    status, error text), rewritten as runs finish
DIR/summary.json    statistics with confidence intervals
DIR/nees_position.parquet  the runs' average position NEES per record time (batch.consistency),
                    when the runs have a covariance
DIR/report.html     histograms, CDFs, metric vs varied parameter
"""

from __future__ import annotations

import json
import logging
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import pyarrow as pa
import pyarrow.parquet as pq

from testbench.batch.executor import run_dask, run_local
from testbench.batch.plan import BatchPlan
from testbench.batch.summary import summarize
from testbench.batch.worker import load_result
from testbench.core.errors import InputError

log = logging.getLogger(__name__)


@dataclass
class BatchResult:
    """Rows of every finished run (sorted by run index), the summary and the folder."""

    out_dir: Path
    rows: list[dict[str, Any]]
    summary: dict[str, Any]
    skipped: int


def run_batch(
    plan: BatchPlan,
    out_dir: str | Path,
    *,
    workers: int = 1,
    scheduler: str | None = None,
    on_result: Callable[[dict[str, Any]], None] | None = None,
    report: bool = True,
) -> BatchResult:
    """Run (or resume) the batch into out_dir; returns when every run has a result."""
    out = Path(out_dir)
    runs_dir = out / "runs"
    out.mkdir(parents=True, exist_ok=True)
    _check_identity(out / "batch.json", plan)  # before anything is written: another batch's folder stays as it was
    runs_dir.mkdir(exist_ok=True)
    specs = plan.run_specs()
    rows: dict[int, dict[str, Any]] = {}
    for s in specs:
        done = load_result(runs_dir / s.name)
        if done is not None:
            rows[s.index] = done
    pending = [s for s in specs if s.index not in rows]
    skipped = len(rows)
    if skipped:
        log.info("resuming %s: %d runs already done, %d to go", out, skipped, len(pending))

    def collect(row: dict[str, Any]) -> None:
        rows[int(row["run"])] = row
        write_runs_parquet(out / "runs.parquet", rows)
        if on_result is not None:
            on_result(row)

    scenario = str(Path(plan.scenario).resolve())
    try:
        if pending:
            if scheduler:
                run_dask(pending, scenario, runs_dir, scheduler, collect)
            else:
                run_local(pending, scenario, runs_dir, max(1, int(workers)), collect)
    finally:
        # Even on Ctrl-C: what finished is in runs.parquet and summary.json.
        ordered = [rows[i] for i in sorted(rows)]
        write_runs_parquet(out / "runs.parquet", rows)
        summary = summarize(ordered, plan.runs)
        summary["nees_position"] = _nees_summary(runs_dir, ordered, out / "nees_position.parquet")
        (out / "summary.json").write_text(json.dumps(_json_safe(summary), indent=2, sort_keys=True) + "\n", encoding="utf-8")
    if report:
        from testbench.batch.report import write_batch_report

        write_batch_report(out, ordered, summary, out / "report.html")
    return BatchResult(out, ordered, summary, skipped)


def _nees_summary(runs_dir: Path, rows: list[dict[str, Any]], series_path: Path) -> dict[str, float] | None:
    """Average position NEES over the finished runs (batch.consistency), or None when fewer
    than two finished runs have a covariance; its time series goes to series_path (removed
    when there is none, so that a resumed batch never shows a stale one). Never fails the
    batch: a run folder that cannot be read is left out with a warning."""
    from testbench.batch.consistency import nees_consistency

    dirs = []
    for r in rows:
        d = runs_dir / f"run_{int(r['run']):05d}"
        if r.get("status") in ("passed", "threshold_failed") and (d / "telemetry.parquet").is_file():
            dirs.append(d)
    try:
        res = nees_consistency(dirs)
    except Exception as exc:  # noqa: BLE001 -- a statistic must not lose the batch
        log.warning("NEES consistency not computed: %s", exc)
        res = None
    series_path.unlink(missing_ok=True)
    if res is None:
        return None
    tmp = series_path.with_suffix(".parquet.part")
    res.series.to_parquet(tmp, index=False)
    tmp.replace(series_path)
    return res.as_dict()


def _check_identity(path: Path, plan: BatchPlan) -> None:
    ident = plan.identity()
    if not path.is_file() and (path.parent / "run.json").is_file():
        raise InputError(f"{path.parent}: holds a run of `testbench run` (run.json); use a new --out folder for the batch")
    if path.is_file():
        old = json.loads(path.read_text(encoding="utf-8"))
        if old != ident:
            diff = sorted(k for k in ident if old.get(k) != ident[k])
            raise InputError(f"{path.parent}: holds a different batch (differs in {', '.join(diff)}); use a new --out folder")
        return
    path.write_text(json.dumps(ident, indent=2, sort_keys=True) + "\n", encoding="utf-8")


def write_runs_parquet(path: Path, rows: dict[int, dict[str, Any]]) -> None:
    """One row per finished run; columns are the union of the rows' keys (missing -> null)."""
    ordered = [rows[i] for i in sorted(rows)]
    keys: dict[str, None] = {}
    for r in ordered:
        keys.update(dict.fromkeys(r))
    cols = {}
    for k in keys:
        vals = [r.get(k) for r in ordered]
        if all(isinstance(v, (int, float)) and not isinstance(v, bool) or v is None for v in vals) and k not in ("status", "error"):
            cols[k] = pa.array([None if v is None else float(v) for v in vals], pa.float64()) if k != "run" else pa.array(vals, pa.int64())
        else:
            cols[k] = pa.array([None if v is None else str(v) for v in vals], pa.string())
    tmp = path.with_suffix(".parquet.part")
    pq.write_table(pa.table(cols), tmp)
    tmp.replace(path)


def _json_safe(x: Any) -> Any:
    if isinstance(x, dict):
        return {k: _json_safe(v) for k, v in x.items()}
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x
