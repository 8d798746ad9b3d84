"""One Monte Carlo run, executed in a worker process (local pool or Dask worker).

`execute_run` is a plain top-level function of plain data so that both back ends can ship it.
It never raises: a failed run comes back as a row with status "error" and its error text, so
one failure never loses the others. The row is also written to the run's folder atomically
(result.json), which is what makes a batch resumable.
"""

from __future__ import annotations

import json
import logging
import math
import multiprocessing
import os
import time
import traceback
from pathlib import Path
from typing import Any

import numpy as np

from testbench.core.heap import keep_freed_memory

log = logging.getLogger(__name__)

# What one worker process keeps between its runs (testbench.world.memo): a 7 km world at
# 1.5 m, camera imagery and reference map at two ground samples, is ~400 MB.
WORKER_MEMO_MB = 1024


def execute_run(scenario: str, run_dir: str, index: int, entropy: int, spawn_key: tuple[int, ...], overrides: tuple[str, ...], varied: dict[str, Any]) -> dict[str, Any]:
    """Run one scenario instance; returns its result row (also saved as run_dir/result.json)."""
    # Each worker uses one core: libraries below must not start their own thread pools.
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    keep_freed_memory()  # a Dask worker does not come through the CLI (core/heap.py)
    t0 = time.perf_counter()
    row: dict[str, Any] = {"run": index, "seed_entropy": str(entropy), "seed_spawn_key": json.dumps(list(spawn_key))}
    row.update({f"vary.{k}": v for k, v in varied.items()})
    try:
        import cv2

        cv2.setNumThreads(1)
        from testbench.world import memo

        if multiprocessing.parent_process() is not None:
            # A pool or Dask worker process (not the caller's own process, whose memory the
            # memo would keep): its runs share whole-map reads and feature images.
            memo.enable(int(float(os.environ.get("TESTBENCH_WORKER_MEMO_MB", WORKER_MEMO_MB)) * 2**20))
        from testbench.config.loader import load_scenario
        from testbench.sim.runner import run_scenario

        loaded = load_scenario(scenario, list(overrides))
        seq = np.random.SeedSequence(entropy=entropy, spawn_key=tuple(spawn_key))
        outcome = run_scenario(loaded, run_dir, seed=seq, report=False)
        row.update({"status": outcome.status, "exit_status": outcome.exit_status, "error": outcome.abort_reason or ""})
        row.update({k: float(v) for k, v in outcome.metrics.items() if isinstance(v, (int, float)) and not isinstance(v, bool)})
        row["thresholds_failed"] = ",".join(outcome.failed_thresholds)
    except BaseException as exc:  # noqa: BLE001 -- recorded, the batch goes on
        if isinstance(exc, KeyboardInterrupt):
            raise
        row.update({"status": "error", "exit_status": getattr(exc, "exit_status", 1), "error": f"{type(exc).__name__}: {exc}"})
        log.debug("run %d failed:\n%s", index, traceback.format_exc())
    row["worker_wall_s"] = time.perf_counter() - t0
    _save(Path(run_dir) / "result.json", row)
    return row


def _save(path: Path, row: dict[str, Any]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".json.part")
    clean = {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in row.items()}
    tmp.write_text(json.dumps(clean, sort_keys=True), encoding="utf-8")
    tmp.replace(path)  # atomic: a killed run never leaves a half-written result


def load_result(run_dir: Path) -> dict[str, Any] | None:
    """The saved row of a finished run, or None if it has not finished."""
    p = run_dir / "result.json"
    if not p.is_file():
        return None
    try:
        row = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError):
        return None
    return {k: (math.nan if v is None else v) for k, v in row.items()}
