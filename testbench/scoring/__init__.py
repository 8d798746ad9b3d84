"""Scoring: pure functions from a run record to the metrics of DESIGN.md's output contract.

    from testbench.scoring import score_run, check_thresholds, write_metrics_json
    result = score_run(run_dir)                      # MetricsResult (typed tree)
    thr = check_thresholds(result.flatten(), thresholds)  # ThresholdResult
    write_metrics_json(run_dir, result, thr)          # DIR/metrics.json

User metrics: `@register_metric("name")` on a function RunRecord -> dict of floats.
"""

from testbench.scoring.record_io import RunRecord, load_run
from testbench.scoring.registry import register_metric, registered_metrics, unregister_metric
from testbench.scoring.result import (
    ControlMetrics,
    FormationMetrics,
    IsmnMetrics,
    IsmnPhase,
    MetricsResult,
    NavMetrics,
    NavSubset,
    NisStats,
    RelnavMetrics,
    RelnavPair,
    VehicleMetrics,
    flatten,
    unflatten,
)
from testbench.scoring.score import score_and_write, score_record, score_run, write_metrics_json
from testbench.scoring.stats import ChiSquareStats, ErrorStats, chi_square_stats, error_stats
from testbench.scoring.thresholds import ThresholdResult, check_thresholds, validate_thresholds
from testbench.scoring.tum import write_run_tums, write_tum

__all__ = [
    "ChiSquareStats", "ControlMetrics", "ErrorStats", "FormationMetrics", "IsmnMetrics", "IsmnPhase",
    "MetricsResult", "NavMetrics", "NavSubset", "NisStats", "RelnavMetrics", "RelnavPair", "RunRecord",
    "ThresholdResult", "VehicleMetrics", "check_thresholds", "chi_square_stats", "error_stats", "flatten",
    "load_run", "register_metric", "registered_metrics", "score_and_write", "score_record", "score_run",
    "unflatten", "unregister_metric", "validate_thresholds", "write_metrics_json", "write_run_tums", "write_tum",
]
