"""World sources named in scenarios: a GeoTIFF path or a `procedural:` spec.

    procedural:farmland?seed=7&season=summer&size_km=6&gsd_m=1

Optional `sun_azimuth_deg` (from north, clockwise) and `sun_elevation_deg` put the sun where
the season's table does not (imagery of the same season taken at another date or hour: the
shadows and hillshade move, nothing else does).

generates the world (imagery.tif + elevation.tif, georeferenced at the scenario origin) once
into a cache folder keyed by the spec AND the origin, so that several vehicles and runs reuse
it. Files are written to temporary names and renamed: a reader never sees a partial file.
Cache root: `cache_dir`, else $TESTBENCH_CACHE, else ~/.cache/testbench/worlds.
"""

from __future__ import annotations

import dataclasses
import hashlib
import logging
import math
import os
from dataclasses import dataclass
from urllib.parse import parse_qsl

from testbench.core.errors import InputError
from testbench.core.interfaces import GeodeticOrigin

log = logging.getLogger(__name__)

PREFIX = "procedural:"
_KEYS = {"seed": int, "season": str, "size_km": float, "gsd_m": float, "sun_azimuth_deg": float,
         "sun_elevation_deg": float}
_DEFAULTS = {"seed": 0, "season": "summer", "size_km": 6.0, "gsd_m": 1.0, "sun_azimuth_deg": None,
             "sun_elevation_deg": None}


@dataclass(frozen=True)
class ProceduralSpec:
    """A parsed `procedural:` world spec."""

    terrain: str
    seed: int = 0
    season: str = "summer"
    size_km: float = 6.0
    gsd_m: float = 1.0
    sun_azimuth_deg: float | None = None  # None: the season's
    sun_elevation_deg: float | None = None

    def canonical(self) -> str:
        # The sun only when given, so that the season's own worlds keep their names and caches.
        sun = "".join(f"&{k}={v:g}" for k, v in (("sun_azimuth_deg", self.sun_azimuth_deg),
                                                  ("sun_elevation_deg", self.sun_elevation_deg)) if v is not None)
        return (f"{PREFIX}{self.terrain}?seed={self.seed}&season={self.season}"
                f"&size_km={self.size_km:g}&gsd_m={self.gsd_m:g}{sun}")

    def appearance(self):
        """The Season to generate with: the season's table, its sun replaced where given."""
        from testbench.world.procedural import season_from

        s = season_from(self.season)
        if self.sun_azimuth_deg is not None:
            s = dataclasses.replace(s, sun_azimuth_rad=math.radians(self.sun_azimuth_deg))
        if self.sun_elevation_deg is not None:
            s = dataclasses.replace(s, sun_elevation_rad=math.radians(self.sun_elevation_deg))
        return s


def is_procedural(spec) -> bool:
    return isinstance(spec, str) and spec.strip().startswith(PREFIX)


def parse_spec(spec: str) -> ProceduralSpec:
    """Parse 'procedural:TERRAIN?key=value&...' (keys: seed, season, size_km, gsd_m,
    sun_azimuth_deg, sun_elevation_deg)."""
    from testbench.world.procedural import TERRAINS, season_from

    body = spec.strip()[len(PREFIX):]
    terrain, _, query = body.partition("?")
    terrain = terrain.strip().lower()
    if terrain not in TERRAINS:
        raise InputError(f"world '{spec}': unknown terrain '{terrain}', expected one of "
                         f"{', '.join(TERRAINS)}")
    vals = dict(_DEFAULTS)
    for k, v in parse_qsl(query, keep_blank_values=True):
        if k not in _KEYS:
            raise InputError(f"world '{spec}': unknown key '{k}', expected {', '.join(_KEYS)}")
        try:
            vals[k] = _KEYS[k](v)
        except ValueError:
            raise InputError(f"world '{spec}': {k}={v!r} is not a {_KEYS[k].__name__}") from None
    vals["season"] = season_from(vals["season"]).name
    if not (vals["size_km"] > 0 and vals["gsd_m"] > 0):
        raise InputError(f"world '{spec}': size_km and gsd_m must be > 0")
    el = vals["sun_elevation_deg"]
    if el is not None and not 0.0 < el <= 90.0:
        raise InputError(f"world '{spec}': sun_elevation_deg={el:g} must be in (0, 90] degrees above the horizon")
    return ProceduralSpec(terrain, **vals)


def default_cache_dir() -> str:
    return os.environ.get("TESTBENCH_CACHE") or os.path.join(
        os.path.expanduser("~"), ".cache", "testbench", "worlds")


def world_dir(spec: ProceduralSpec, origin: GeodeticOrigin, cache_dir=None) -> str:
    """Cache folder of a spec at an origin (name readable, hash for the exact key)."""
    key = f"{spec.canonical()}|{origin.lat_rad:.12f}|{origin.lon_rad:.12f}|{origin.alt_m:.4f}|v2"
    h = hashlib.sha256(key.encode()).hexdigest()[:12]
    name = f"{spec.terrain}-seed{spec.seed}-{spec.season}-{spec.size_km:g}km-{spec.gsd_m:g}m-{h}"
    return os.path.join(os.fspath(cache_dir) if cache_dir else default_cache_dir(), name)


def ensure_world(spec: ProceduralSpec, origin: GeodeticOrigin, cache_dir=None) -> tuple[str, str]:
    """Generate the world files if absent; returns (imagery_path, elevation_path)."""
    from testbench.world.procedural.writer import write_world_streamed

    d = world_dir(spec, origin, cache_dir)
    img, dem = os.path.join(d, "imagery.tif"), os.path.join(d, "elevation.tif")
    if os.path.exists(img) and os.path.exists(dem):
        return img, dem
    log.info("generating procedural world %s into %s", spec.canonical(), d)
    # Band by band: a large world never sits whole in memory (files appear atomically).
    write_world_streamed(d, spec.terrain, spec.size_km, spec.gsd_m, spec.seed, spec.appearance(), origin)
    return img, dem


def _resolve(path: str, base_dir) -> str:
    p = os.path.expandvars(os.path.expanduser(path))
    if base_dir and not os.path.isabs(p):
        p = os.path.join(base_dir, p)
    return p


def open_world_imagery(spec_or_path, origin: GeodeticOrigin, cache_dir=None, base_dir=None,
                       what: str = "map imagery"):
    """MapSource for a GeoTIFF path or a `procedural:` spec (generated and cached); `what`
    names it in error messages (e.g. 'world.reference_map')."""
    from testbench.world.imagery import MapSource

    if is_procedural(spec_or_path):
        img, _ = ensure_world(parse_spec(spec_or_path), origin, cache_dir)
        return MapSource(img, origin, what=what)
    return MapSource(_resolve(os.fspath(spec_or_path), base_dir), origin, what=what)


def open_elevation(spec_or_path, origin: GeodeticOrigin, cache_dir=None, base_dir=None,
                   what: str = "elevation"):
    """ElevationModel for a DEM path or a `procedural:` spec; FlatElevation for None/'flat'.

    'flat:H' gives flat ground H m above the origin altitude. `what` names it in error
    messages (e.g. 'world.reference_elevation').
    """
    from testbench.world.elevation import ElevationModel, FlatElevation

    if spec_or_path is None:
        return FlatElevation(0.0)
    flat = spec_or_path.strip().lower() if isinstance(spec_or_path, str) else ""
    if flat == "flat" or flat.startswith("flat:"):  # not a file named flat...
        _, _, hs = spec_or_path.partition(":")
        try:
            height_m = float(hs) if hs.strip() else 0.0
        except ValueError:
            height_m = math.nan
        if not math.isfinite(height_m):
            raise InputError(f"{what} '{spec_or_path}': expected 'flat' or 'flat:HEIGHT_M' (a finite height in "
                             "metres above the origin's altitude)")
        return FlatElevation(height_m)
    if is_procedural(spec_or_path):
        _, dem = ensure_world(parse_spec(spec_or_path), origin, cache_dir)
        return ElevationModel(dem, origin, what=what)
    return ElevationModel(_resolve(os.fspath(spec_or_path), base_dir), origin, what=what)
