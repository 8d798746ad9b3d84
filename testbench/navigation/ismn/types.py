"""Messages of the ISMN pipeline (frozen dataclasses; the shared PositionFix is in core.messages).

Pixel conventions: (col, row) = (x, y) with integers at pixel centres, as OpenCV uses them.
"Map px" are pixels of the reference-map window (a north-up LocalRaster); "ortho px" are pixels
of the orthorectified camera frame, which lies on a sub-grid of the same window grid.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np


@dataclass(frozen=True)
class SearchWindow:
    """Where to look in the reference map (DESIGN.md eq. 3-5), local NED metres.

    centre_ne_m (2,): predicted footprint centre (optical axis meets the ground).
    footprint_ne_m (4,): predicted footprint bounds (north_min, north_max, east_min, east_max).
    bounds_ne_m (4,): window to request = footprint + 3 sigma of position (+ attitude) + margin.
    margin_m: the half-width added around the footprint; gsd_m: map metres per pixel to request;
    ground_down_m: NED down of the ground plane used (= -terrain height above the origin).
    """

    centre_ne_m: np.ndarray
    footprint_ne_m: tuple[float, float, float, float]
    bounds_ne_m: tuple[float, float, float, float]
    margin_m: float
    gsd_m: float
    ground_down_m: float


@dataclass(frozen=True)
class OrthoFrame:
    """A camera frame warped into a north-up virtual nadir view on the map window's grid.

    image (H, W) uint8 grey (0 outside the frame); valid (H, W) bool (ground seen by the camera);
    north0_m, east0_m, gsd_m: north-west corner and spacing, LocalRaster convention, computed
    from the ESTIMATED pose (a position error of the estimate shifts this mapping);
    origin_px (2,): (col, row) of ortho pixel (0, 0) in the map window (integers);
    map_x, map_y: None for a plane homography, else (H, W) float32 camera pixel coordinates
    (undistorted, downsampled frame) of every ortho pixel (relief);
    H_ortho_to_cam (3, 3): ortho px -> undistorted FULL-RESOLUTION camera px (plane case, or
    the best plane for the relief case);
    ground_down_m (H, W) or float: NED down of the ground at each ortho pixel (estimated).
    """

    image: np.ndarray
    valid: np.ndarray
    north0_m: float
    east0_m: float
    gsd_m: float
    origin_px: tuple[int, int]
    H_ortho_to_cam: np.ndarray
    cam_xy_full: object = None  # callable (cols, rows) -> (N, 2) full-res undistorted camera px
    ground_down_m: object = 0.0

    def ortho_to_ne(self, col, row):
        """Local (north_m, east_m) of continuous ortho pixel coordinates under the estimate."""
        north = self.north0_m - (np.asarray(row, float) + 0.5) * self.gsd_m
        east = self.east0_m + (np.asarray(col, float) + 0.5) * self.gsd_m
        return north, east


@dataclass(frozen=True)
class MatchPrior:
    """What a matcher knows before matching.

    origin_px (2,): predicted (col, row) of the ortho frame's pixel (0, 0) in the map window;
    search_radius_px: how far from it the true placement may be (3 sigma + margin);
    ortho_valid (H, W) bool and map_valid (Hm, Wm) bool masks; gsd_m: metres per pixel;
    map_features: optional callable (kind, level) -> float32 feature image (features.robust_image)
    of the map window reduced 2^level times, (Hm, Wm) at level 0, precomputed by the caller (a
    cached map), or None (the callable too may answer None: the matcher then computes it);
    map_pyramid: optional callable level -> (grey uint8, valid bool) of the map window reduced
    2^level times as area.Pyramid makes it (a cached map's), or None;
    heading_sigma_rad: the estimate's 1-sigma heading uncertainty, which rotates the ortho view
    against the map (a matcher that searches translations only widens its search with it).
    """

    origin_px: tuple[float, float]
    search_radius_px: float
    ortho_valid: np.ndarray | None = None
    map_valid: np.ndarray | None = None
    gsd_m: float = 1.0
    map_features: object = None
    heading_sigma_rad: float = 0.0
    map_pyramid: object = None


@dataclass(frozen=True)
class MatchResult:
    """A registration of the ortho frame in the map window.

    offset_px (2,): (d_col, d_row) shift of the ortho frame in map pixels from the predicted
    placement (east, south positive): ortho pixel p lies at map pixel p + origin + offset.
    ortho_px, map_px: (N, 2) correspondences (col, row) or None;
    quality: the matcher's own figure in [0, 1]; cov_px2 (2, 2): its covariance of one
    correspondence (or of the offset when there are none), map pixels^2.
    peak: raw peak score (NCC value, phase response or inlier ratio) for diagnostics.
    """

    offset_px: np.ndarray
    ortho_px: np.ndarray | None
    map_px: np.ndarray | None
    quality: float
    cov_px2: np.ndarray
    peak: float = float("nan")
    method: str = ""


@dataclass(frozen=True)
class IsmnDiagnostics:
    """What one ISMN attempt did, for reports and debugging.

    latency_ms: {"window", "ortho", "match", "pose", "total"} wall-clock milliseconds;
    ortho, ortho_valid: the orthorectified frame; map_window: the reference window (grey);
    frame: the prepared camera frame (grey uint8, as orthorectified); frame_thumb: it
    downsampled to thumb_px wide, made when read (the report keeps one example a minute, and
    the resizing, 1-2 ms, must not be paid, or timed, for every frame); peak_quality: matcher quality;
    offset_px, offset_m (2,): matched shift (east, south) in map px / (north, east) in m;
    window: the SearchWindow; n_correspondences, n_inliers; reason: why no fix ("" if one);
    attempted: False when the pipeline declined the frame by design (waiting for the heading),
    which the fix rate does not count.
    """

    t_s: float
    latency_ms: dict = field(default_factory=dict)
    ortho: np.ndarray | None = None
    ortho_valid: np.ndarray | None = None
    map_window: np.ndarray | None = None
    frame: np.ndarray | None = None
    thumb_px: int = 320
    peak_quality: float = 0.0
    offset_px: np.ndarray | None = None
    offset_m: np.ndarray | None = None
    window: SearchWindow | None = None
    n_correspondences: int = 0
    n_inliers: int = 0
    reason: str = ""
    attempted: bool = True

    @property
    def frame_thumb(self) -> np.ndarray | None:
        """The frame (H, W) downsampled to thumb_px wide (INTER_AREA), or None without a frame."""
        if self.frame is None:
            return None
        h = max(1, round(self.thumb_px * self.frame.shape[0] / self.frame.shape[1]))
        return cv2.resize(self.frame, (self.thumb_px, h), interpolation=cv2.INTER_AREA)
