"""A raster resampled onto the scenario's local north-east grid: the form the renderer and the
scene matcher consume, whatever CRS the source GeoTIFF had.

Grid convention: row 0 is the northernmost row, rows increase southwards, columns increase
eastwards. Pixel (row, col) has its CENTRE at
    north_m = north0_m - (row + 0.5) * gsd_m,   east_m = east0_m + (col + 0.5) * gsd_m
i.e. (north0_m, east0_m) is the north-west CORNER of pixel (0, 0), in local NED metres at the
scenario origin. The grid is north-up (aligned with local north) by construction.
"""

from __future__ import annotations

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
