"""`testbench sensors record|allan`: static IMU records and their Allan-deviation analysis."""

from __future__ import annotations

import json
import os
import time

import numpy as np

from testbench.core.errors import InputError


def register(subparsers) -> None:
    p = subparsers.add_parser("sensors", help="sensor model tools: static IMU records, Allan analysis")
    sub = p.add_subparsers(dest="sensors_cmd", required=True)
    r = sub.add_parser("record", help="write a static (level, at rest) IMU record to parquet")
    r.add_argument("--preset", default="paper", choices=["paper", "consumer_mems", "tactical"])
    r.add_argument("--duration", type=float, default=7200.0, help="seconds (default 7200)")
    r.add_argument("--rate", type=float, default=100.0, help="Hz (default 100)")
    r.add_argument("--lat-deg", type=float, default=45.0, help="latitude for the Earth rate (default 45)")
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--out", required=True, help="output .parquet file")
    r.set_defaults(handler=_record)
    a = sub.add_parser("allan", help="Allan deviation of a static record: fits, allan.json, allan.png")
    a.add_argument("record", help="parquet file written by `testbench sensors record`")
    a.add_argument("--preset", default=None, help="preset drawn for comparison (default: the record's own)")
    a.add_argument("--out", required=True, help="output folder")
    a.set_defaults(handler=_allan)


def _record(args) -> int:
    from testbench.sensors.imu_params import ImuParams
    from testbench.sensors.imu_static import static_record, write_parquet

    if args.duration <= 0 or args.rate <= 0:
        raise InputError(f"--duration and --rate must be positive (got {args.duration}, {args.rate})")
    t0 = time.perf_counter()
    rec = static_record(ImuParams(preset=args.preset).spec(), args.duration, args.rate,
                        np.random.default_rng(args.seed), lat_rad=np.deg2rad(args.lat_deg))
    gen_s = time.perf_counter() - t0
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    write_parquet(rec, args.out, {"preset": args.preset, "rate_hz": args.rate, "lat_deg": args.lat_deg, "seed": args.seed})
    print(f"wrote {args.out}: {len(rec['t_s'])} samples ({args.preset}, {args.rate:g} Hz), generated in {gen_s:.2f} s")
    return 0


def _allan(args) -> int:
    import pyarrow.parquet as pq

    from testbench.sensors.allan import analyse_record
    from testbench.sensors.imu_params import PRESETS, ImuParams
    from testbench.sensors.imu_static import COLUMNS

    if not os.path.isfile(args.record):
        raise InputError(f"{args.record}: no such file (expected a parquet IMU record)")
    try:
        table = pq.read_table(args.record)
    except Exception as exc:  # pyarrow raises several types for a bad file
        raise InputError(f"{args.record}: not a readable parquet file ({exc})") from None
    missing = [c for c in COLUMNS if c not in table.column_names]
    if missing:
        raise InputError(f"{args.record}: missing columns {missing}; expected {list(COLUMNS)}")
    meta = {k.decode(): v.decode() for k, v in (table.schema.metadata or {}).items()}
    preset = args.preset or meta.get("preset", "paper")
    if preset not in PRESETS:
        raise InputError(f"--preset: unknown {preset!r}; expected one of {sorted(PRESETS)}")
    rec = {c: table.column(c).to_numpy() for c in COLUMNS}
    fits = analyse_record(rec)
    spec = ImuParams(preset=preset).spec()
    os.makedirs(args.out, exist_ok=True)
    summary = {"record": os.path.abspath(args.record), "preset": preset, "channels": {}}
    for name, fit in fits.items():
        ref = spec.gyro if name.startswith("gyro") else spec.accel
        summary["channels"][name] = {
            **{k: v for k, v in fit.as_dict().items()},
            "configured": {"white_density": ref.white_density, "bias_instability": ref.bias_instability,
                           "rate_random_walk": ref.rate_random_walk},
            "ratio": {"white_density": fit.white_density / ref.white_density if ref.white_density else None,
                      "bias_instability": fit.bias_instability / ref.bias_instability if ref.bias_instability else None},
        }
    with open(os.path.join(args.out, "allan.json"), "w") as fh:
        json.dump(summary, fh, indent=1)
    _plot(fits, spec, os.path.join(args.out, "allan.png"))
    for name, ch in summary["channels"].items():
        print(f"{name}: white x{ch['ratio']['white_density']:.3f}, bias instability x{ch['ratio']['bias_instability']:.3f} of configured")
    print(f"wrote {args.out}/allan.json and allan.png")
    return 0


def _plot(fits, spec, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 5))
    for ax, triad, ref, unit in ((axes[0], "gyro", spec.gyro, "rad/s"), (axes[1], "accel", spec.accel, "m/s^2")):
        taus = None
        for name, fit in fits.items():
            if name.startswith(triad):
                ax.loglog(fit.taus_s, fit.adev, label=name)
                taus = fit.taus_s
        if taus is not None:
            model = np.sqrt(ref.white_density**2 / taus + (0.664 * ref.bias_instability) ** 2
                            + ref.rate_random_walk**2 * taus / 3.0)
            ax.loglog(taus, ref.white_density / np.sqrt(taus), "k--", lw=1, label="configured white N/sqrt(tau)")
            ax.loglog(taus, np.full_like(taus, 0.664 * ref.bias_instability), "k:", lw=1, label="configured floor 0.664 B")
            ax.loglog(taus, model, "k-", lw=1.5, alpha=0.5, label="configured model")
        ax.set_xlabel("tau (s)")
        ax.set_ylabel(f"Allan deviation ({unit})")
        ax.set_title(triad)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
