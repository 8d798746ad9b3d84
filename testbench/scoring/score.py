"""Scoring entry points: run record -> MetricsResult -> metrics.json.

The lead's `testbench run` calls, after the recorder has closed its files:

    result = score_run(run_dir)
    thr = check_thresholds(result.flatten(), record_thresholds)      # or let write_metrics_json do it
    write_metrics_json(run_dir, result, thr)
"""

from __future__ import annotations

import json
import logging
import os
from pathlib import Path
from typing import Iterable, Mapping

from testbench.scoring.metrics_control import compute_control
from testbench.scoring.metrics_events import compute_formation, compute_ismn, compute_relnav
from testbench.scoring.metrics_nav import compute_nav
from testbench.scoring.metrics_tan import compute_tan
from testbench.scoring.record_io import RunRecord, load_run
from testbench.scoring.registry import MetricFn, registered_metrics, resolve_metrics, run_metric
from testbench.scoring.result import MetricsResult, VehicleMetrics, json_safe
from testbench.scoring.thresholds import ThresholdResult, check_thresholds

log = logging.getLogger(__name__)


def _float_or_none(value) -> float | None:
    try:
        return None if value is None else float(value)
    except (TypeError, ValueError):
        return None


def score_vehicle(record: RunRecord) -> VehicleMetrics:
    """Every built-in section for a record holding one vehicle (see RunRecord.subset)."""
    return VehicleMetrics(
        control=compute_control(record),
        nav=compute_nav(record),
        ismn=compute_ismn(record),
        tan=compute_tan(record),
        relnav=compute_relnav(record),
        formation=compute_formation(record),
    )


def score_record(record: RunRecord, metrics: Iterable[str | MetricFn] | None = None) -> MetricsResult:
    """Score a loaded record: top-level sections over all vehicles, `vehicles` per vehicle.

    metrics: user metrics to run (names, "package.module:function" or callables); None runs
    every registered metric plus those named in run.json "metrics".
    """
    info = record.run_info
    if metrics is None:
        specs: list = list(registered_metrics().values()) + list(info.get("metrics") or [])
    else:
        specs = list(metrics)
    custom = {name: run_metric(name, fn, record) for name, fn in resolve_metrics(specs).items()}

    overall = score_vehicle(record)
    vehicles = {vid: score_vehicle(record.subset(vid)) for vid in record.vehicle_ids}
    return MetricsResult(
        real_time_factor=_float_or_none(info.get("real_time_factor")),
        sim_time_s=_float_or_none(info.get("sim_time_s")),
        wall_time_s=_float_or_none(info.get("wall_time_s")),
        status=info.get("status"),
        control=overall.control,
        nav=overall.nav,
        ismn=overall.ismn,
        tan=overall.tan,
        relnav=overall.relnav,
        formation=overall.formation,
        vehicles=vehicles,
        custom=custom,
    )


def score_run(run_dir: str | Path, metrics: Iterable[str | MetricFn] | None = None) -> MetricsResult:
    """Load the run in `run_dir` and score it (see score_record)."""
    return score_record(load_run(run_dir), metrics=metrics)


def write_metrics_json(
    run_dir: str | Path,
    result: MetricsResult,
    thresholds: ThresholdResult | Mapping | None = None,
) -> Path:
    """Write DIR/metrics.json: result.to_dict() plus "thresholds": {"passed", "failed"}.

    thresholds: a ThresholdResult; or a threshold spec {"key": {"min"/"max": x}} to check
    here; or None to check the thresholds listed in DIR/run.json (none -> empty lists).
    NaN/inf become null (strict JSON). Written atomically (temp file + rename).
    Returns the path written.
    """
    run_dir = Path(run_dir)
    if thresholds is None:
        info_path = run_dir / "run.json"
        spec = json.loads(info_path.read_text()).get("thresholds") if info_path.is_file() else None
        thresholds = check_thresholds(result.flatten(), spec or {})
    elif not isinstance(thresholds, ThresholdResult):
        thresholds = check_thresholds(result.flatten(), thresholds)
    doc = result.to_dict()
    doc["thresholds"] = thresholds.to_dict()
    path = run_dir / "metrics.json"
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(json_safe(doc), indent=2, allow_nan=False) + "\n")
    os.replace(tmp, path)
    log.info("wrote %s (%d thresholds passed, %d failed)", path, len(thresholds.passed), len(thresholds.failed))
    return path


def score_and_write(run_dir: str | Path) -> tuple[MetricsResult, ThresholdResult]:
    """Score DIR, check run.json thresholds, write metrics.json; returns both results."""
    record = load_run(run_dir)
    result = score_record(record)
    thr = check_thresholds(result.flatten(), record.thresholds)
    write_metrics_json(run_dir, result, thr)
    return result, thr
