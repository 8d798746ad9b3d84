"""Runs a batch's pending runs on a local process pool or a Dask distributed cluster.

Both back ends execute the same `worker.execute_run` on the same plain arguments, so the same
batch gives identical per-run metrics whichever runs it. Finished runs are on disk as soon as
they finish (result.json), so an interrupted batch (Ctrl-C, a killed machine) keeps them and a
re-run into the same folder resumes with the rest.
"""

from __future__ import annotations

import concurrent.futures as cf
import logging
import multiprocessing
from pathlib import Path
from typing import Any, Callable, Iterable

from testbench.batch.plan import RunSpec
from testbench.batch.worker import execute_run

log = logging.getLogger(__name__)

OnResult = Callable[[dict[str, Any]], None]


def _args(spec: RunSpec, scenario: str, runs_dir: Path) -> tuple:
    return (scenario, str(runs_dir / spec.name), spec.index, spec.entropy, spec.spawn_key, spec.overrides, spec.varied)


def run_local(specs: Iterable[RunSpec], scenario: str, runs_dir: Path, workers: int, on_result: OnResult) -> None:
    """A pool of `workers` processes (spawned: each starts clean, no inherited JSBSim state)."""
    ctx = multiprocessing.get_context("spawn")
    pool = cf.ProcessPoolExecutor(max_workers=workers, mp_context=ctx)
    try:
        futures = [pool.submit(execute_run, *_args(s, scenario, runs_dir)) for s in specs]
        for fut in cf.as_completed(futures):
            on_result(fut.result())
    except BaseException:
        # Ctrl-C or an error in the parent: drop what has not started; finished runs are saved.
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown(wait=True)


def run_dask(specs: Iterable[RunSpec], scenario: str, runs_dir: Path, scheduler: str, on_result: OnResult) -> None:
    """The same runs on a Dask distributed cluster at `scheduler` (e.g. tcp://host:8786).

    The workers must see the scenario file and the output folder at the same paths (a shared
    file system), as usual for Dask batch jobs.
    """
    from distributed import Client, as_completed

    from testbench.core.errors import InputError

    try:
        client = Client(scheduler, timeout="20s")
    except (OSError, TimeoutError) as exc:
        raise InputError(f"--scheduler {scheduler}: cannot reach a Dask scheduler there ({exc})") from None
    try:
        futures = [
            client.submit(execute_run, *_args(s, scenario, runs_dir), key=f"testbench-{runs_dir.parent.name}-{s.name}", pure=False)
            for s in specs
        ]
        for fut in as_completed(futures):
            on_result(fut.result())
    except BaseException:
        client.cancel(futures if "futures" in locals() else [])
        raise
    finally:
        client.close()
