"""Sky gradient and aerial perspective (haze), evaluated on a coarse pixel grid and upsampled.

Both vary slowly across the frame, so they are computed every `COARSE_PX` pixels and
interpolated with cv2.warpAffine (a power-of-two step keeps OpenCV's 1/32-pixel interpolation
weights exact).
"""

from __future__ import annotations

import cv2
import numpy as np

COARSE_PX = 16


def coarse_axes(width: int, height: int, step: int) -> tuple[np.ndarray, np.ndarray]:
    """Pixel coordinates 0, step, 2 step, ... reaching at least width-1 / height-1."""
    nx = -(-(width - 1) // step) + 1
    ny = -(-(height - 1) // step) + 1
    return np.arange(nx) * float(step), np.arange(ny) * float(step)


def upsample(coarse: np.ndarray, width: int, height: int, step: int,
             interpolation: int = cv2.INTER_LINEAR) -> np.ndarray:
    """Full-resolution image from samples at pixels (i step, j step): exact bilinear weights."""
    M = np.array([[1.0 / step, 0.0, 0.0], [0.0, 1.0 / step, 0.0]])
    return cv2.warpAffine(coarse, M, (width, height), flags=interpolation | cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_REPLICATE)


def sky_colour(elevation_rad: np.ndarray, zenith_rgb, horizon_rgb) -> np.ndarray:
    """(..., 3) float32 sky colour for rays at the given elevation above the horizon (rad):
    pale at the horizon, deepening towards the zenith; below the horizon (ground beyond the far
    plane) the horizon haze colour."""
    s = np.sqrt(np.clip(np.asarray(elevation_rad) / 0.7, 0.0, 1.0))[..., None]
    z = np.asarray(zenith_rgb, np.float32)
    h = np.asarray(horizon_rgb, np.float32)
    return (h * (1.0 - s) + z * s).astype(np.float32)


def haze_alpha(range_m: np.ndarray, visibility_m: float | None) -> np.ndarray:
    """Share of the horizon colour seen through `range_m` of air (Koschmieder-like, 0..1)."""
    if visibility_m is None:
        return np.zeros_like(range_m, dtype=np.float32)
    return (1.0 - np.exp(-np.asarray(range_m) / visibility_m)).astype(np.float32)


def apply_sky_and_haze(rgb: np.ndarray, sky: np.ndarray, ground: np.ndarray,
                       elev_c: np.ndarray, alpha_c: np.ndarray | None, step: int, opts) -> np.ndarray:
    """Fill sky pixels with the gradient and blend ground pixels towards the horizon colour.

    rgb (H, W, 3) uint8 (modified in place and returned); sky, ground (H, W) bool;
    elev_c: coarse ray elevation (rad); alpha_c: coarse haze share or None.
    """
    H, W = rgb.shape[:2]
    if alpha_c is not None and float(alpha_c.max(initial=0.0)) > 0.02:
        a = upsample(np.ascontiguousarray(alpha_c, np.float32), W, H, step)
        haze = np.empty_like(rgb)
        haze[:] = np.asarray(opts.sky_horizon_rgb, np.uint8)
        blended = cv2.blendLinear(rgb, haze, 1.0 - a, a)
        cv2.copyTo(blended, ground.view(np.uint8), rgb)
    if sky.any():
        col = sky_colour(elev_c, opts.sky_zenith_rgb, opts.sky_horizon_rgb)
        full = np.clip(upsample(col, W, H, step), 0, 255).astype(np.uint8)
        cv2.copyTo(full, sky.view(np.uint8), rgb)
    return rgb
