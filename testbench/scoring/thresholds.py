"""Thresholds as regression gates: a scenario's `thresholds:` checked against the metrics.

    thresholds:
      ismn.smooth.horizontal_error_m.mean: {max: 1.5}
      ismn.fix_rate: {min: 0.8}

A key the run did not produce is a FAILURE naming the key (a renamed or broken metric must not
pass silently); so is a value that is not a finite number.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping

from testbench.core.errors import InputError

BOUND_KINDS = ("min", "max")


@dataclass(frozen=True)
class ThresholdResult:
    """passed: keys whose every bound held; failed: one entry per violated bound or missing key,
    {"key", "value", "bound", "kind" ("min" | "max" | "missing" | "not_a_number"), "reason"}."""

    passed: list[str] = field(default_factory=list)
    failed: list[dict[str, Any]] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.failed

    def to_dict(self) -> dict[str, Any]:
        return {"passed": list(self.passed), "failed": [dict(f) for f in self.failed]}


def validate_thresholds(thresholds: Mapping[str, Any], where: str = "thresholds") -> dict[str, dict[str, float]]:
    """Check the shape {"dotted.key": {"min": x, "max": y}}; returns it with float bounds.

    Raises InputError naming the key for anything else (unknown bound name, non-number, empty).
    """
    if thresholds is None:
        return {}
    if not isinstance(thresholds, Mapping):
        raise InputError(f"{where}: expected a mapping of metric key -> {{min: x, max: y}}")
    out: dict[str, dict[str, float]] = {}
    for key, spec in thresholds.items():
        if not isinstance(spec, Mapping) or not spec:
            raise InputError(f"{where}.{key}: expected {{min: x}} and/or {{max: y}}, got {spec!r}")
        bounds = {}
        for kind, value in spec.items():
            if kind not in BOUND_KINDS:
                raise InputError(f"{where}.{key}.{kind}: unknown bound; expected min or max")
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise InputError(f"{where}.{key}.{kind}: expected a finite number, got {value!r}")
            bounds[kind] = float(value)
        if "min" in bounds and "max" in bounds and bounds["min"] > bounds["max"]:
            raise InputError(f"{where}.{key}: min {bounds['min']} > max {bounds['max']}")
        out[str(key)] = bounds
    return out


def check_thresholds(metrics_flat: Mapping[str, Any], thresholds: Mapping[str, Any]) -> ThresholdResult:
    """Check every threshold against the flat (dotted-key) metrics.

    metrics_flat: e.g. MetricsResult.flatten(); thresholds: {"dotted.key": {"min"/"max": bound}}.
    Bounds are inclusive (value == max passes).
    """
    spec = validate_thresholds(thresholds)
    passed: list[str] = []
    failed: list[dict[str, Any]] = []
    for key, bounds in spec.items():
        if key not in metrics_flat or metrics_flat[key] is None:
            failed.append({"key": key, "value": None, "bound": None, "kind": "missing",
                           "reason": f"metric {key} is missing from this run's metrics"})
            continue
        raw = metrics_flat[key]
        try:
            value = float(raw)
        except (TypeError, ValueError):
            value = math.nan
        if isinstance(raw, bool) or not math.isfinite(value):
            failed.append({"key": key, "value": raw if isinstance(raw, (int, float, str)) else repr(raw),
                           "bound": None, "kind": "not_a_number",
                           "reason": f"metric {key} = {raw!r} is not a finite number"})
            continue
        bad = False
        if "min" in bounds and value < bounds["min"]:
            failed.append({"key": key, "value": value, "bound": bounds["min"], "kind": "min",
                           "reason": f"{key} = {value:.6g} < min {bounds['min']:.6g}"})
            bad = True
        if "max" in bounds and value > bounds["max"]:
            failed.append({"key": key, "value": value, "bound": bounds["max"], "kind": "max",
                           "reason": f"{key} = {value:.6g} > max {bounds['max']:.6g}"})
            bad = True
        if not bad:
            passed.append(key)
    return ThresholdResult(passed=passed, failed=failed)
