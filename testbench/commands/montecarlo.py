"""`testbench montecarlo SCENARIO --runs N [--workers K | --scheduler ADDR] --out DIR`."""

from __future__ import annotations

import argparse
import math
import sys


def register(subparsers) -> None:
    p = subparsers.add_parser("montecarlo", help="run a Monte Carlo batch (local pool or Dask cluster); resumable")
    p.add_argument("scenario")
    p.add_argument("--runs", type=int, required=True, help="number of runs N (seeds SeedSequence(seed).spawn(N))")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--workers", type=int, default=1, help="local worker processes (default 1)")
    g.add_argument("--scheduler", help="Dask scheduler address, e.g. tcp://127.0.0.1:8786")
    p.add_argument("--out", required=True, help="batch folder (re-run into it to resume)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY.PATH=VALUE")
    p.add_argument("--vary", action="append", default=[], metavar="KEY.PATH=DIST", help="uniform(a,b) | normal(mu,sigma) | choice(a,b,..) | linspace(a,b) | sequence(a,b,..) "
                   "(run i takes value i, cycling); KEY+=DIST adds the draw to the scenario's value; KEY1,KEY2=DIST "
                   "gives both keys one draw, and choice/sequence of [v1,v2] tuples one value each")
    p.add_argument("--seed", type=int, help="batch seed (default: the scenario's)")
    p.add_argument("--no-report", action="store_true")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from testbench.batch import BatchPlan, Vary, run_batch
    from testbench.config.loader import load_scenario
    from testbench.core.errors import InputError
    from testbench.sim.runner import check_scenario

    if args.runs < 1:
        raise InputError(f"--runs {args.runs}: expected a positive integer")
    if args.workers < 1:
        raise InputError(f"--workers {args.workers}: expected a positive integer")
    vary = tuple(Vary.parse(v) for v in args.vary)
    # Check the scenario before starting workers: validated, and the first run's (every varied
    # key at its first draw) built as `run --check` builds it (maps opened, initial state set),
    # so that a bad path or an impossible start is one clear error, not N failed runs. Built
    # only for the local pool: a cluster's workers open the maps on their own file systems.
    loaded = load_scenario(args.scenario, list(args.overrides))
    seed = loaded.scenario.seed if args.seed is None else args.seed
    plan = BatchPlan(args.scenario, args.runs, seed, tuple(args.overrides), vary)
    if vary:
        loaded = load_scenario(args.scenario, list(plan.run_specs()[0].overrides))
    if args.scheduler is None:
        check_scenario(loaded)
    bar = tqdm(total=args.runs, unit="run", file=sys.stderr, disable=not sys.stderr.isatty())
    failed = 0

    def on_result(row) -> None:
        nonlocal failed
        failed += row.get("status") == "error"
        bar.update(1)
        bar.set_postfix(errors=failed)

    try:
        result = run_batch(plan, args.out, workers=args.workers, scheduler=args.scheduler, on_result=on_result, report=not args.no_report)
    except KeyboardInterrupt:
        bar.close()
        print(f"interrupted: finished runs are kept in {args.out}; run the same command again to resume", file=sys.stderr)
        return 130
    bar.close()
    counts = result.summary["status_counts"]
    print(f"batch {args.out}: {len(result.rows)}/{args.runs} runs ({result.skipped} resumed), status {counts}")
    nees = result.summary.get("nees_position")
    if nees:
        line = (f"position NEES: average of {nees['runs']} runs inside its 95 % band {nees['fraction_within']:.3f} "
                f"of the time, mean {nees['mean_of_average']:.2f} (3 consistent)")
        if math.isfinite(nees.get("chance_p_value", math.nan)):
            line += (f"; a consistent filter with these errors' time correlation: {nees['chance_share_mean']:.3f} on "
                     f"average, 5th percentile {nees['chance_share_p05']:.3f}, p = {nees['chance_p_value']:.3f}")
        print(line)
    return 0 if counts.get("error", 0) == 0 else 1
