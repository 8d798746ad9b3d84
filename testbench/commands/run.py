"""`testbench run SCENARIO --out DIR`: fly one scenario and write the output contract."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from testbench.config.loader import load_scenario
from testbench.core.errors import InputError


def register(subparsers) -> None:
    p = subparsers.add_parser("run", help="run a scenario and write metrics, telemetry, trajectories and a report")
    p.add_argument("scenario", help="scenario YAML file")
    p.add_argument("--out", help="output folder (default: reports/<scenario name>)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY.PATH=VALUE", help="override a scenario key (repeatable)")
    p.add_argument("--seed", type=int, help="override the scenario seed")
    p.add_argument("--realtime", action="store_true", help="pace the run to the wall clock and report the lag")
    p.add_argument("--no-report", action="store_true", help="do not write report.html")
    p.add_argument("--pdf", action="store_true", help="also write report.pdf")
    p.add_argument("--save-frames", type=int, metavar="N", default=0, help="save every Nth camera frame as PNG under OUT/frames")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--processes", type=int, default=1, metavar="N",
                   help="run the vehicles' sensors, navigation and control in N processes, this one and N - 1 "
                        "forked workers (a swarm on several cores; the same record as one process; Linux, not with "
                        "--save-frames)")
    p.add_argument("--check", action="store_true",
                   help="only check the scenario: build every vehicle, open every map, set the initial state, "
                        "print the resolved scenario (YAML) and exit 0 (2 on bad input) without flying or writing")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from testbench.sim.runner import run_scenario

    overrides = list(args.overrides)
    if args.seed is not None:
        if args.seed < 0:
            raise InputError(f"--seed {args.seed}: expected a non-negative integer")
        overrides.append(f"seed={args.seed}")
    loaded = load_scenario(args.scenario, overrides)
    if args.check:
        from testbench.sim.runner import check_scenario

        resolved = check_scenario(loaded)
        n = len(loaded.scenario.vehicles)
        print(f"# {loaded.scenario.name}: valid; {n} vehicle{'s' * (n != 1)} built, maps opened, initial state set")
        print(resolved, end="")
        return 0
    out = Path(args.out) if args.out else Path("reports") / loaded.scenario.name
    if args.save_frames < 0:
        raise InputError(f"--save-frames {args.save_frames}: expected a non-negative integer")
    if args.processes < 1:
        raise InputError(f"--processes {args.processes}: expected a positive integer")
    bar = _progress(loaded.scenario.duration_s, disabled=args.quiet)
    sink = _frame_saver(out / "frames", args.save_frames) if args.save_frames else None
    try:
        outcome = run_scenario(
            loaded, out, realtime=args.realtime, on_progress=bar.update_to, frame_sink=sink,
            report=not args.no_report, pdf=args.pdf, processes=args.processes,
        )
    finally:
        bar.close()
    m = outcome.metrics
    keys = [
        "real_time_factor", "control.altitude_error_m.rms", "control.cross_track_error_m.rms",
        "nav.horizontal_error_m.mean", "ismn.smooth.horizontal_error_m.mean", "ismn.turning.horizontal_error_m.mean",
        "ismn.fix_rate", "relnav.error_m.max", "formation.error_m.rms",
    ]
    shown = ", ".join(f"{k}={m[k]:.3g}" for k in keys if isinstance(m.get(k), (int, float)))
    print(f"{outcome.status}: {loaded.scenario.name} -> {out}  ({shown})")
    if outcome.abort_reason:
        print(f"aborted: {outcome.abort_reason}", file=sys.stderr)
    if isinstance(m.get("nav.lost_at_s"), (int, float)):
        # Which vehicles, when several fly (metrics flattened: vehicles.<id>.nav.lost_at_s).
        lost = sorted((v, k.split(".")[1]) for k, v in m.items()
                      if k.startswith("vehicles.") and k.endswith(".nav.lost_at_s") and isinstance(v, (int, float)))
        who = "" if len(lost) < 2 else " (" + ", ".join(f"{vid} at {t:.1f} s" for t, vid in lost) + ")"
        print(f"warning: the navigator was lost from t={m['nav.lost_at_s']:.1f} s{who}: its position error stayed beyond "
              "5.5 sigma of its own covariance for 10 s (nav.lost_at_s; see nav.nees in metrics.json)", file=sys.stderr)
    for key in outcome.failed_thresholds:
        print(f"threshold failed: {key}", file=sys.stderr)
    return outcome.exit_status


class _NoBar:
    def update_to(self, t_s: float) -> None:
        pass

    def close(self) -> None:
        pass


class _Bar:
    def __init__(self, total_s: float):
        from tqdm import tqdm

        self._bar = tqdm(total=round(total_s), unit="sim s", file=sys.stderr, dynamic_ncols=True, leave=False)

    def update_to(self, t_s: float) -> None:
        self._bar.update(int(t_s) - self._bar.n)

    def close(self) -> None:
        self._bar.close()


def _progress(total_s: float, disabled: bool):
    # A bar only where someone watches: long runs on a terminal.
    if disabled or not sys.stderr.isatty():
        return _NoBar()
    return _Bar(total_s)


def _frame_saver(folder: Path, every: int):
    counts: dict[tuple[str, str], int] = {}

    def sink(vehicle_id: str, sensor: str, frame) -> None:
        key = (vehicle_id, sensor)
        n = counts.get(key, 0)
        counts[key] = n + 1
        if n % every == 0:
            from testbench.sensors.camera import save_frame_png

            folder.mkdir(parents=True, exist_ok=True)
            save_frame_png(frame, folder / f"{vehicle_id}_{sensor}_{frame.t_s:08.2f}.png")

    return sink
