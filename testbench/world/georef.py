"""Local north-east frame of the scenario origin and its link to map CRSs.

Local (north_m, east_m) are the NED north/east coordinates of a point on the horizontal plane
through the origin (down = 0): the tangent plane at the origin, exactly as the vehicles' NED
positions. A map pixel is tied to it through geodetic lat/lon (WGS-84): local NE ->
ECEF -> lat/lon (testbench.core.geodesy) -> map CRS (pyproj). Earth curvature (the ground
drops ~2 m 5 km away from the origin) is not modelled in heights: terrain heights are relative
to the origin altitude.

For the procedural worlds we write GeoTIFFs in `local_tmerc_crs(origin)`, a transverse
Mercator centred on the origin with unit scale and no false origin: its x/y equal local
east/north to within millimetres over 10 km.
"""

from __future__ import annotations

import numpy as np
import pyproj

from testbench.core import geodesy
from testbench.core.errors import InputError
from testbench.core.interfaces import GeodeticOrigin

_WGS84_LONLAT = pyproj.CRS.from_epsg(4326)


def local_tmerc_crs(origin: GeodeticOrigin) -> pyproj.CRS:
    """Transverse Mercator CRS centred on the origin (x = east m, y = north m).

    Its scale factor is (R + alt) / R (R the Gaussian radius at the origin), so that distances
    match the local NED plane at the origin's altitude, not at the ellipsoid.
    """
    lat = np.degrees(origin.lat_rad)
    lon = np.degrees(origin.lon_rad)
    r_m, r_n = geodesy.radii_of_curvature(origin.lat_rad)
    k = 1.0 + origin.alt_m / float(np.sqrt(r_m * r_n))
    return pyproj.CRS.from_proj4(
        f"+proj=tmerc +lat_0={lat:.12f} +lon_0={lon:.12f} +k={k:.12f} +x_0=0 +y_0=0 "
        "+ellps=WGS84 +towgs84=0,0,0,0,0,0,0 +units=m +no_defs"
    )


class LocalFrame:
    """Maps local NE (m, tangent plane at the origin) <-> x/y of one map CRS.

    Vectorised: arrays of any shape broadcast together. Exact to floating point (no grid
    approximation here; callers interpolate on coarse grids where they need speed).
    """

    def __init__(self, origin: GeodeticOrigin, crs, where: str = "map"):
        self.origin = origin
        try:
            self.crs = pyproj.CRS.from_user_input(crs)
        except pyproj.exceptions.CRSError as exc:
            raise InputError(f"{where}: unusable CRS ({exc}); expected a projected or geographic CRS "
                             "such as EPSG:32610 or EPSG:4326") from None
        if not (self.crs.is_projected or self.crs.is_geographic):
            raise InputError(f"{where}: unusable CRS '{self.crs.name}' (neither projected nor "
                             "geographic); reproject it, e.g. gdalwarp -t_srs EPSG:XXXX in.tif out.tif")
        try:
            self._to_map = pyproj.Transformer.from_crs(_WGS84_LONLAT, self.crs, always_xy=True)
            self._to_ll = pyproj.Transformer.from_crs(self.crs, _WGS84_LONLAT, always_xy=True)
        except pyproj.exceptions.ProjError as exc:
            raise InputError(f"{where}: no transformation from WGS-84 to its CRS "
                             f"'{self.crs.name}' ({exc})") from None

    def ne_to_lonlat_deg(self, north_m, east_m):
        """Local NE (m) -> (lon_deg, lat_deg) WGS-84."""
        n, e = np.broadcast_arrays(np.asarray(north_m, float), np.asarray(east_m, float))
        pos = np.stack([n, e, np.zeros_like(n)], axis=-1)
        lat, lon, _ = geodesy.ned_to_geodetic(pos, self.origin.lat_rad, self.origin.lon_rad,
                                              self.origin.alt_m)
        return np.degrees(lon), np.degrees(lat)

    def lonlat_deg_to_ne(self, lon_deg, lat_deg):
        """(lon_deg, lat_deg) WGS-84 -> local NE (m) of the point at the origin altitude."""
        lon, lat = np.broadcast_arrays(np.asarray(lon_deg, float), np.asarray(lat_deg, float))
        ned = geodesy.geodetic_to_ned(np.radians(lat), np.radians(lon), self.origin.alt_m,
                                      self.origin.lat_rad, self.origin.lon_rad, self.origin.alt_m)
        return ned[..., 0], ned[..., 1]

    def ne_to_xy(self, north_m, east_m):
        """Local NE (m) -> map CRS (x, y) (x = easting or longitude)."""
        lon, lat = self.ne_to_lonlat_deg(north_m, east_m)
        x, y = self._to_map.transform(lon, lat)
        return np.asarray(x, float), np.asarray(y, float)

    def xy_to_ne(self, x, y):
        """Map CRS (x, y) -> local NE (m)."""
        lon, lat = self._to_ll.transform(np.asarray(x, float), np.asarray(y, float))
        return self.lonlat_deg_to_ne(lon, lat)


class GridInterpolator:
    """Bilinear upsampling of values given at every `step`-th pixel (node k at index k*step),
    served in row ranges so that a caller never needs the whole (n_rows, n_cols) grid at once.

    coarse: (nr, nc) with nr >= ceil((n_rows-1)/step)+1 and nc likewise (for instance source
    pixel coordinates at the nodes). rows(start, stop) returns rows [start, stop) of the
    (n_rows, n_cols) float32 upsampled grid, bit-identical to the same rows of interp_grid:
    every output row depends only on its own two coarse rows.
    """

    def __init__(self, coarse: np.ndarray, step: int, n_rows: int, n_cols: int):
        self.step = int(step)
        self.n_rows = int(n_rows)
        c = np.arange(n_cols) / step
        c0 = np.minimum(c.astype(np.int64), coarse.shape[1] - 2)
        fc = c - c0
        # Along columns in float64 on the few coarse rows, then rows in float32 (values are
        # pixel coordinates < 1e5: float32 keeps them to ~0.004 px). (nr, n_cols): small.
        # C order: indexing columns leaves the product column-major, and rows() reads rows.
        a = coarse[:, c0] * (1.0 - fc) + coarse[:, c0 + 1] * fc
        self._a = a.astype(np.float32, order="C")
        self._upper: np.ndarray | None = None  # scratch rows for rows(), kept across calls

    def rows(self, start: int, stop: int, out: np.ndarray | None = None) -> np.ndarray:
        """Rows [start, stop) of the upsampled grid: (stop - start, n_cols) float32.

        out: optional (stop - start, n_cols) float32 array to fill and return (a caller
        walking strips reuses one buffer instead of faulting in fresh pages per strip).
        """
        if not 0 <= start <= stop <= self.n_rows:
            raise ValueError(f"rows [{start}, {stop}) outside the grid's {self.n_rows} rows")
        a = self._a
        r = np.arange(start, stop) / self.step
        r0 = np.minimum(r.astype(np.int64), a.shape[0] - 2)
        fr = (r - r0)[:, None].astype(np.float32)
        w0 = 1.0 - fr
        shape = (stop - start, a.shape[1])
        if out is None:
            out = np.empty(shape, np.float32)
        if self._upper is None or self._upper.shape[0] < shape[0]:
            self._upper = np.empty(shape, np.float32)
        upper = self._upper[:shape[0]]
        # out = a[r0] * (1 - fr) + a[r0 + 1] * fr: the same float32 products and sum, but
        # broadcast from the two coarse rows of each run of rows sharing r0 (at most `step`
        # long) rather than gathered into full-size copies first.
        cuts = np.flatnonzero(np.diff(r0)) + 1
        for i0, i1 in zip(np.r_[0, cuts], np.r_[cuts, len(r0)]) if len(r0) else ():
            k = r0[i0]
            np.multiply(a[k], w0[i0:i1], out=out[i0:i1])
            np.multiply(a[k + 1], fr[i0:i1], out=upper[i0:i1])
        out += upper
        return out


def interp_grid(coarse: np.ndarray, step: int, n_rows: int, n_cols: int) -> np.ndarray:
    """Bilinear upsampling of values given at every `step`-th pixel (node k at index k*step).

    coarse: (nr, nc) with nr >= ceil((n_rows-1)/step)+1 and nc likewise; returns (n_rows,
    n_cols) float32. Exact float interpolation (cv2.remap would quantise weights to 1/32).
    For large grids use GridInterpolator.rows on row strips (same values, bounded memory).
    """
    return GridInterpolator(coarse, step, n_rows, n_cols).rows(0, n_rows)
