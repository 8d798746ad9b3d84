"""make_world: the procedural world generator's entry point (dispatch by terrain)."""

from __future__ import annotations

import numpy as np

from testbench.core.errors import InputError
from testbench.world.procedural.appearance import season_from

TERRAINS = ("farmland", "grassland", "desert", "canyon", "urban")


def make_world(terrain: str, size_km: float, gsd_m: float, seed: int, season="summer"):
    """Generate a square world centred on the origin.

    terrain: one of TERRAINS; size_km: side (km); gsd_m: metres per pixel; seed: int;
    season: summer/autumn/winter/spring or 0..3 (same layout, different appearance).
    Returns (imagery uint8 (H, W, 3) RGB, elevation float32 (H, W) m above the origin altitude,
    valid bool (H, W)); row 0 is the north edge, H = W = round(size_km * 1000 / gsd_m).
    """
    if terrain not in TERRAINS:
        raise InputError(f"terrain '{terrain}': expected one of {', '.join(TERRAINS)}")
    if not (size_km > 0 and gsd_m > 0):
        raise InputError(f"procedural world: size_km and gsd_m must be > 0 (got {size_km}, {gsd_m})")
    n = int(round(size_km * 1000.0 / gsd_m))
    if n < 16 or n > 30000:
        raise InputError(f"procedural world: {size_km} km at {gsd_m} m/px gives {n} px per side; "
                         "expected 16..30000")
    s = season_from(season)
    shape = (n, n)
    if terrain == "farmland":
        from testbench.world.procedural.farmland import make_farmland as fn
    elif terrain == "grassland":
        from testbench.world.procedural.natural import make_grassland as fn
    elif terrain == "desert":
        from testbench.world.procedural.natural import make_desert as fn
    elif terrain == "canyon":
        from testbench.world.procedural.canyon import make_canyon as fn
    else:
        from testbench.world.procedural.urban import make_urban as fn
    rgb, z, valid = fn(int(seed), shape, float(gsd_m), s)
    return rgb, np.ascontiguousarray(z, dtype=np.float32), valid
