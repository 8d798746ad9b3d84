"""Georeferenced rasters (GeoTIFF, any CRS) read onto the scenario's local north-east grid.

`GeoRasterReader` is the shared machinery (open + checks, windowed/decimated reads, reprojection
onto a `LocalRaster`); its views are `MapSource` (imagery, RGB uint8) in imagery.py and
`ElevationModel` in elevation.py. Only windows are ever read: coarse output grids are read decimated through
`out_shape` (GDAL then uses the file's overviews), so a 10 km x 10 km map at 1 m never sits in
memory.

Pixel convention of the source: rasterio's affine maps (col, row) of pixel CORNERS; the centre
of pixel (r, c) is transform * (c + 0.5, r + 0.5). Internally we use continuous source pixel
coordinates with centres at integers, as the LocalRaster grid does.
"""

from __future__ import annotations

import contextlib
import logging
import os
from dataclasses import dataclass

import cv2
import numpy as np
import rasterio
from rasterio.enums import ColorInterp, MaskFlags, Resampling
from rasterio.windows import Window

from testbench.core.errors import InputError
from testbench.core.interfaces import GeodeticOrigin
from testbench.world.georef import GridInterpolator, LocalFrame
from testbench.world.raster import LocalRaster, bilinear_at_rowcol

log = logging.getLogger(__name__)

_NODE_STEP = 32  # output pixels between exactly transformed grid nodes
_MAX_CV_SIZE = 32000  # cv2.remap needs sizes below SHRT_MAX
# Output pixels reprojected at once: the float32 coordinate maps and remap temporaries of a
# strip stay at a few tens of MB whatever the window (a 7000 x 7000 window at once needed
# ~1 GB of them), and they stay in the CPU caches.
_STRIP_PX = 1 << 20
# GDAL's block cache while reading windows (bytes). Its default (5 % of RAM) only keeps a
# second copy of the blocks of the last windows: every window read here is read once and kept
# by the caller (world, map cache), so a few rows of 256 px tiles are all GDAL needs.
# An explicit GDAL_CACHEMAX in the environment wins.
_GDAL_CACHE_BYTES = 64 << 20


@dataclass(frozen=True)
class Footprint:
    """Where a map lies in local NE (m): its 4 corners and their bounding box."""

    corners_ne_m: np.ndarray  # (4, 2) north, east of the NW, NE, SE, SW image corners
    north_min_m: float
    north_max_m: float
    east_min_m: float
    east_max_m: float


def open_georaster(path: str | os.PathLike, what: str) -> rasterio.io.DatasetReader:
    """Open `path` with rasterio and check it is georeferenced; InputError otherwise."""
    path = os.fspath(path)
    if not os.path.exists(path):
        raise InputError(f"{what} '{path}': no such file")
    try:
        ds = rasterio.open(path)
    except rasterio.errors.RasterioIOError as exc:
        raise InputError(f"{what} '{path}': not a readable raster ({exc})") from None
    if ds.crs is None or ds.transform.is_identity:
        gcps = " (it has only GCPs: warp it with gdalwarp -t_srs EPSG:XXXX first)" if ds.gcps[0] else ""
        ds.close()
        raise InputError(
            f"{what} '{path}': no georeference{gcps}; add a world file (.tfw) and .aux.xml / .prj "
            f"with the CRS, or run `gdal_translate -a_srs EPSG:XXXX -a_ullr ULX ULY LRX LRY in.tif out.tif`"
        )
    if abs(ds.transform.b) > 0 or abs(ds.transform.d) > 0:
        log.info("%s has a rotated/sheared geotransform; handled by the general reprojection", path)
    return ds


def map_centre_lat_lon_deg(path: str | os.PathLike, what: str = "map") -> tuple[float, float]:
    """(lat, lon) degrees of the centre of a georeferenced raster's bounds (InputError when it
    is missing, unreadable or not georeferenced): the local origin tools put on a map."""
    from pyproj import Transformer

    with open_georaster(path, what) as ds:
        x, y = (ds.bounds.left + ds.bounds.right) / 2, (ds.bounds.bottom + ds.bounds.top) / 2
        lon, lat = Transformer.from_crs(ds.crs, "EPSG:4326", always_xy=True).transform(x, y)
    return lat, lon


class GeoRasterReader:
    """One georeferenced raster, read in windows onto local north-up grids.

    bands: 1-based band indices to read (in output order). resampling: used when reading
    decimated (coarse output grids). The dataset stays open (rasterio handle) until close().
    """

    def __init__(self, path, origin: GeodeticOrigin, bands: list[int], *, what: str,
                 resampling: Resampling = Resampling.average):
        self.path = os.fspath(path)
        self.origin = origin
        self.what = what
        self.ds = open_georaster(path, what)
        self.frame = LocalFrame(origin, self.ds.crs, where=f"{what} '{self.path}'")
        self.bands = bands
        self.resampling = resampling
        self.footprint = self._footprint()
        self.native_gsd_m = self._native_gsd()
        dist = float(np.hypot(0.5 * (self.footprint.north_min_m + self.footprint.north_max_m),
                              0.5 * (self.footprint.east_min_m + self.footprint.east_max_m)))
        if dist > 200e3:
            log.warning("%s '%s' lies %.0f km from the scenario origin: the local tangent plane "
                        "is a poor approximation there", what, self.path, dist / 1e3)

    # -- geometry -------------------------------------------------------------------------
    def _footprint(self) -> Footprint:
        h, w = self.ds.height, self.ds.width
        # Sample the border densely: the edges are not straight lines in local NE.
        t = np.linspace(0.0, 1.0, 33)
        cols = np.concatenate([t * w, np.full_like(t, w), (1 - t) * w, np.zeros_like(t)])
        rows = np.concatenate([np.zeros_like(t), t * h, np.full_like(t, h), (1 - t) * h])
        xs, ys = _apply(self.ds.transform, cols, rows)
        n, e = self.frame.xy_to_ne(xs, ys)
        k = len(t)
        corners = np.stack([n[[0, k, 2 * k, 3 * k]], e[[0, k, 2 * k, 3 * k]]], axis=-1)
        return Footprint(corners, float(n.min()), float(n.max()), float(e.min()), float(e.max()))

    def _native_gsd(self) -> float:
        """Mean ground size (m) of one source pixel near the map centre."""
        h, w = self.ds.height, self.ds.width
        cols = np.array([w / 2, w / 2 + 1, w / 2])
        rows = np.array([h / 2, h / 2, h / 2 + 1])
        xs, ys = _apply(self.ds.transform, cols, rows)
        n, e = self.frame.xy_to_ne(xs, ys)
        dx = np.hypot(n[1] - n[0], e[1] - e[0])
        dy = np.hypot(n[2] - n[0], e[2] - e[0])
        return float(np.sqrt(dx * dy))

    def ne_to_src_colrow(self, north_m, east_m):
        """Local NE (m) -> continuous source (col, row), pixel centres at integers."""
        x, y = self.frame.ne_to_xy(north_m, east_m)
        col, row = _apply(~self.ds.transform, x, y)
        return np.asarray(col) - 0.5, np.asarray(row) - 0.5

    # -- reading --------------------------------------------------------------------------
    def _reading(self):
        """Context for window reads: GDAL's block cache bounded to _GDAL_CACHE_BYTES."""
        if "GDAL_CACHEMAX" in os.environ:
            return contextlib.nullcontext()
        return rasterio.Env(GDAL_CACHEMAX=_GDAL_CACHE_BYTES)

    def _all_valid(self) -> bool:
        """True when GDAL reports every band fully valid (no nodata, mask or alpha band):
        dataset_mask would then be 255 everywhere, so it need not be read."""
        return (ColorInterp.alpha not in self.ds.colorinterp
                and all(MaskFlags.all_valid in flags for flags in self.ds.mask_flag_enums))

    def read_grid(self, north0_m: float, east0_m: float, gsd_m: float, height: int, width: int):
        """Reproject onto the local grid with NW corner (north0_m, east0_m), `gsd_m` m/px.

        Returns (data, valid): data (height, width, len(bands)) in the source dtype, valid
        (height, width) bool (False off-map and at nodata; data 0 there).

        Memory: the source window (decimated to about gsd_m), the outputs, and per strip of
        _STRIP_PX output pixels the float32 source coordinates and remap temporaries.
        """
        if height > _MAX_CV_SIZE or width > _MAX_CV_SIZE:
            raise InputError(f"{self.what} '{self.path}': requested window {height}x{width} px is "
                             f"too large; use a coarser gsd_m")
        step = _NODE_STEP
        nr = max(2, -(-(height - 1) // step) + 1)
        nc = max(2, -(-(width - 1) // step) + 1)
        rr = np.arange(nr) * step
        cc = np.arange(nc) * step
        north = north0_m - (rr[:, None] + 0.5) * gsd_m
        east = east0_m + (cc[None, :] + 0.5) * gsd_m
        col_n, row_n = self.ne_to_src_colrow(north, east)
        # Source pixels per output pixel: choose the decimation of the read.
        dc = np.hypot(np.diff(col_n, axis=1), np.diff(row_n, axis=1)).mean() / step
        dr = np.hypot(np.diff(col_n, axis=0), np.diff(row_n, axis=0)).mean() / step
        factor = max(1, int(np.floor(min(dc, dr))))
        margin = 2 + factor
        c_lo = int(np.floor(col_n.min())) - margin
        c_hi = int(np.ceil(col_n.max())) + margin + 1
        r_lo = int(np.floor(row_n.min())) - margin
        r_hi = int(np.ceil(row_n.max())) + margin + 1
        c_lo, r_lo = max(c_lo, 0), max(r_lo, 0)
        c_hi, r_hi = min(c_hi, self.ds.width), min(r_hi, self.ds.height)
        nb = len(self.bands)
        dtype = self.ds.dtypes[self.bands[0] - 1]
        if c_hi - c_lo < 2 or r_hi - r_lo < 2:  # entirely off the map
            return np.zeros((height, width, nb), dtype=dtype), np.zeros((height, width), bool)
        win = Window(c_lo, r_lo, c_hi - c_lo, r_hi - r_lo)
        out_h = max(2, -(-win.height // factor))
        out_w = max(2, -(-win.width // factor))
        if max(out_h, out_w) > _MAX_CV_SIZE:
            raise InputError(f"{self.what} '{self.path}': window too large for one read; "
                             "use a coarser gsd_m or a smaller window")
        sx, sy = win.width / out_w, win.height / out_h
        # Source centre coordinates -> coordinates in the (decimated) window array.
        win_c = (col_n - c_lo + 0.5) / sx - 0.5
        win_r = (row_n - r_lo + 0.5) / sy - 0.5
        # uint8 only: cv2 remaps 8-bit data at coordinates rounded to 1/32 px, but float data at
        # the exact float coordinates, so a node 3e-6 px off its pixel already moves a height.
        shift = _integer_shift(win_c, win_r, cc, rr) if np.dtype(dtype) == np.uint8 else None
        src, mask = self._read_window(win, out_h, out_w, dtype)
        if shift is not None:
            # The grid is the window's own pixels (a map written on this local grid, read at
            # its gsd): remap would return them unchanged, so copy them instead (nodata needs
            # no fill there: the copy zeroes what the mask marks invalid).
            return _shifted_copy(src, mask, shift, (height, width, nb))
        if mask is not None:
            bad = mask == 0
            if bad.any() and not bad.all():
                # Fill nodata with the window mean so that it cannot leak into valid pixels
                # through bilinear weights (-32767 times a tiny weight is still a cliff).
                _fill(src, bad)
            del bad
        out = np.empty((height, width, nb), dtype=dtype)
        valid = np.empty((height, width), bool)
        grid_c = GridInterpolator(win_c, step, height, width)
        grid_r = GridInterpolator(win_r, step, height, width)
        # Strip by strip: cv2.remap computes every output pixel from its own map values only,
        # so strips give exactly the pixels of one whole-window remap.
        rows = max(1, _STRIP_PX // width)
        buf_c = np.empty((min(rows, height), width), np.float32)
        buf_r = np.empty_like(buf_c)
        for y0 in range(0, height, rows):
            y1 = min(height, y0 + rows)
            map_c = grid_c.rows(y0, y1, out=buf_c[:y1 - y0])
            map_r = grid_r.rows(y0, y1, out=buf_r[:y1 - y0])
            o = out[y0:y1]
            _remap(src, map_c, map_r, o)
            v = valid[y0:y1]
            if mask is None:
                v[...] = _inside(out_h, out_w, map_c, map_r)
            else:
                m = cv2.remap(mask, map_c, map_r, cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=0)
                np.greater_equal(m, 250, out=v)  # every neighbour with weight >= 1/32 valid
            if not v.all():
                o[~v] = 0
        return out, valid

    def _read_window(self, win: Window, out_h: int, out_w: int, dtype):
        """Source window read at (out_h, out_w) px (decimated with self.resampling when smaller).

        Returns (src, mask): src (out_h, out_w, nb) C-contiguous (cv2 layout, read in place:
        no band-first copy) or, for more than 4 bands, (nb, out_h, out_w) (one cv2 plane per
        band); mask (out_h, out_w) uint8 dataset mask, or None when every pixel is valid.
        """
        nb = len(self.bands)
        decimate = (out_h, out_w) != (win.height, win.width)
        if nb <= 4:
            src = np.empty((out_h, out_w, nb), dtype=dtype)
            dst = np.moveaxis(src, -1, 0)  # a band-first view GDAL fills through its strides
        else:
            src = dst = np.empty((nb, out_h, out_w), dtype=dtype)
        with self._reading():
            if decimate:
                self.ds.read(self.bands, window=win, out=dst, resampling=self.resampling)
            else:
                self.ds.read(self.bands, window=win, out=dst)
            if self._all_valid():
                return src, None
            if decimate:
                mask = self.ds.dataset_mask(window=win, out_shape=(out_h, out_w),
                                            resampling=Resampling.nearest)
            else:
                mask = self.ds.dataset_mask(window=win)
        return src, mask

    def sample_points(self, north_m, east_m):
        """Bilinear source values at local points, native resolution, exact float weights.

        Returns (values float64 (..., n_bands), valid bool (...)). Reads the one source window
        that covers all the points (sparse queries over a limited area).
        """
        n, e = np.broadcast_arrays(np.asarray(north_m, float), np.asarray(east_m, float))
        nb = len(self.bands)
        out = np.zeros(n.shape + (nb,))
        ok = np.zeros(n.shape, bool)
        col, row = self.ne_to_src_colrow(n, e)
        fin = np.isfinite(col) & np.isfinite(row)
        fin &= (col > -1) & (row > -1) & (col < self.ds.width) & (row < self.ds.height)
        if not fin.any():
            return out, ok
        c_lo = max(int(np.floor(col[fin].min())), 0)
        r_lo = max(int(np.floor(row[fin].min())), 0)
        c_hi = min(int(np.floor(col[fin].max())) + 2, self.ds.width)
        r_hi = min(int(np.floor(row[fin].max())) + 2, self.ds.height)
        win = Window(c_lo, r_lo, c_hi - c_lo, r_hi - r_lo)
        with self._reading():
            src = np.moveaxis(self.ds.read(self.bands, window=win), 0, -1)
            if self._all_valid():
                mask = np.ones(src.shape[:2], bool)
            else:
                mask = self.ds.dataset_mask(window=win) > 0
        vals, valid = bilinear_at_rowcol(src, mask, np.where(fin, row - r_lo, -1.0),
                                         np.where(fin, col - c_lo, -1.0))
        return vals, valid

    def grid_shape(self, north_min_m, north_max_m, east_min_m, east_max_m, gsd_m):
        """(height, width) of the local grid covering the box at gsd_m (rounded, >= 1)."""
        if not gsd_m > 0:
            raise InputError(f"{self.what}: gsd_m must be > 0, got {gsd_m}")
        if not (north_max_m > north_min_m and east_max_m > east_min_m):
            raise InputError(f"{self.what}: empty window north [{north_min_m}, {north_max_m}] "
                             f"east [{east_min_m}, {east_max_m}]")
        h = max(1, int(np.ceil((north_max_m - north_min_m) / gsd_m - 1e-9)))
        w = max(1, int(np.ceil((east_max_m - east_min_m) / gsd_m - 1e-9)))
        return h, w

    def close(self) -> None:
        self.ds.close()


def _apply(t, a, b):
    """Affine t applied to arrays (a, b) -> (x, y)."""
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    return t.a * a + t.b * b + t.c, t.d * a + t.e * b + t.f


def _remap(src: np.ndarray, map_c: np.ndarray, map_r: np.ndarray, dst: np.ndarray) -> None:
    """cv2.remap (bilinear, constant 0 border) of a _read_window source into dst (h, w, nb).

    src: (H, W, nb) for nb <= 4 (one cv2 call), else (nb, H, W) planes (cv2 takes <= 4
    channels); map_c, map_r (h, w) float32 source column, row; dst: C-contiguous.
    """
    kw = dict(interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    if src.ndim == 3 and src.shape[2] <= 4:
        # cv2 writes into dst when its shape and type fit (no fresh (h, w, nb) array per strip)
        r = cv2.remap(src, map_c, map_r, dst=dst, **kw)
        if not np.shares_memory(r, dst):
            dst[...] = r.reshape(dst.shape)
        return
    for i, plane in enumerate(src):
        dst[..., i] = cv2.remap(plane, map_c, map_r, **kw)


# Largest distance (px) of a grid node from a whole-pixel translation for _integer_shift to take
# it as one. cv2.remap rounds the coordinates of 8-bit data to 1/32 px, so anything within 1/64
# of a whole pixel reads that pixel alone (weight 1, its neighbour 0); 1e-3 px also leaves room
# for the float32 rounding (< 0.004 px below 1e5) of the maps the node interpolation makes.
_SHIFT_TOL_PX = 1e-3


def _integer_shift(win_c: np.ndarray, win_r: np.ndarray, cc: np.ndarray, rr: np.ndarray) -> tuple[int, int] | None:
    """(dc, dr) when the output grid is the window's pixel grid shifted by whole pixels: window
    column win_c = dc + output column cc and row win_r = dr + output row rr at every node, to
    _SHIFT_TOL_PX; None otherwise. win_c, win_r: (nr, nc) window coordinates of the nodes at
    output rows rr (nr,) and columns cc (nc,). Bilinear interpolation between nodes keeps such a
    translation, so what holds at the nodes holds at every pixel."""
    dc = float(np.rint(win_c[0, 0] - cc[0]))
    dr = float(np.rint(win_r[0, 0] - rr[0]))
    if (np.abs(win_c - (cc[None, :] + dc)).max() > _SHIFT_TOL_PX
            or np.abs(win_r - (rr[:, None] + dr)).max() > _SHIFT_TOL_PX):
        return None
    return int(dc), int(dr)


def _shifted_copy(src: np.ndarray, mask: np.ndarray | None, shift: tuple[int, int],
                  shape: tuple[int, int, int]) -> tuple[np.ndarray, np.ndarray]:
    """What _remap and the validity of read_grid give on a whole-pixel shift, by copying: (out
    (h, w, nb) in src's dtype, valid (h, w) bool) for shape (h, w, nb), out[y, x] = window pixel
    (y + dr, x + dc) and valid there (mask >= 250 where a mask is given); 0 and invalid off the
    window (cv2's constant-0 border, the neighbour of weight 0 ignored). src: a _read_window
    source ((H, W, nb), or (nb, H, W) planes for nb > 4)."""
    dc, dr = shift
    h, w, nb = shape
    planes = nb > 4  # _read_window's layout for more than 4 bands
    hs, ws = src.shape[1:] if planes else src.shape[:2]
    # Zeroed pages from the allocator: only the copied rectangle is written.
    out = np.zeros(shape, src.dtype)
    valid = np.zeros((h, w), bool)
    y0, y1 = max(0, -dr), min(h, hs - dr)
    x0, x1 = max(0, -dc), min(w, ws - dc)
    if y1 <= y0 or x1 <= x0:
        return out, valid
    rows, cols = slice(y0 + dr, y1 + dr), slice(x0 + dc, x1 + dc)
    if planes:
        for i, plane in enumerate(src):
            out[y0:y1, x0:x1, i] = plane[rows, cols]
    else:
        out[y0:y1, x0:x1] = src[rows, cols]
    if mask is None:
        valid[y0:y1, x0:x1] = True
    else:
        v = valid[y0:y1, x0:x1]
        np.greater_equal(mask[rows, cols], 250, out=v)
        if not v.all():
            out[y0:y1, x0:x1][~v] = 0
    return out, valid


def _fill(src: np.ndarray, bad: np.ndarray) -> None:
    """Set the `bad` pixels of a _read_window source to the mean of the others, per band
    (cast to the source dtype), in place. bad: (H, W) bool, neither all False nor all True."""
    if src.ndim == 3 and src.shape[2] <= 4:
        src[bad] = src[~bad].mean(axis=0).astype(src.dtype)
    else:
        fill = np.moveaxis(src, 0, -1)[~bad].mean(axis=0).astype(src.dtype)
        for plane, value in zip(src, fill):
            plane[bad] = value


def _inside(h: int, w: int, map_c: np.ndarray, map_r: np.ndarray) -> np.ndarray:
    """Validity of the pixels remapped from an all-valid (h, w) source window: exactly
    `cv2.remap(mask, map_c, map_r) >= 250` for a 255-filled mask (constant-0 border), without
    an (h, w) mask array.

    The mask is remapped from the crop of the window that the strip's maps reach: cv2 turns
    a coordinate x into the neighbours floor(x') and floor(x') + 1 of x' = round(32 x) / 32, so
    columns floor(min) .. floor(max) + 2 (clipped to the window) hold every neighbour inside
    the window; the others see the constant-0 border in both cases. Shifting float32
    coordinates by a whole c0 <= their minimum (c0 >= 0, |x| < 2^24) is exact, so cv2 sees the
    same fractions and weights. map_c, map_r: (n, m) float32 -> (n, m) bool.
    """
    c_min, c_max = float(map_c.min()), float(map_c.max())
    r_min, r_max = float(map_r.min()), float(map_r.max())
    if c_min >= 0 and r_min >= 0 and c_max <= w - 2 and r_max <= h - 2:
        # Both neighbours of every pixel lie in the window (floor(x') <= w - 2): all weights
        # fall on 255s, which cv2's weights (summing to exactly 1 in fixed point) keep at 255.
        return np.ones(map_c.shape, bool)
    c0 = min(max(int(np.floor(c_min)), 0), w)
    r0 = min(max(int(np.floor(r_min)), 0), h)
    c1 = min(max(int(np.floor(c_max)) + 3, c0), w)
    r1 = min(max(int(np.floor(r_max)) + 3, r0), h)
    if c1 == c0 or r1 == r0:  # the strip lies entirely off the window
        return np.zeros(map_c.shape, bool)
    ones = np.full((r1 - r0, c1 - c0), 255, np.uint8)
    m = cv2.remap(ones, map_c - np.float32(c0), map_r - np.float32(r0), cv2.INTER_LINEAR,
                  borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    return m >= 250
