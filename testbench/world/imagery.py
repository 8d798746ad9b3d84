"""Georeferenced imagery (`MapSource`): the RGB uint8 view of a GeoTIFF in any CRS on the
scenario's local north-east grid, read through geotiff.GeoRasterReader."""

from __future__ import annotations

import os

import numpy as np
from rasterio.enums import ColorInterp

from testbench.core.interfaces import GeodeticOrigin
from testbench.world import memo
from testbench.world.geotiff import GeoRasterReader, open_georaster
from testbench.world.raster import LocalRaster


def _rgb_bands(ds) -> tuple[list[int], bool]:
    """Band indices for R, G, B (grey replicated) and whether a rescale to uint8 is needed."""
    ci = list(ds.colorinterp)
    if ds.count >= 3:
        if ColorInterp.red in ci and ColorInterp.green in ci and ColorInterp.blue in ci:
            bands = [ci.index(ColorInterp.red) + 1, ci.index(ColorInterp.green) + 1,
                     ci.index(ColorInterp.blue) + 1]
        else:  # e.g. NAIP R, G, B, NIR with undefined interpretation
            bands = [1, 2, 3]
    else:
        bands = [1]
    return bands, ds.dtypes[0] != "uint8"


class MapSource:
    """Georeferenced imagery (GeoTIFF in any CRS) seen on the scenario's local NE grid.

    Bands: RGB uint8 out; 1-band grey is replicated to RGB; a 4th band (NIR, alpha) is
    dropped (alpha still marks nodata through the dataset mask). Non-uint8 imagery is
    stretched linearly between its 0.5 and 99.5 percentiles (from an overview read).
    """

    def __init__(self, path, origin: GeodeticOrigin, *, what: str = "map imagery"):
        # `what` names the map in error messages (e.g. the scenario key it came from).
        ds_probe = open_georaster(path, what)
        bands, rescale = _rgb_bands(ds_probe)
        ds_probe.close()
        self._reader = GeoRasterReader(path, origin, bands, what=what)
        self.path = self._reader.path
        self.origin = origin
        self._grey = len(bands) == 1
        self._stretch = self._stretch_limits() if rescale else None
        self._cache: tuple[tuple, LocalRaster] | None = None
        st = os.stat(self.path)
        self._file_id = (os.fspath(self.path), st.st_size, st.st_mtime_ns)  # a rewritten file is another map

    crs = property(lambda self: self._reader.ds.crs)
    footprint = property(lambda self: self._reader.footprint,
                         doc="Footprint: where the map lies in local NE (m).")
    native_gsd_m = property(lambda self: self._reader.native_gsd_m,
                            doc="Ground size of one source pixel near the map centre (m).")

    def _stretch_limits(self):
        ds = self._reader.ds
        k = max(1, max(ds.width, ds.height) // 512)
        a = ds.read(self._reader.bands, out_shape=(len(self._reader.bands), ds.height // k or 1,
                                                  ds.width // k or 1)).astype(np.float64)
        lo, hi = np.percentile(a, [0.5, 99.5])
        return float(lo), float(max(hi, lo + 1e-9))

    def _to_rgb8(self, data: np.ndarray) -> np.ndarray:
        if self._stretch is not None:
            lo, hi = self._stretch
            data = np.clip((data.astype(np.float32) - lo) * (255.0 / (hi - lo)) + 0.5, 0, 255)
            data = data.astype(np.uint8)
        if self._grey:
            data = np.repeat(data[..., :1], 3, axis=-1)
        return data

    def read_local(self, north_min_m: float, north_max_m: float, east_min_m: float,
                   east_max_m: float, gsd_m: float, memoise: bool = True) -> LocalRaster:
        """Imagery on the local north-up grid covering the box, at gsd_m m per pixel.

        Grid: north0_m = north_max_m, east0_m = east_min_m, height = ceil(dN/gsd),
        width = ceil(dE/gsd). data (H, W, 3) uint8 RGB; valid False off-map and at nodata.
        The last window is cached (same arguments -> same object); with the process memo on
        (world.memo) reads are kept between runs unless memoise is False (a caller that keeps
        what it derives from the read instead).
        """
        key = (north_min_m, north_max_m, east_min_m, east_max_m, gsd_m)
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        self._cache = None  # the window this read replaces need not coexist with the new one
        r = memo.cached(self.memo_key(*key) if memoise else None, lambda: self._read(key))
        self._cache = (key, r)
        return r

    def memo_key(self, north_min_m: float, north_max_m: float, east_min_m: float, east_max_m: float,
                 gsd_m: float) -> tuple:
        """What read_local's result depends on (the file as opened, the local frame, the box)."""
        o = self.origin
        return ("map", self._file_id, (o.lat_rad, o.lon_rad, o.alt_m),
                (north_min_m, north_max_m, east_min_m, east_max_m, gsd_m))

    def _read(self, key: tuple) -> LocalRaster:
        north_min_m, north_max_m, east_min_m, east_max_m, gsd_m = key
        h, w = self._reader.grid_shape(*key)
        data, valid = self._reader.read_grid(north_max_m, east_min_m, gsd_m, h, w)
        return LocalRaster(self._to_rgb8(data), valid, float(north_max_m), float(east_min_m), float(gsd_m))

    def sample(self, north_m, east_m):
        """Bilinear RGB at local points at the map's native resolution.

        Returns (rgb float64 (..., 3), valid bool (...)). Reads the source window that covers
        the points, so meant for sparse queries over a limited area.
        """
        vals, valid = self._reader.sample_points(north_m, east_m)
        if self._stretch is not None:
            lo, hi = self._stretch
            vals = np.where(valid[..., None], np.clip((vals - lo) * (255.0 / (hi - lo)), 0, 255), 0)
        if self._grey:
            vals = np.repeat(vals[..., :1], 3, axis=-1)
        return vals, valid

    def close(self) -> None:
        self._reader.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

