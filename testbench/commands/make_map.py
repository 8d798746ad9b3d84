"""`testbench make-map`: write a procedural world (imagery.tif, elevation.tif, preview.png)."""

from __future__ import annotations

import math
import os
import time

from testbench.core.errors import InputError
from testbench.core.interfaces import GeodeticOrigin


def _origin(text: str) -> GeodeticOrigin:
    try:
        parts = [float(p) for p in text.split(",")]
    except ValueError:
        parts = []
    if len(parts) not in (2, 3) or not (-90 <= parts[0] <= 90 and -180 <= parts[1] <= 180):
        raise InputError(f"--origin-lat-lon '{text}': expected LAT,LON[,ALT_M] in degrees")
    alt = parts[2] if len(parts) == 3 else 0.0
    return GeodeticOrigin(math.radians(parts[0]), math.radians(parts[1]), alt)


def register(subparsers) -> None:
    from testbench.world.procedural import SEASONS, TERRAINS

    p = subparsers.add_parser("make-map", help="generate a procedural world as GeoTIFFs",
                              description="Write DIR/imagery.tif, DIR/elevation.tif (GeoTIFF, "
                              "local transverse Mercator at the origin) and DIR/preview.png.")
    p.add_argument("--terrain", required=True, choices=TERRAINS)
    p.add_argument("--size-km", type=float, default=6.0, help="side of the square world (km)")
    p.add_argument("--gsd-m", type=float, default=1.0, help="metres per pixel")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--season", default="summer", help=f"{', '.join(SEASONS)} or 0..3")
    p.add_argument("--origin-lat-lon", default="47.0,-99.0",
                   help="LAT,LON[,ALT_M] degrees of the world centre (the scenario origin)")
    p.add_argument("--out", required=True, help="output folder")
    p.set_defaults(handler=run)


def run(args) -> int:
    import cv2

    from testbench.world.procedural.world import world_shape
    from testbench.world.procedural.writer import write_world_streamed

    origin = _origin(args.origin_lat_lon)
    t0 = time.perf_counter()
    img, dem, preview, (z_min, z_max) = write_world_streamed(
        args.out, args.terrain, args.size_km, args.gsd_m, args.seed, args.season, origin, preview_px=1500
    )
    cv2.imwrite(os.path.join(args.out, "preview.png"), preview[..., ::-1])
    h, w = world_shape(args.terrain, args.size_km, args.gsd_m)
    print(f"{img} ({w}x{h} px, {args.gsd_m:g} m/px), {dem} (relief {z_min:.1f}..{z_max:.1f} m): "
          f"generated and written in {time.perf_counter() - t0:.1f} s")
    return 0
