"""A raster resampled onto the scenario's local north-east grid: the form the renderer and the
scene matcher consume, whatever CRS the source GeoTIFF had.

Grid convention: row 0 is the northernmost row, rows increase southwards, columns increase
eastwards. Pixel (row, col) has its CENTRE at
    north_m = north0_m - (row + 0.5) * gsd_m,   east_m = east0_m + (col + 0.5) * gsd_m
i.e. (north0_m, east0_m) is the north-west CORNER of pixel (0, 0), in local NED metres at the
scenario origin. The grid is north-up (aligned with local north) by construction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class LocalRaster:
    """An image or elevation grid on the local north-east grid.

    data: (H, W, C) uint8 imagery or (H, W) float32 elevation (m above the origin altitude).
    valid: (H, W) bool, False where the source had no data (off-map or nodata).
    north0_m, east0_m: north-west corner of the grid (m); gsd_m: metres per pixel.
    """

    data: np.ndarray
    valid: np.ndarray
    north0_m: float
    east0_m: float
    gsd_m: float

    @property
    def shape(self) -> tuple[int, int]:
        return self.data.shape[0], self.data.shape[1]

    def ne_to_rowcol(self, north_m, east_m):
        """Continuous (row, col) pixel coordinates, centre convention (integers at centres)."""
        row = (self.north0_m - np.asarray(north_m, float)) / self.gsd_m - 0.5
        col = (np.asarray(east_m, float) - self.east0_m) / self.gsd_m - 0.5
        return row, col

    def rowcol_to_ne(self, row, col):
        """Inverse of ne_to_rowcol: local (north_m, east_m) of continuous pixel coordinates."""
        north = self.north0_m - (np.asarray(row, float) + 0.5) * self.gsd_m
        east = self.east0_m + (np.asarray(col, float) + 0.5) * self.gsd_m
        return north, east

    def affine_ne_from_colrow(self) -> np.ndarray:
        """3x3 matrix A with [east, north, 1]^T = A @ [col, row, 1]^T (pixel centres at integers)."""
        g = self.gsd_m
        return np.array(
            [[g, 0.0, self.east0_m + 0.5 * g], [0.0, -g, self.north0_m - 0.5 * g], [0.0, 0.0, 1.0]]
        )



def sample_bilinear(raster: LocalRaster, north_m, east_m):
    """Bilinear value of `raster` at local (north_m, east_m) (arrays broadcast together).

    Returns (values, valid): values float64 of shape (..., C) for (H, W, C) data or (...) for
    (H, W) data; valid False where any of the four neighbours with non-zero weight is invalid
    or outside the grid (values there are 0). Exact float weights (no 1/32 quantisation).
    """
    row, col = raster.ne_to_rowcol(north_m, east_m)
    return bilinear_at_rowcol(raster.data, raster.valid, row, col)


def sample_bilinear_point(raster: LocalRaster, north_m: float, east_m: float) -> tuple[float, bool]:
    """sample_bilinear at one local (north_m, east_m) point, in plain floats (bilinear_point):
    the same (value, valid), bit for bit."""
    row = (raster.north0_m - north_m) / raster.gsd_m - 0.5  # ne_to_rowcol's formula, on floats
    col = (east_m - raster.east0_m) / raster.gsd_m - 0.5
    return bilinear_point(raster.data, raster.valid, row, col)


def bilinear_at_rowcol(data: np.ndarray, valid: np.ndarray, row, col):
    """Bilinear interpolation of data (H, W[, C]) at continuous (row, col), centres at integers.

    Returns (values float64 (...[, C]), valid bool (...)) as sample_bilinear does.
    """
    row, col = np.asarray(row, float), np.asarray(col, float)
    if row.shape != col.shape:
        row, col = np.broadcast_arrays(row, col)
    h, w = data.shape[:2]
    inside = (row >= 0) & (col >= 0) & (row <= h - 1) & (col <= w - 1)
    everywhere = bool(inside.all())
    rs = row if everywhere else np.where(inside, row, 0.0)
    cs = col if everywhere else np.where(inside, col, 0.0)
    # rs, cs >= 0, so the floor needs no lower clip; the upper one keeps the second row and
    # column on the grid (the last one is reached at weight 1 from the one before it).
    r0 = np.minimum(np.floor(rs), max(h - 2, 0))
    c0 = np.minimum(np.floor(cs), max(w - 2, 0))
    fr = rs - r0
    fc = cs - c0
    gr = 1 - fr
    gc = 1 - fc
    # One flat index per point and gathers along the flattened grid (np.take): the same pixels
    # as data[r, c] for less than two-index fancy indexing costs (with the lookups skipped
    # below, 1.5-2.7x on the terrain-aided navigation's 2 000-250 000 points a call).
    step_r, step_c = (w if h > 1 else 0), (1 if w > 1 else 0)  # a one-pixel axis has no neighbour
    i00 = r0.astype(np.int64)
    i00 *= w
    i00 += c0.astype(np.int64)
    corners = ((gr * gc, i00), (gr * fc, i00 + step_c), (fr * gc, i00 + step_r), (fr * fc, i00 + (step_r + step_c)))
    flat = np.ascontiguousarray(data).reshape((h * w,) + data.shape[2:])
    extra = (None,) * (data.ndim - 2)
    out = np.zeros(row.shape + data.shape[2:])
    for wt, idx in corners:
        out += flat.take(idx, axis=0).astype(np.float64) * wt[(...,) + extra]
    ok = inside  # (inside is not used again: no copy)
    if not valid.all():  # a grid without gaps (a DEM window, most images) needs no lookups
        valid_flat = np.ascontiguousarray(valid).reshape(-1)
        for wt, idx in corners:
            ok &= valid_flat.take(idx) | (wt <= 0.0)
    if not ok.all():
        out[~ok] = 0.0
    return out, ok


def bilinear_point(data: np.ndarray, valid: np.ndarray, row: float, col: float) -> tuple[float, bool]:
    """bilinear_at_rowcol for one point of (H, W) data, in plain floats: the same operations
    in the same order, so the same value bit for bit, at a few microseconds instead of the
    hundred that a dozen numpy calls on one-element arrays cost (the dynamics ask the terrain
    under each vehicle at every physics step). Returns (value float, valid bool)."""
    h, w = data.shape[:2]
    inside = row >= 0 and col >= 0 and row <= h - 1 and col <= w - 1
    rs, cs = (row, col) if inside else (0.0, 0.0)
    r0 = min(max(math.floor(rs), 0), max(h - 2, 0))
    c0 = min(max(math.floor(cs), 0), max(w - 2, 0))
    fr = rs - r0
    fc = cs - c0
    r1 = min(r0 + 1, h - 1)
    c1 = min(c0 + 1, w - 1)
    out = 0.0
    ok = inside
    for wt, ri, ci in (((1 - fr) * (1 - fc), r0, c0), ((1 - fr) * fc, r0, c1),
                       (fr * (1 - fc), r1, c0), (fr * fc, r1, c1)):
        out += float(data[ri, ci]) * wt
        ok = ok and (bool(valid[ri, ci]) or wt <= 0.0)
    return (out if ok else 0.0), ok
