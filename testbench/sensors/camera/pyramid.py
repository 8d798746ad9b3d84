"""Image pyramids of map rasters (cv2.pyrDown chains), cached for as long as the raster lives.

Each level is RGBA uint8: RGB from the imagery, alpha = 255 where the map has data. Warping
the alpha with the colour gives the no-data mask in the same pass (and OpenCV warps four
channels faster than three). Level L has pixel centres at level-0 coordinates 2^L * i
(pyrDown's kernel is centred on source pixel 2i), so level-L pixel coordinates are the level-0
coordinates divided by 2^L.
"""

from __future__ import annotations

import weakref

import cv2
import numpy as np

from testbench.world.raster import LocalRaster

_MIN_LEVEL_PX = 8
_CACHE: dict[int, "RasterPyramid"] = {}


def imagery_rgba(raster: LocalRaster) -> np.ndarray:
    """(H, W, 4) uint8 RGBA of an imagery raster: grey is replicated, bands beyond 3 dropped,
    non-uint8 data clipped into 0-255; alpha = 255 on valid pixels."""
    data = np.asarray(raster.data)
    if data.ndim == 2:
        data = data[:, :, None]
    if data.shape[2] == 1:
        data = np.repeat(data, 3, axis=2)
    data = data[:, :, :3]
    if data.dtype != np.uint8:
        data = np.clip(data, 0, 255).astype(np.uint8)
    alpha = np.where(np.asarray(raster.valid, bool), np.uint8(255), np.uint8(0))
    rgba = np.dstack([data, alpha])
    rgba[alpha == 0, :3] = 0  # no-data renders black whatever the source holds there
    return np.ascontiguousarray(rgba)


class RasterPyramid:
    """RGBA pyramid of one imagery raster; levels[L] has half the size of levels[L - 1]."""

    def __init__(self, raster: LocalRaster):
        level = imagery_rgba(raster)
        # All data valid: alpha is 255 wherever a warp samples inside the map (pyrDown reflects
        # at the borders, so coarse levels keep it), and a renderer may skip reading it.
        self.all_valid = bool(np.asarray(raster.valid, bool).all())
        self.levels: list[np.ndarray] = [level]
        while min(level.shape[:2]) >= 2 * _MIN_LEVEL_PX:
            level = cv2.pyrDown(level)
            self.levels.append(level)
        # [col, row, 1] (level-0 pixel centres) = inv_affine @ [east, north, 1]
        self.map_from_ne = np.linalg.inv(raster.affine_ne_from_colrow())

    @property
    def max_level(self) -> int:
        return len(self.levels) - 1


def pyramid_for(raster: LocalRaster) -> RasterPyramid:
    """The pyramid of `raster`, built once and dropped when the raster is garbage-collected."""
    key = id(raster)
    pyr = _CACHE.get(key)
    if pyr is None:
        pyr = RasterPyramid(raster)
        _CACHE[key] = pyr
        weakref.finalize(raster, _CACHE.pop, key, None)
    return pyr


class DemSampler:
    """A DEM prepared for ray casting: float32 heights with no-data filled, extrema and the
    largest slope (a Lipschitz bound on the terrain, m/m), cached per raster like pyramids."""

    def __init__(self, dem: LocalRaster):
        h = np.asarray(dem.data, np.float32)
        if h.ndim == 3:
            h = h[:, :, 0]
        valid = np.asarray(dem.valid, bool) & np.isfinite(h)
        fill = float(np.median(h[valid])) if valid.any() else 0.0
        self.height = np.ascontiguousarray(np.where(valid, h, np.float32(fill)), np.float32)
        self.h_min = float(self.height.min())
        self.h_max = float(self.height.max())
        gy, gx = np.gradient(self.height.astype(np.float64), dem.gsd_m)
        # Bilinear interpolation within a cell can be steeper than the central difference:
        # bound it with the forward differences as well.
        fx = np.abs(np.diff(self.height, axis=1)).max(initial=0.0) / dem.gsd_m
        fy = np.abs(np.diff(self.height, axis=0)).max(initial=0.0) / dem.gsd_m
        self.slope_max = float(max(np.hypot(gx, gy).max(initial=0.0), np.hypot(fx, fy), 1e-3))
        self.raster = dem
        self.map_from_ne = np.linalg.inv(dem.affine_ne_from_colrow())
        # Max-filtered heights for empty-space skipping: max_maps[j][r, c] bounds the terrain
        # (bilinear included) within 2^j cells of cell (r, c) in both directions.
        # Level 0 is a 3 x 3 dilation of radius 2; level j (radius 2^j + 1) is the max of level
        # j-1 at offsets 0, +-2^(j-1) along each axis, whose windows tile exactly radius 2^j + 1.
        # That keeps every level O(pixels) (a direct square dilation of radius 513 on a
        # 3000 x 3000 DEM takes seconds per level).
        kernel = np.ones((5, 5), np.uint8)
        self.max_maps = [cv2.dilate(self.height, kernel, borderType=cv2.BORDER_REPLICATE)]
        big = max(self.height.shape)
        j = 1
        while (1 << j) <= big and j <= 9:
            self.max_maps.append(_shifted_max(self.max_maps[-1], 1 << (j - 1)))
            j += 1

    def cell_index(self, north_m: np.ndarray, east_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nearest cell (row, col), clamped into the raster (the terrain extends its edges)."""
        A = self.map_from_ne
        H, W = self.height.shape
        col = np.clip(np.rint(A[0, 0] * east_m + A[0, 2]), 0, W - 1).astype(np.intp)
        row = np.clip(np.rint(A[1, 1] * north_m + A[1, 2]), 0, H - 1).astype(np.intp)
        return row, col

    def height_at(self, north_m: np.ndarray, east_m: np.ndarray) -> np.ndarray:
        """Bilinear terrain height (m, up) at NED north/east; edges extend outwards."""
        shape = np.shape(north_m)
        A = self.map_from_ne
        col = A[0, 0] * np.ravel(east_m) + A[0, 2]
        row = A[1, 1] * np.ravel(north_m) + A[1, 2]
        return sample_points(self.height, col, row, cv2.BORDER_REPLICATE).reshape(shape)


def _shifted_max(a: np.ndarray, shift: int) -> np.ndarray:
    """max(a[r + dr, c + dc]) over dr, dc in {-shift, 0, +shift}, edges replicated (H, W)."""
    out = a.copy()
    for axis in (0, 1):
        padded = np.pad(out, [(shift, shift) if ax == axis else (0, 0) for ax in (0, 1)], mode="edge")
        n = out.shape[axis]
        lo = padded[:n] if axis == 0 else padded[:, :n]
        hi = padded[2 * shift:] if axis == 0 else padded[:, 2 * shift:]
        out = np.maximum(np.maximum(out, lo), hi)
    return out


def sample_points(img: np.ndarray, col: np.ndarray, row: np.ndarray,
                  border: int = cv2.BORDER_REPLICATE) -> np.ndarray:
    """Bilinear samples of a single-channel float32 image at (col, row) points, shape (n,).

    cv2.remap wants maps under 32767 px a side, so the points are laid out in rows of 1024.
    """
    n = col.size
    width = 1024
    rows = max(1, -(-n // width))
    mx = np.zeros(rows * width, np.float32)
    my = np.zeros(rows * width, np.float32)
    mx[:n] = col
    my[:n] = row
    out = cv2.remap(img, mx.reshape(rows, width), my.reshape(rows, width), cv2.INTER_LINEAR,
                    borderMode=border)
    return out.ravel()[:n].astype(np.float64)


_DEM_CACHE: dict[int, DemSampler] = {}


def dem_sampler_for(dem: LocalRaster) -> DemSampler:
    key = id(dem)
    s = _DEM_CACHE.get(key)
    if s is None:
        s = DemSampler(dem)
        _DEM_CACHE[key] = s
        weakref.finalize(dem, _DEM_CACHE.pop, key, None)
    return s
