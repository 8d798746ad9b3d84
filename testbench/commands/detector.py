"""`testbench detector train|eval`: the CNN detector's reproducible training and its
precision/recall by range on a freshly rendered held-out set."""

from __future__ import annotations

import json
import os

from testbench.core.errors import InputError


def register(subparsers) -> None:
    p = subparsers.add_parser("detector", help="CNN detector: train from a seed, evaluate by range")
    sub = p.add_subparsers(dest="detector_cmd", required=True)
    t = sub.add_parser("train", help="render crops, train the CNN detector on CPU, write weights + JSON card")
    t.add_argument("--seed", type=int, required=True)
    t.add_argument("--out", required=True, help="weights file to write (.pt); the card goes to the same name .json")
    t.add_argument("--minutes", type=float, default=None,
                   help="wall-clock cap (stops early: a capped run is no longer reproducible)")
    t.add_argument("--steps", type=int, default=None, help="optimisation steps (default 4000, as the packaged weights)")
    t.add_argument("--samples", type=int, default=None, help="rendered training crops (default 16000)")
    t.set_defaults(handler=_train)
    e = sub.add_parser("eval", help="precision/recall by range bin on fresh held-out renders")
    e.add_argument("--weights", default=None, help="weights file (default: the packaged weights)")
    e.add_argument("--frames", type=int, default=200, help="crops per range bin (default 200)")
    e.add_argument("--seed", type=int, default=12345)
    e.add_argument("--score-min", type=float, default=None, help="detection threshold (default: the detector's)")
    e.add_argument("--json", default=None, help="also write the result to this JSON file")
    e.set_defaults(handler=_eval)


def _train(args) -> int:
    from testbench.navigation.relative.cnn.train import TrainSettings, quick_settings, train

    if args.minutes is not None and args.minutes <= 0:
        raise InputError(f"--minutes must be positive (got {args.minutes})")
    kw = {}
    if args.steps is not None:
        if args.steps < 1:
            raise InputError(f"--steps must be >= 1 (got {args.steps})")
        kw["steps"] = args.steps
    if args.samples is not None:
        if args.samples < TrainSettings().batch:
            raise InputError(f"--samples must be >= {TrainSettings().batch} (got {args.samples})")
        kw["n_train"] = args.samples
    out_dir = os.path.dirname(os.path.abspath(args.out))
    if not os.path.isdir(out_dir):
        raise InputError(f"--out {args.out}: folder {out_dir} does not exist")

    def progress(step: int, loss: float) -> None:
        if step % 200 == 0:
            print(f"step {step}: loss {loss:.4f}", flush=True)

    card = train(args.seed, args.out, args.minutes, quick_settings(**kw), progress=progress)
    from testbench.navigation.relative.cnn.evaluate import format_table

    print(f"wrote {args.out} ({card['weights_bytes']} bytes) and its card; time {card['time_s']}")
    if card["stopped_early_by_time_cap"]:
        print(f"stopped by the --minutes cap after {card['steps_done']} steps (not reproducible)")
    print(format_table(card["validation"]))
    return 0


def _eval(args) -> int:
    from testbench.navigation.relative.cnn.detector import CnnDetector
    from testbench.navigation.relative.cnn.evaluate import EvalSettings, evaluate, format_table

    if args.frames < 1:
        raise InputError(f"--frames must be >= 1 (got {args.frames})")
    kw = {}
    if args.weights is not None:
        kw["weights"] = args.weights
    if args.score_min is not None:
        kw["score_min"] = args.score_min
    try:
        params = CnnDetector.Params(**kw)
    except Exception as exc:
        raise InputError(f"detector eval: bad option ({str(exc).splitlines()[0]})") from None
    det = CnnDetector(params)
    res = evaluate(det, args.seed, EvalSettings(frames_per_bin=args.frames))
    print(format_table(res))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(res, f, indent=2)
    return 0
