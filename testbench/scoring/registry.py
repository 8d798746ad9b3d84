"""User metrics: pure functions RunRecord -> dict of floats, registered by name.

    from testbench.scoring import register_metric

    @register_metric("climb")
    def climb(record):
        tel = record.telemetry
        return {"max_rate_mps": float((-tel["truth_vd_mps"]).max())}

Every registered metric runs in `score_run`; its dict lands in metrics.json under the
metric's name ("climb.max_rate_mps"), so thresholds can gate it. A scenario (run.json
"metrics") may also name metrics as "package.module:function"; they are imported on demand.
"""

from __future__ import annotations

from typing import Any, Callable, Iterable, Mapping

from testbench.core.errors import InputError
from testbench.core.registry import register, resolve_class

MetricFn = Callable[[Any], Mapping[str, Any]]

#: Top-level keys of metrics.json that belong to the built-in scoring.
RESERVED_NAMES = frozenset(
    {"control", "nav", "ismn", "tan", "relnav", "formation", "vehicles", "thresholds",
     "real_time_factor", "sim_time_s", "wall_time_s", "status"}
)

_METRICS: dict[str, MetricFn] = {}


def register_metric(name: str) -> Callable[[MetricFn], MetricFn]:
    """Decorator: register `fn(record) -> dict of floats` as metric `name` (no dots)."""
    if "." in name or name in RESERVED_NAMES:
        raise ValueError(f"metric name {name!r} has a dot or is reserved ({', '.join(sorted(RESERVED_NAMES))})")

    def deco(fn: MetricFn) -> MetricFn:
        register("metric", name)(fn)  # also resolvable through the core registry
        _METRICS[name] = fn
        fn.metric_name = name
        return fn

    return deco


def unregister_metric(name: str) -> None:
    """Remove a registered metric (tests; a long-lived process changing its mind)."""
    _METRICS.pop(name, None)


def registered_metrics() -> dict[str, MetricFn]:
    """Name -> function of every registered metric."""
    return dict(_METRICS)


def resolve_metrics(specs: Iterable[str | MetricFn]) -> dict[str, MetricFn]:
    """Name -> function for registered names, "package.module:function" strings or callables."""
    out: dict[str, MetricFn] = {}
    for spec in specs:
        if callable(spec):
            name = getattr(spec, "metric_name", getattr(spec, "__name__", "metric"))
            out[name] = spec
            continue
        if spec in _METRICS:
            out[spec] = _METRICS[spec]
            continue
        fn = resolve_class("metric", str(spec), where=f"metrics[{spec!r}]")
        if not callable(fn):
            raise InputError(f"metrics: {spec!r} is not callable (expected a function RunRecord -> dict)")
        name = getattr(fn, "metric_name", str(spec).rpartition(":")[2])
        out[name] = fn
    for name in out:
        if name in RESERVED_NAMES or "." in name:
            raise InputError(f"metrics: name {name!r} is reserved or has a dot")
    return out


def _check_values(name: str, value: Any) -> Any:
    if isinstance(value, Mapping):
        return {str(k): _check_values(f"{name}.{k}", v) for k, v in value.items()}
    if isinstance(value, bool):
        return value
    try:
        return float(value)
    except (TypeError, ValueError):
        raise InputError(f"metric {name}: expected a number, got {type(value).__name__}") from None


def run_metric(name: str, fn: MetricFn, record: Any) -> dict[str, Any]:
    """Call one metric and check it returned a (nested) dict of numbers."""
    value = fn(record)
    if not isinstance(value, Mapping):
        raise InputError(f"metric {name}: expected a dict of floats, got {type(value).__name__}")
    return _check_values(name, value)
