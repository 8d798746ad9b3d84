"""`testbench ismn replay`: a recorded run's camera frames through the scene-matching pipeline,
open loop (testbench.navigation.ismn.harness), to compare pipeline settings frame by frame;
`testbench ismn sensitivity`: how much the fixes follow the estimate they are given
(testbench.navigation.ismn.sensitivity); `testbench ismn map-agreement`: how two reference maps
disagree in georeference, tile by tile (testbench.navigation.ismn.map_agreement)."""

from __future__ import annotations

import json


def _run_frames_args(parser, step_s: float) -> None:
    """The arguments every tool over a recorded run's frames takes."""
    parser.add_argument("scenario", help="the scenario the run flew")
    parser.add_argument("run_dir", help="the run's output folder (its telemetry.parquet)")
    parser.add_argument("--set", action="append", help="scenario override key.path=value (repeatable)")
    parser.add_argument("--t0", type=float, default=0.0, help="first frame time, s")
    parser.add_argument("--t1", type=float, default=1e9, help="last frame time, s")
    parser.add_argument("--step", type=float, default=step_s, help="frame spacing, s (a multiple of the 0.1 s record)")
    parser.add_argument("--pipeline", help="pipeline params to override, JSON (e.g. '{\"n_sigma\": 3}')")
    parser.add_argument("--frames-dir", help="cache of rendered frames (grey PNG; rendering costs more than matching)")
    parser.add_argument("--matcher", help="matcher params to override, JSON (e.g. '{\"tiles_x\": 9}')")


def register(subparsers) -> None:
    p = subparsers.add_parser("ismn", help="scene-matching tools: replay a recorded run's frames through the pipeline")
    sub = p.add_subparsers(dest="ismn_cmd", required=True)
    r = sub.add_parser("replay", help="render a run's camera at its true poses, match with its recorded estimates, "
                                      "score each fix against truth (open loop)")
    _run_frames_args(r, 0.5)
    r.add_argument("--matcher-type", help="matcher type to use instead of the scenario's (ncc, orb, sift)")
    r.add_argument("--save-bad", type=float, default=5.0, help="save frames whose fix errs by more than this, m")
    r.add_argument("--save-dir", help="where --save-bad frames go (.npz: ortho, map window)")
    r.add_argument("--est-truth", action="store_true", help="estimate = the true pose (+ --est-offset N,E,D) with the recorded sigmas")
    r.add_argument("--est-offset", help="N,E,D metres added to the true position with --est-truth")
    r.add_argument("--turn-bank-deg", type=float, default=10.0, help="a frame is 'turning' beyond this bank, deg")
    r.add_argument("--turn-rate-deg-s", type=float, default=3.0, help="... or beyond this heading rate, deg/s")
    r.add_argument("--rows", action="store_true", help="print every frame's row before the summary")
    r.set_defaults(handler=_replay)

    s = sub.add_parser("sensitivity", help="how much a fix follows its prior: d fix / d prior attitude and "
                                           "position on a run's frames, against the fix's declared coupling")
    _run_frames_args(s, 1.0)
    s.add_argument("--tilt-mrad", type=float, default=1.0, help="attitude step of the central differences, mrad")
    s.add_argument("--shift-m", type=float, default=0.3,
                   help="position step, m (well under the working ground sample: a whole pixel changes nothing)")
    s.add_argument("--sweep-steps", type=int, default=0,
                   help="also sweep the prior over --sweep-m in this many steps: the fix's spread and jumps (0: off)")
    s.add_argument("--sweep-m", type=float, default=1.5,
                   help="length of the sweep, m (about one working ground sample: paper_ismn_800m works at 1.54 m)")
    s.set_defaults(handler=_sensitivity)

    m = sub.add_parser("map-agreement", help="how far map B shows the ground from where map A shows it, tile by "
                                             "tile: the figures world.reference_map_error is set from")
    m.add_argument("map_a", help="GeoTIFF (any CRS)")
    m.add_argument("map_b", help="GeoTIFF of the same ground (another year, another source)")
    m.add_argument("--gsd-m", type=float, help="ground sample to compare at, m (default: the coarser map's)")
    m.add_argument("--tile-m", type=float, default=400.0, help="tile side, m")
    m.add_argument("--search-m", type=float, default=25.0, help="how far each tile is searched for, m")
    m.add_argument("--tiles", help="also write each matched tile (centre, offset, peak, kept) to this CSV")
    m.add_argument("--plot", help="also draw the tiles' offsets as arrows over map A to this PNG")
    m.set_defaults(handler=_map_agreement)


def _replay(args) -> int:
    from testbench.navigation.ismn.harness import run, summarise

    rows = run(args)
    if args.rows:
        for row in rows:
            print(" ".join(f"{k}={v:.3f}" if isinstance(v, float) else f"{k}={v}" for k, v in row.items()))
    print(json.dumps(summarise(rows), indent=1))
    return 0


def _sensitivity(args) -> int:
    from testbench.core.errors import InputError
    from testbench.navigation.ismn.sensitivity import run

    if not (args.tilt_mrad > 0 and args.shift_m > 0):
        raise InputError(f"--tilt-mrad and --shift-m must be > 0 (got {args.tilt_mrad}, {args.shift_m})")
    if args.sweep_steps < 0 or args.sweep_steps == 1 or (args.sweep_steps and not args.sweep_m > 0):
        raise InputError(f"--sweep-steps must be 0 (off) or >= 2 and --sweep-m > 0 "
                         f"(got {args.sweep_steps}, {args.sweep_m})")
    summary = run(args)
    # One line per key (a matrix row-major on its line): valid JSON that reads as a table.
    print("{\n" + ",\n".join(f" {json.dumps(k)}: {json.dumps(v)}" for k, v in summary.items()) + "\n}")
    return 0 if summary["n_used"] else 1


def _map_agreement(args) -> int:
    import math

    from testbench.core.errors import InputError
    from testbench.core.interfaces import GeodeticOrigin
    from testbench.navigation.ismn.map_agreement import map_agreement
    from testbench.world.geotiff import map_centre_lat_lon_deg
    from testbench.world.imagery import MapSource

    if not (args.tile_m > 0 and args.search_m > 0) or (args.gsd_m is not None and not args.gsd_m > 0):
        raise InputError(f"--tile-m, --search-m and --gsd-m must be > 0 (got {args.tile_m}, {args.search_m}, {args.gsd_m})")
    lat, lon = map_centre_lat_lon_deg(args.map_a, "map_a")
    origin = GeodeticOrigin(math.radians(lat), math.radians(lon), 0.0)
    with MapSource(args.map_a, origin) as a, MapSource(args.map_b, origin) as b:
        fa, fb = a.footprint, b.footprint
        bounds = (max(fa.north_min_m, fb.north_min_m), min(fa.north_max_m, fb.north_max_m),
                  max(fa.east_min_m, fb.east_min_m), min(fa.east_max_m, fb.east_max_m))
        if not (bounds[1] - bounds[0] > args.tile_m and bounds[3] - bounds[2] > args.tile_m):
            raise InputError(f"{args.map_b}: its ground and {args.map_a}'s share less than one {args.tile_m:g} m tile "
                             "(expected two maps of the same place)")
        gsd = args.gsd_m or max(float(a.native_gsd_m), float(b.native_gsd_m))
        result = map_agreement(a, b, bounds, gsd, args.tile_m, args.search_m)
        if args.plot:
            from testbench.navigation.ismn.map_agreement import agreement_figure
            from testbench.navigation.ismn.ortho import to_grey_u8

            preview_gsd = max(gsd, max(bounds[1] - bounds[0], bounds[3] - bounds[2]) / 1500.0)
            grey = to_grey_u8(a.read_local(*bounds, preview_gsd).data)
            agreement_figure(result, grey, bounds).savefig(args.plot)
    if args.tiles:
        keep = result.inliers()
        with open(args.tiles, "w") as f:
            f.write("centre_north_m,centre_east_m,offset_north_m,offset_east_m,peak,kept\n")
            for (cn, ce), (dn, de), pk, k in zip(result.centre_ne_m, result.offset_ne_m, result.peak, keep):
                f.write(f"{cn:.1f},{ce:.1f},{dn:.3f},{de:.3f},{pk:.3f},{int(k)}\n")
    print(json.dumps({"map_a": args.map_a, "map_b": args.map_b, **result.summary()}, indent=1))
    return 0 if len(result.offset_ne_m) else 1
