"""A large reference-map window kept across frames, so that each frame's search window is a
crop instead of a fresh read (reprojecting a GeoTIFF window costs ~100 ms per frame).

The cache holds one grey window per ground sample (the whole map when it is small enough); a
request inside it is served as a view. A crop lies on the cached grid and starts on a multiple
of ALIGN_PX pixels of it, so its north-west corner can differ from the requested bounds by up to
ALIGN_PX pixels (it always covers them); callers use the returned raster's own geometry. The
alignment lets a crop's reduced levels (area.Pyramid) and their feature images be cut from the
cached read's, computed once, instead of being made again for every frame.
"""

from __future__ import annotations

import math

import numpy as np

from testbench.navigation.ismn.area import Pyramid
from testbench.navigation.ismn.ortho import to_grey_u8
from testbench.world import memo
from testbench.world.raster import LocalRaster


#: Crops start on multiples of this many pixels of the cached read: levels up to log2(ALIGN_PX)
#: (a 2^3 reduction, the matchers' coarse level for a 2 Mpx ortho frame) are cut from the read's.
ALIGN_PX = 8


def quantise_gsd(gsd_m: float, native_gsd_m: float | None, steps_per_octave: int = 8) -> float:
    """Round a ground sample up to native * 2^(k / steps_per_octave) so that nearby requests
    share one cached window (no change when it equals the native sample)."""
    if not native_gsd_m or gsd_m <= native_gsd_m * (1 + 1e-9):
        return float(gsd_m)
    k = math.ceil(steps_per_octave * math.log2(gsd_m / native_gsd_m) - 1e-9)
    return float(native_gsd_m * 2.0 ** (k / steps_per_octave))


class MapWindowCache:
    """Grey reference-map windows served from one larger cached read per ground sample.

    source: anything with read_local(north_min, north_max, east_min, east_max, gsd_m) ->
    LocalRaster. When the whole map (source.footprint) is at most whole_map_max_px a side at the
    requested ground sample, the cached read is the whole map, read once: every request is a
    crop of it, padded with no-data where it reaches past the map. Otherwise the cached read
    extends every side of the request by grow x its larger extent (at most max_side_px a side,
    else read as asked) and is replaced when a request leaves it.

    Reads, their grey images and feature images go through `testbench.world.memo`, so a batch
    worker that enables the memo reads and prepares a whole map once for all its runs.
    """

    def __init__(self, source, grow: float = 0.5, max_side_px: int = 6000, whole_map_max_px: int = 5000):
        self.source = source
        self.grow = float(grow)
        self.max_side_px = int(max_side_px)
        # A whole map is read only up to this side (5000 px: 25 Mpx, ~150 MB with its feature
        # image), no more than a grown window could take: a 10 km map at 1 m stays windowed.
        self.whole_map_max_px = min(int(whole_map_max_px), self.max_side_px)
        self._cache: dict[float, LocalRaster] = {}
        self._whole: dict[float, bool] = {}  # the cached read at this gsd is the whole map
        self._memo_keys: dict[float, tuple | None] = {}
        self._features: dict[tuple[float, str, int], np.ndarray] = {}
        self._pyramids: dict[float, Pyramid] = {}

    def _whole_map_bounds(self, gsd_m: float) -> tuple[float, float, float, float] | None:
        fp = getattr(self.source, "footprint", None)
        if fp is None or max(fp.north_max_m - fp.north_min_m, fp.east_max_m - fp.east_min_m) > self.whole_map_max_px * gsd_m:
            return None
        return fp.north_min_m, fp.north_max_m, fp.east_min_m, fp.east_max_m

    def read(self, north_min: float, north_max: float, east_min: float, east_max: float, gsd_m: float) -> LocalRaster:
        """LocalRaster (grey (H, W) uint8 data, valid) covering the bounds at gsd_m."""
        c = self._cache.get(gsd_m)
        if c is None or not (self._whole[gsd_m] or _covers(c, north_min, north_max, east_min, east_max)):
            # Drop the window this read replaces, and its feature images, before reading: the
            # old and new windows (and float32 features) need not coexist at the peak. (Same
            # eviction as ever: all windows go when more than 4, this one included, were held.)
            c = None
            evict_all = len(self._cache) > 4
            self._cache.pop(gsd_m, None)
            self._pyramids.pop(gsd_m, None)
            for k in [k for k in self._features if k[0] == gsd_m]:
                del self._features[k]
            if evict_all:
                self._cache.clear()
                self._features.clear()
                self._pyramids.clear()
            box = self._whole_map_bounds(gsd_m)
            self._whole[gsd_m] = box is not None
            if box is None:
                m = self.grow * max(north_max - north_min, east_max - east_min)
                if max(north_max - north_min, east_max - east_min) + 2 * m > self.max_side_px * gsd_m:
                    m = 0.0
                box = (north_min - m, north_max + m, east_min - m, east_max + m)
            key_fn = getattr(self.source, "memo_key", None)
            key = None if key_fn is None else ("ismn-grey", key_fn(*box, gsd_m))
            self._memo_keys[gsd_m] = key
            c = memo.cached(key, lambda: self._read_grey(box, gsd_m))
            self._cache[gsd_m] = c
        g = c.gsd_m
        r0 = int(math.floor((c.north0_m - north_max) / g + 1e-9))
        c0 = int(math.floor((east_min - c.east0_m) / g + 1e-9))
        r1 = int(math.ceil((c.north0_m - north_min) / g - 1e-9))
        c1 = int(math.ceil((east_max - c.east0_m) / g - 1e-9))
        r0, c0 = r0 - r0 % ALIGN_PX, c0 - c0 % ALIGN_PX
        if not self._whole[gsd_m]:
            r0, c0, r1, c1 = max(0, r0), max(0, c0), min(c.shape[0], r1), min(c.shape[1], c1)
        elif r0 < 0 or c0 < 0 or r1 > c.shape[0] or c1 > c.shape[1]:
            return _padded_crop(c, r0, c0, r1, c1)
        return LocalRaster(c.data[r0:r1, c0:c1], c.valid[r0:r1, c0:c1], c.north0_m - r0 * g, c.east0_m + c0 * g, g)

    def _read_grey(self, box, gsd_m: float) -> LocalRaster:
        # A source that memoises (MapSource) need not also keep the RGB read: the grey is kept.
        extra = {"memoise": False} if hasattr(self.source, "memo_key") else {}
        r = self.source.read_local(box[0], box[1], box[2], box[3], gsd_m, **extra)
        return LocalRaster(to_grey_u8(r.data), np.asarray(r.valid, bool), r.north0_m, r.east0_m, r.gsd_m)

    def _aligned_crop(self, window: LocalRaster, level: int) -> tuple[int, int, int, int] | None:
        """(row, col, rows, cols) of `window` reduced 2^level times (area.Pyramid's sizes: each
        level the largest even crop halved) inside the cached read's level `level`; None when
        the window is not a crop of the current cache or does not start on a multiple of 2^level."""
        c = self._cache.get(window.gsd_m)
        at = None if c is None else _crop_of(c, window)
        s = 2**level
        if at is None or at[0] % s or at[1] % s:
            return None
        return at[0] // s, at[1] // s, window.shape[0] // s, window.shape[1] // s

    def _pyramid(self, gsd_m: float) -> Pyramid:
        pyr = self._pyramids.get(gsd_m)
        if pyr is None:
            c = self._cache[gsd_m]
            pyr = self._pyramids[gsd_m] = Pyramid(c.data, c.valid, int(math.log2(ALIGN_PX)))
        return pyr

    def pyramid_level(self, window: LocalRaster, level: int) -> tuple[np.ndarray, np.ndarray] | None:
        """(grey uint8, valid bool) of a window this cache served, reduced 2^level times exactly as
        area.Pyramid reduces it (2 x 2 means are local, so a crop of the read's level is the
        crop's level), cut from the cached read's pyramid (made once per read); None when the
        window is no aligned crop of the current cache or level is beyond log2(ALIGN_PX)."""
        if not 0 < level <= math.log2(ALIGN_PX):
            return None
        at = self._aligned_crop(window, level)
        if at is None:
            return None
        r, c, h, w = at
        img, valid = self._pyramid(window.gsd_m)[level]
        return img[r:r + h, c:c + w], valid[r:r + h, c:c + w]

    def features(self, window: LocalRaster, kind: str, level: int = 0) -> np.ndarray | None:
        """Appearance-robust feature image (features.robust_image) of a window this cache
        served, reduced 2^level times, cut from the feature image of the whole cached read's
        level (computed once per read); None when the window is not an (aligned) crop of the
        current cache. The local normalisation then sees the read around the window too, where
        the window's own image has its edge, and its global term is the read's."""
        at = self._aligned_crop(window, level) if level <= math.log2(ALIGN_PX) else None
        if at is None:
            return None
        gsd = window.gsd_m
        f = self._features.get((gsd, kind, level))
        if f is None:
            from testbench.navigation.ismn.features import robust_image

            key = self._memo_keys.get(gsd)
            img, valid = self._pyramid(gsd)[level]
            memo_key = key and (("ismn-features", kind, key) if level == 0 else ("ismn-features", kind, level, key))
            f = memo.cached(memo_key, lambda: robust_image(img, valid, kind)[0])
            self._features[(gsd, kind, level)] = f
        r, c, h, w = at
        return f[r:r + h, c:c + w]


def _padded_crop(c: LocalRaster, r0: int, c0: int, r1: int, c1: int) -> LocalRaster:
    """Rows r0:r1, cols c0:c1 of c (grey), no-data (0, invalid) where they lie outside it."""
    g = c.gsd_m
    h, w = max(0, r1 - r0), max(0, c1 - c0)
    data = np.zeros((h, w), c.data.dtype)
    valid = np.zeros((h, w), bool)
    ya, xa = max(0, r0), max(0, c0)
    yb, xb = min(c.shape[0], r1), min(c.shape[1], c1)
    if yb > ya and xb > xa:
        data[ya - r0:yb - r0, xa - c0:xb - c0] = c.data[ya:yb, xa:xb]
        valid[ya - r0:yb - r0, xa - c0:xb - c0] = c.valid[ya:yb, xa:xb]
    return LocalRaster(data, valid, c.north0_m - r0 * g, c.east0_m + c0 * g, g)


def _crop_of(c: LocalRaster, r: LocalRaster) -> tuple[int, int] | None:
    """(row, col) of raster r's first pixel inside the cached raster c, None if not a crop of it."""
    g = c.gsd_m
    if abs(r.gsd_m - g) > 1e-9 * g:
        return None
    r0 = round((c.north0_m - r.north0_m) / g)
    c0 = round((r.east0_m - c.east0_m) / g)
    if abs(c.north0_m - r0 * g - r.north0_m) > 1e-6 * g or abs(c.east0_m + c0 * g - r.east0_m) > 1e-6 * g:
        return None
    if r0 < 0 or c0 < 0 or r0 + r.shape[0] > c.shape[0] or c0 + r.shape[1] > c.shape[1]:
        return None
    return r0, c0


def _covers(r: LocalRaster, n0: float, n1: float, e0: float, e1: float) -> bool:
    g = r.gsd_m
    tol = 1e-6 * g
    return (r.north0_m >= n1 - tol and r.north0_m - r.shape[0] * g <= n0 + tol
            and r.east0_m <= e0 + tol and r.east0_m + r.shape[1] * g >= e1 - tol)
