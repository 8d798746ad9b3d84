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


class OrthoFrame:
    """A camera frame warped into a north-up virtual nadir view on the map window's grid.

    shape (H, W) of the grid; north0_m, east0_m, gsd_m: its north-west corner and spacing,
    LocalRaster convention, computed from the ESTIMATED pose (a position error of the estimate
    shifts this mapping); origin_px (2,): (col, row) of ortho pixel (0, 0) in the map window
    (integers); H_ortho_to_cam (3, 3): ortho px -> undistorted FULL-RESOLUTION camera px (plane
    case, or the best plane for the relief case); cam_xy_full: callable (cols, rows) -> (N, 2)
    full-resolution undistorted camera px of ortho pixels; ground_down_m: NED down of the ground
    plane (estimated).

    The pixels are made when asked for, because a matcher that refines tiles needs a tenth of
    the grid at full resolution (a 2 Mpx warp is ~7 ms of a ~40 ms frame):
    - image (H, W) uint8 grey (0 outside the frame) and valid (H, W) bool (ground the camera
      sees): the whole grid, made once when first read;
    - crop(level, x0, y0, x1, y1): (grey, valid) of columns x0:x1, rows y0:y1 of the grid
      reduced 2^level times, exactly as area.Pyramid reduces the whole image (2 x 2 means; a
      reduced pixel is valid when all it covers are): warped at full resolution over the
      region it covers and reduced;
    - coarse(level): (grey, valid) of the whole grid reduced 2^level times (H >> level,
      W >> level), warped one level finer from the frame reduced as much and halved: close to
      the reduced image, not equal to it (the global placement uses it, and the tiles refine
      what it finds);
    - valid_share(x0, y0, w, h): the share of valid pixels in a full-resolution region.

    A grid of at most WHOLE_BELOW_PX pixels is warped whole at the first request of any kind:
    there a matcher's ~130 region warps (~30 us each, most of it per call) cost more than the
    whole grid (~4.5 ns a pixel with its reductions): naip_ismn_800m's 0.19 Mpx grids (5 m per
    pixel) gave a latency mean of 38.0 ms region by region, 32.2 ms whole (600 s runs on B).

    render(x0, y0, w, h) -> (grey, valid) of a full-resolution region; render_coarse(level) ->
    (grey, valid); surely_valid(x0, y0, w, h) -> bool: True only when every pixel of the region
    is valid, found without warping it (False: not known). An OrthoFrame made from arrays
    (image=, valid=) serves everything from them.
    """

    WHOLE_BELOW_PX = 750_000

    def __init__(self, shape: tuple[int, int], north0_m: float, east0_m: float, gsd_m: float,
                 origin_px: tuple[int, int], H_ortho_to_cam: np.ndarray, cam_xy_full=None,
                 ground_down_m: float = 0.0, *, render=None, render_coarse=None, surely_valid=None,
                 image: np.ndarray | None = None, valid: np.ndarray | None = None):
        if render is None and image is None:
            raise ValueError("OrthoFrame needs a render function or an image")
        self.shape = (int(shape[0]), int(shape[1]))
        self.north0_m, self.east0_m, self.gsd_m = float(north0_m), float(east0_m), float(gsd_m)
        self.origin_px = (int(origin_px[0]), int(origin_px[1]))
        self.H_ortho_to_cam = H_ortho_to_cam
        self.cam_xy_full = cam_xy_full
        self.ground_down_m = ground_down_m
        self._render, self._render_coarse, self._surely_valid = render, render_coarse, surely_valid
        self._image = image
        self._valid = None if image is None else (np.ones(self.shape, bool) if valid is None else np.asarray(valid, bool))
        self._coarse: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._pyramid = None
        self._by_region = self.shape[0] * self.shape[1] > self.WHOLE_BELOW_PX

    @classmethod
    def from_image(cls, image: np.ndarray, valid: np.ndarray | None = None) -> "OrthoFrame":
        """An OrthoFrame over a given grey uint8 image (H, W) and mask (None: all valid), on a
        unit grid at the map window's origin (for matchers and tests that have the image)."""
        return cls(image.shape, 0.0, 0.0, 1.0, (0, 0), None, image=image, valid=valid)

    def _whole(self) -> None:
        if self._image is None:
            self._image, self._valid = self._render(0, 0, self.shape[1], self.shape[0])

    @property
    def image(self) -> np.ndarray:
        self._whole()
        return self._image

    @property
    def valid(self) -> np.ndarray:
        self._whole()
        return self._valid

    def crop(self, level: int, x0: int, y0: int, x1: int, y1: int) -> tuple[np.ndarray, np.ndarray]:
        """(grey (y1 - y0, x1 - x0) uint8, valid bool) of the grid reduced 2^level times; the
        region must lie inside that level (W >> level columns, H >> level rows)."""
        if not self._by_region:
            self._whole()
        if self._image is not None:
            if level == 0:
                return self._image[y0:y1, x0:x1], self._valid[y0:y1, x0:x1]
            if self._pyramid is None:
                from testbench.navigation.ismn.area import pyramid

                self._pyramid = pyramid(self._image, self._valid, 8)
            img, valid = self._pyramid[level]
            return img[y0:y1, x0:x1], valid[y0:y1, x0:x1]
        s = 2**level
        img, valid = self._render(x0 * s, y0 * s, (x1 - x0) * s, (y1 - y0) * s)
        if level == 0:
            return img, valid
        from testbench.navigation.ismn.area import pyramid

        return pyramid(img, valid, level)[level]

    def valid_share(self, x0: int, y0: int, w: int, h: int) -> float:
        """Share of valid pixels in full-resolution columns x0:x0+w, rows y0:y0+h (inside the grid)."""
        if self._by_region and self._image is None and self._surely_valid is not None and self._surely_valid(x0, y0, w, h):
            return 1.0
        valid = self.crop(0, x0, y0, x0 + w, y0 + h)[1]
        return cv2.countNonZero(valid.view(np.uint8)) / valid.size if valid.size else float("nan")

    def coarse(self, level: int) -> tuple[np.ndarray, np.ndarray]:
        """(grey, valid) of the whole grid reduced 2^level times (see the class docstring)."""
        if level == 0:
            return self.image, self.valid
        out = self._coarse.get(level)
        if out is None:
            out = self._coarse[level] = (self._render_coarse(level)
                                         if self._by_region and self._render_coarse is not None and self._image is None
                                         else self.crop(level, 0, 0, self.shape[1] >> level, self.shape[0] >> level))
        return out

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

    latency_ms: {"window", "ortho", "match", "pose", "total"} wall-clock milliseconds ("ortho"
    prepares the frame and the ortho mapping; the warps a matcher asks the OrthoFrame for fall in
    "match"), and "ortho_to_fix", their sum from "ortho" to "pose", when a fix was made;
    ortho_frame: the OrthoFrame; ortho, ortho_valid: its image and mask (warped when first
    read); map_window: the reference window (grey);
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
    ortho_frame: OrthoFrame | None = None
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
    def ortho(self) -> np.ndarray | None:
        """The ortho image (H, W) uint8, or None."""
        return None if self.ortho_frame is None else self.ortho_frame.image

    @property
    def ortho_valid(self) -> np.ndarray | None:
        """The ortho mask (H, W) bool, or None."""
        return None if self.ortho_frame is None else self.ortho_frame.valid

    @property
    def frame_thumb(self) -> np.ndarray | None:
        """The frame (H, W) downsampled to thumb_px wide (INTER_AREA), or None without a frame."""
        if self.frame is None:
            return None
        h = max(1, round(self.thumb_px * self.frame.shape[0] / self.frame.shape[1]))
        return cv2.resize(self.frame, (self.thumb_px, h), interpolation=cv2.INTER_AREA)
