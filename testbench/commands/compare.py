"""`testbench compare BASE NEW`: two runs or two Monte Carlo batches, metric by metric.

Exit 0 when nothing got worse, 3 when a figure got worse or went missing, or the new run
aborted where the base completed (as a failed threshold), 2 for bad input. The statistics live in testbench.scoring.compare.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from testbench.core.errors import EXIT_THRESHOLD_FAILED, InputError

# Per-vehicle and per-pair figures repeat the top-level ones many times over in a swarm.
DETAIL_PATTERNS = ("vehicles.*", "*.pairs.*")


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "compare", help="compare two runs (or two Monte Carlo batches) metric by metric: better, worse, same")
    p.add_argument("base", metavar="BASE", help="run folder (testbench run --out) or batch folder (testbench montecarlo --out)")
    p.add_argument("new", metavar="NEW", help="the same kind of folder, to compare against BASE")
    p.add_argument("--only", action="append", default=[], metavar="GLOB", help="compare only keys matching (repeatable), e.g. 'nav.*'")
    p.add_argument("--ignore", action="append", default=[], metavar="GLOB", help="leave out keys matching (repeatable)")
    p.add_argument("--details", action="store_true", help="also per-vehicle and per-pair figures (left out by default)")
    p.add_argument("--rel-tol", type=float, default=0.02, help="a relative change above this counts (runs: of the value; batches: of the mean, and only when significant; default 0.02)")
    p.add_argument("--alpha", type=float, default=0.05, help="batches: significance level of the rank test (default 0.05)")
    p.add_argument("--timing", action="store_true", help="let a slower wall time, real-time factor or latency fail the comparison")
    p.add_argument("--all", action="store_true", help="list unchanged figures too")
    p.add_argument("--json", metavar="FILE", help="write every compared figure to this JSON file")
    p.set_defaults(handler=run)


def _kind(folder: Path) -> str:
    if (folder / "runs.parquet").is_file():
        return "batch"
    if (folder / "metrics.json").is_file():
        return "run"
    raise InputError(f"{folder}: neither a run folder (metrics.json) nor a batch folder (runs.parquet); "
                     "expected the --out folder of `testbench run` or `testbench montecarlo`")


def _meta(folder: Path, kind: str) -> dict:
    """The folder's batch.json or run.json ({} when missing or not a JSON object)."""
    try:
        meta = json.loads((folder / ("batch.json" if kind == "batch" else "run.json")).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return meta if isinstance(meta, dict) else {}


def _scenario_name(meta: dict, kind: str) -> str | None:
    return Path(str(meta.get("scenario", ""))).stem if kind == "batch" else meta.get("scenario_name")


def run(args: argparse.Namespace) -> int:
    from testbench.scoring import compare as cmp

    if not (args.rel_tol >= 0 and math.isfinite(args.rel_tol)):
        raise InputError(f"--rel-tol {args.rel_tol}: expected a number >= 0")
    if not 0 < args.alpha < 1:
        raise InputError(f"--alpha {args.alpha}: expected a number between 0 and 1")
    base, new = Path(args.base), Path(args.new)
    kinds = (_kind(base), _kind(new))
    if kinds[0] != kinds[1]:
        raise InputError(f"{base} is a {kinds[0]} folder but {new} is a {kinds[1]} folder; expected two of the same kind")
    ignore = list(args.ignore) + ([] if args.details else list(DETAIL_PATTERNS))
    metas = (_meta(base, kinds[0]), _meta(new, kinds[0]))
    names = (_scenario_name(metas[0], kinds[0]), _scenario_name(metas[1], kinds[0]))
    if names[0] != names[1]:
        print(f"note: different scenarios ({names[0]} / {names[1]}): the figures may not be comparable", file=sys.stderr)
    status = None
    if kinds[0] == "run":
        _note_numerics(metas[0].get("environment"), metas[1].get("environment"))
        flats = (_flat_metrics(base), _flat_metrics(new))
        status = cmp.compare_status(flats[0].get("status"), flats[1].get("status"))
        changes = cmp.compare_runs(*flats, args.rel_tol, args.only, ignore)
        head = f"runs: {base} -> {new} (a change counts above {args.rel_tol:.0%} of the base value)"
    else:
        import pandas as pd

        changes, paired = cmp.compare_batches(pd.read_parquet(base / "runs.parquet"), pd.read_parquet(new / "runs.parquet"),
                                              args.alpha, args.rel_tol, args.only, ignore)
        changes += cmp.compare_runs(_batch_figures(base), _batch_figures(new), args.rel_tol, args.only, ignore)
        test = "paired runs, Wilcoxon signed-rank" if paired else "unpaired runs, Mann-Whitney U"
        head = (f"batches: {base} -> {new} (means over runs; {test}; a change counts at p < {args.alpha} "
                f"and above {args.rel_tol:.0%} of the base mean)")
    if not changes:
        raise InputError(f"no metric in common to compare (--only {args.only or '-'}, --ignore {ignore or '-'})")
    bad = cmp.failed(changes, timing_counts=args.timing) or (status is not None and status.verdict == "worse")
    print(head)
    if status is not None and status.verdict != "same":
        aborted = [f"{which}: {m['abort_reason']}" for which, m in zip(("base", "new"), metas)
                   if m.get("status") == "aborted" and m.get("abort_reason")]
        print(f"status: {status.base} -> {status.new}  {status.verdict}" + "".join(f"\n  {a}" for a in aborted)
              + ("\n  (an aborted run's figures cover only the time before its abort)" if aborted else ""))
    _print_table([c for c in cmp.sort_changes(changes) if args.all or c.verdict != "same"])
    counts = {v: sum(1 for c in changes if c.verdict == v) for v in cmp.ORDER}
    print(", ".join(f"{n} {v}" for v, n in counts.items() if n) + f" (of {len(changes)})")
    if args.json:
        rows = ([status.to_dict()] if status is not None else []) + [c.to_dict() for c in changes]
        Path(args.json).write_text(json.dumps(rows, indent=1, allow_nan=False) + "\n", encoding="utf-8")
    return EXIT_THRESHOLD_FAILED if bad else 0


def _note_numerics(base_env: dict | None, new_env: dict | None) -> None:
    """Say on stderr when two runs (their run.json `environment`) were made under different code
    or numerics: then even the same scenario and seed fly different realisations
    (testbench.sim.provenance), and a change in a single-event figure (a maximum) may be chance
    rather than the code."""
    from testbench.sim.provenance import numerics_differences

    diffs = numerics_differences(base_env, new_env)
    if diffs:
        print("note: the runs differ in " + "; ".join(diffs) + ": under the same seed their records are "
              "bit-identical only when code, library builds and CPU features are the same", file=sys.stderr)


def _flat_metrics(folder: Path) -> dict:
    from testbench.scoring.result import flatten

    try:
        return flatten(json.loads((folder / "metrics.json").read_text(encoding="utf-8")))
    except ValueError as exc:
        raise InputError(f"{folder / 'metrics.json'}: not valid JSON ({exc})") from None


def _batch_figures(folder: Path) -> dict:
    """The batch-level figures of summary.json (one number per batch, no test): its position
    NEES consistency and threshold pass rate, as batch.<key>."""
    from testbench.scoring.result import flatten

    try:
        summary = json.loads((folder / "summary.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    sections = {k: summary[k] for k in ("nees_position", "threshold_pass_rate") if isinstance(summary.get(k), dict)}
    figures = flatten(sections, "batch.")
    counts = summary.get("status_counts")
    if isinstance(counts, dict) and sum(counts.values()):
        # The share of runs that flew to their end (passed or failed a threshold): the per-run
        # figures and the pass rate are of those runs only, so an aborted run shows only here.
        finished = counts.get("passed", 0) + counts.get("threshold_failed", 0)
        figures["batch.finished_rate"] = finished / sum(counts.values())
    return figures


def _print_table(changes) -> None:
    if not changes:
        return
    w = max(len(c.key) for c in changes)
    print(f"{'metric':<{w}}  {'base':>11}  {'new':>11}  {'change':>8}  {'p':>6}  verdict")
    for c in changes:
        rel = "" if math.isnan(c.rel) else f"{c.rel:+.1%}"
        p = "" if math.isnan(c.p) else f"{c.p:.3f}"
        tag = c.verdict + (" (timing)" if c.timing and c.verdict in ("worse", "better", "changed") else "")
        print(f"{c.key:<{w}}  {c.base:>11.4g}  {c.new:>11.4g}  {rel:>8}  {p:>6}  {tag}")
