"""make_world: the procedural world generator's entry point (dispatch by terrain).

make_world returns whole arrays; world_bands streams the same world band by band (what the
GeoTIFF writer uses, so that a large world never sits in memory twice).
"""

from __future__ import annotations

from typing import Iterator

import numpy as np

from testbench.core.errors import InputError
from testbench.world.procedural.appearance import season_from

TERRAINS = ("farmland", "grassland", "desert", "canyon", "urban")


def _terrain_class(terrain: str):
    if terrain == "farmland":
        from testbench.world.procedural.farmland import Farmland as cls
    elif terrain == "grassland":
        from testbench.world.procedural.natural import Grassland as cls
    elif terrain == "desert":
        from testbench.world.procedural.natural import Desert as cls
    elif terrain == "canyon":
        from testbench.world.procedural.canyon import Canyon as cls
    else:
        from testbench.world.procedural.urban import Urban as cls
    return cls


def world_shape(terrain: str, size_km: float, gsd_m: float) -> tuple[int, int]:
    """(H, W) pixels of a world; raises InputError on a bad terrain, size or gsd."""
    if terrain not in TERRAINS:
        raise InputError(f"terrain '{terrain}': expected one of {', '.join(TERRAINS)}")
    if not (size_km > 0 and gsd_m > 0):
        raise InputError(f"procedural world: size_km and gsd_m must be > 0 (got {size_km}, {gsd_m})")
    n = int(round(size_km * 1000.0 / gsd_m))
    if n < 16 or n > 30000:
        raise InputError(f"procedural world: {size_km} km at {gsd_m} m/px gives {n} px per side; "
                         "expected 16..30000")
    return n, n


def world_bands(terrain: str, size_km: float, gsd_m: float, seed: int, season="summer"
                ) -> Iterator[tuple[int, np.ndarray, np.ndarray]]:
    """The world of make_world as consecutive row bands: yields (r0, rgb uint8 (n, W, 3),
    z float32 (n, W)); bands are whole multiples of 256 rows (the last one excepted)."""
    from testbench.world.procedural.bands import generate

    shape = world_shape(terrain, size_km, gsd_m)
    gen = _terrain_class(terrain)(int(seed), shape, float(gsd_m), season_from(season))
    yield from generate(gen)


def make_world(terrain: str, size_km: float, gsd_m: float, seed: int, season="summer"):
    """Generate a square world centred on the origin.

    terrain: one of TERRAINS; size_km: side (km); gsd_m: metres per pixel; seed: int;
    season: summer/autumn/winter/spring or 0..3 (same layout, different appearance).
    Returns (imagery uint8 (H, W, 3) RGB, elevation float32 (H, W) m above the origin altitude,
    valid bool (H, W)); row 0 is the north edge, H = W = round(size_km * 1000 / gsd_m).
    """
    shape = world_shape(terrain, size_km, gsd_m)
    s = season_from(season)
    rgb = np.empty(shape + (3,), np.uint8)
    z = np.empty(shape, np.float32)
    for r0, band, zb in world_bands(terrain, size_km, gsd_m, seed, s):
        rgb[r0:r0 + len(band)] = band
        z[r0:r0 + len(band)] = zb
    return rgb, z, np.ones(shape, bool)
