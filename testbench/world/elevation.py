"""Terrain elevation on the local grid: a DEM GeoTIFF in any CRS, or flat ground.

Heights are metres ABOVE THE SCENARIO ORIGIN'S ALTITUDE (up positive): DEM value minus
origin.alt_m. The testbench treats mean sea level as the WGS-84 ellipsoid (DESIGN.md), so a DEM
in metres above sea level and an origin altitude in metres compare directly. A point at local
(north, east) on the terrain has NED down = -height_m(north, east) (Earth curvature ignored).
"""

from __future__ import annotations

import math
from collections import OrderedDict

import numpy as np
from rasterio.enums import Resampling

from testbench.core.errors import InputError
from testbench.core.interfaces import GeodeticOrigin
from testbench.world.geotiff import GeoRasterReader
from testbench.world.raster import LocalRaster, sample_bilinear, sample_bilinear_point

_TILE_PX = 256


class FlatElevation:
    """Flat ground at `height_m` above the origin altitude (the default world)."""

    def __init__(self, height_m: float = 0.0):
        self.height = float(height_m)
        self.footprint = None
        self.native_gsd_m = None

    def height_m(self, north_m, east_m) -> np.ndarray:
        """Height (m above origin altitude), shape of the broadcast inputs."""
        n, _ = np.broadcast_arrays(np.asarray(north_m, float), np.asarray(east_m, float))
        return np.full(n.shape, self.height)

    def height_and_valid(self, north_m, east_m):
        h = self.height_m(north_m, east_m)
        return h, np.ones(h.shape, bool)

    def height_at(self, north_m: float, east_m: float) -> float:
        """height_m at one point (m above the origin altitude)."""
        return self.height

    def read_local(self, north_min_m, north_max_m, east_min_m, east_max_m, gsd_m) -> LocalRaster:
        """Constant float32 grid (same grid convention as MapSource.read_local)."""
        h = max(1, int(np.ceil((north_max_m - north_min_m) / gsd_m - 1e-9)))
        w = max(1, int(np.ceil((east_max_m - east_min_m) / gsd_m - 1e-9)))
        return LocalRaster(np.full((h, w), self.height, np.float32), np.ones((h, w), bool),
                           float(north_max_m), float(east_min_m), float(gsd_m))

    def close(self) -> None:
        pass


class ElevationModel:
    """A DEM GeoTIFF (int16 with nodata, float32, any CRS) on the local NE grid.

    height_m: bilinear at the DEM's native resolution through a small cache of local tiles
    (256 x 256 native pixels), so per-tick queries are cheap and a large DEM is never loaded
    whole. Off the DEM or at nodata the height is `outside_height_m` (default 0: flat at the
    origin altitude); height_and_valid tells which points had data.
    """

    def __init__(self, path, origin: GeodeticOrigin, *, outside_height_m: float = 0.0,
                 band: int = 1, max_tiles: int = 64, what: str = "elevation"):
        self._reader = GeoRasterReader(path, origin, [band], what=what,
                                       resampling=Resampling.average)
        if np.dtype(self._reader.ds.dtypes[band - 1]).kind not in "iuf":
            raise InputError(f"{what} '{self._reader.path}': band {band} is not numeric")
        self.path = self._reader.path
        self.origin = origin
        self.outside_height_m = float(outside_height_m)
        self._tiles: OrderedDict[tuple[int, int], LocalRaster] = OrderedDict()
        self._max_tiles = max_tiles
        self._cache: tuple[tuple, LocalRaster] | None = None

    footprint = property(lambda self: self._reader.footprint)
    native_gsd_m = property(lambda self: self._reader.native_gsd_m)

    def read_local(self, north_min_m, north_max_m, east_min_m, east_max_m, gsd_m) -> LocalRaster:
        """Heights (H, W) float32, m above the origin altitude, on the local north-up grid.

        Same grid as MapSource.read_local (north0 = north_max_m, east0 = east_min_m). Invalid
        pixels hold outside_height_m.
        """
        key = (north_min_m, north_max_m, east_min_m, east_max_m, gsd_m)
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        h, w = self._reader.grid_shape(*key)
        data, valid = self._reader.read_grid(north_max_m, east_min_m, gsd_m, h, w)
        z = data[..., 0].astype(np.float32) - np.float32(self.origin.alt_m)
        z[~valid] = self.outside_height_m
        r = LocalRaster(z, valid, float(north_max_m), float(east_min_m), float(gsd_m))
        self._cache = (key, r)
        return r

    def _tile(self, key: tuple[int, int]) -> LocalRaster:
        t = self._tiles.get(key)
        if t is None:
            g = self.native_gsd_m
            size = _TILE_PX * g
            # One pixel of overlap on every side so bilinear never straddles two tiles.
            n_max = -key[0] * size + g
            e_min = key[1] * size - g
            t = self.read_local(n_max - size - 2 * g, n_max, e_min, e_min + size + 2 * g, g)
            self._tiles[key] = t
            if len(self._tiles) > self._max_tiles:
                self._tiles.popitem(last=False)
        else:
            self._tiles.move_to_end(key)
        return t

    def height_and_valid(self, north_m, east_m):
        """(height m above origin altitude float64, valid bool), shape of the broadcast inputs."""
        n, e = np.broadcast_arrays(np.asarray(north_m, float), np.asarray(east_m, float))
        size = _TILE_PX * self.native_gsd_m
        ti = np.floor(-n / size).astype(np.int64)
        tj = np.floor(e / size).astype(np.int64)
        if n.size and (ti == ti.flat[0]).all() and (tj == tj.flat[0]).all():
            # All in one tile (a sensor's footprint, a beam): no sort into tiles.
            v, good = sample_bilinear(self._tile((int(ti.flat[0]), int(tj.flat[0]))), n, e)
            return np.where(good, v, self.outside_height_m), good
        out = np.full(n.shape, self.outside_height_m)
        ok = np.zeros(n.shape, bool)
        keys = np.stack([ti.ravel(), tj.ravel()], axis=1)
        uniq, inv = np.unique(keys, axis=0, return_inverse=True)
        inv = inv.reshape(n.shape)
        for k, (a, b) in enumerate(uniq):
            sel = inv == k
            v, good = sample_bilinear(self._tile((int(a), int(b))), n[sel], e[sel])
            out[sel] = np.where(good, v, self.outside_height_m)
            ok[sel] = good
        return out, ok

    def height_m(self, north_m, east_m) -> np.ndarray:
        """Terrain height (m above the origin altitude) at local NE points, bilinear."""
        return self.height_and_valid(north_m, east_m)[0]

    def height_at(self, north_m: float, east_m: float) -> float:
        """height_m at one point (m above the origin altitude), the same value bit for bit,
        without numpy's per-call cost (the dynamics' terrain under a vehicle at every step).
        A non-finite point is off the DEM: outside_height_m."""
        n, e = float(north_m), float(east_m)
        if not (math.isfinite(n) and math.isfinite(e)):
            return self.outside_height_m
        size = _TILE_PX * self.native_gsd_m
        v, good = sample_bilinear_point(self._tile((math.floor(-n / size), math.floor(e / size))), n, e)
        return v if good else self.outside_height_m

    def close(self) -> None:
        self._reader.close()
