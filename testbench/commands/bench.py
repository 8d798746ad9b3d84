"""`testbench bench [--json FILE]`: the project's benchmarks, each a ratio or a time measured
in this one process (compare ratios, not absolute times, across machines)."""

from __future__ import annotations

import argparse
import importlib
import json
import logging
import platform
import sys
import time
from datetime import datetime, timezone

from testbench.sim.provenance import environment

log = logging.getLogger(__name__)

# (group, module with run_benchmarks() -> dict[str, float])
SUITES = (
    ("engine", "testbench.sim.bench"),
    ("control", "testbench.control.bench"),
    ("sensors", "testbench.sensors.bench"),
    ("render", "testbench.sensors.camera.bench"),
    ("world", "testbench.world.bench"),
    ("nav", "testbench.navigation.ins.bench"),
    ("ismn", "testbench.navigation.ismn.bench"),
    ("relnav", "testbench.navigation.relative.bench"),
    ("cnn", "testbench.navigation.relative.cnn.bench"),
    ("scenarios", "testbench.batch.bench"),
)


def register(subparsers) -> None:
    p = subparsers.add_parser("bench", help="measure speed: engine overhead, renderer, ISMN latency, scenario real-time factors, Monte Carlo scaling")
    p.add_argument("--json", dest="json_file", help="write the figures to this JSON file")
    p.add_argument("--only", action="append", default=[], help=f"run only these groups ({', '.join(g for g, _ in SUITES)})")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    import cv2

    cv2.setNumThreads(1)  # one-core figures
    figures: dict[str, float] = {}
    for group, module_name in SUITES:
        if args.only and group not in args.only:
            continue
        t0 = time.perf_counter()
        module = importlib.import_module(module_name)
        out = module.run_benchmarks()
        figures.update(out)
        print(f"[{group}] {time.perf_counter() - t0:.1f} s", file=sys.stderr)
        for k, v in sorted(out.items()):
            print(f"  {k:45s} {v:12.4g}")
    # Library builds and CPU features: what else besides the code a figure depends on.
    env = environment()
    meta = {
        "date_utc": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M"),
        "machine": f"{platform.machine()} {platform.processor() or ''} {env['cpu'] or ''}".strip(),
        "cores": _cores(),
        "python": platform.python_version(),
        "environment": env,
    }
    if args.json_file:
        with open(args.json_file, "w", encoding="utf-8") as fh:
            json.dump({"meta": meta, **dict(sorted(figures.items()))}, fh, indent=2)
    return 0


def _cores() -> int:
    import os

    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


