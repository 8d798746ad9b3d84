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


def _axis_window(lo: int, hi: int, n: int, step: int) -> tuple[int, int, int]:
    """Coarse samples [j0, j1) whose cv2.resize by `step` covers full pixels [lo, hi), and the
    offset of pixel lo in that resized block."""
    j0 = max(lo // step - 1, 0)
    j1 = min(-(-hi // step) + 2, n)
    return j0, j1, lo - j0 * step + step // 2


def smooth_upsample(coarse: np.ndarray, box: tuple[int, int, int, int], step: int) -> np.ndarray:
    """Pixels box = (x0, y0, x1, y1) of the full-resolution image of a slowly varying field
    sampled at pixels (i step, j step): one cv2.resize (fast, SIMD) of the samples around it.

    cv2.resize by an even factor samples half a pixel off the grid: this is for colour fields
    (sky, haze), where half a pixel is invisible, not for geometry (see `upsample`).
    """
    x0, y0, x1, y1 = box
    ny, nx = coarse.shape[:2]
    i0, i1, ox = _axis_window(x0, x1, nx, step)
    j0, j1, oy = _axis_window(y0, y1, ny, step)
    block = np.ascontiguousarray(coarse[j0:j1, i0:i1])
    if step > 1:
        block = cv2.resize(block, ((i1 - i0) * step, (j1 - j0) * step), interpolation=cv2.INTER_LINEAR)
    return block[oy:oy + (y1 - y0), ox:ox + (x1 - x0)]


def mask_box(mask: np.ndarray) -> tuple[int, int, int, int] | None:
    """(x0, y0, x1, y1) bounding box of the True pixels of an (H, W) mask, None if none."""
    rows = np.flatnonzero(mask.any(axis=1))
    if rows.size == 0:
        return None
    cols = np.flatnonzero(mask[rows[0]:rows[-1] + 1].any(axis=0))
    return int(cols[0]), int(rows[0]), int(cols[-1]) + 1, int(rows[-1]) + 1


def apply_sky_and_haze(rgb: np.ndarray, sky: np.ndarray, ground: np.ndarray,
                       elev_c: np.ndarray, alpha_c: np.ndarray | None, step: int, opts) -> np.ndarray:
    """Fill sky pixels with the gradient and blend ground pixels towards the horizon colour.

    rgb (H, W, 3) uint8 (modified in place and returned); sky (H, W) bool; ground (H, W)
    bool: the pixels with map data (other non-sky pixels are no-data and are set black);
    elev_c: coarse ray elevation (rad); alpha_c: coarse haze share or None. Coarse samples
    are at pixels (i step, j step). Work is limited to the boxes that hold ground / sky.
    """
    H, W = rgb.shape[:2]
    if alpha_c is not None and float(alpha_c.max(initial=0.0)) > 0.02:
        box = mask_box(~sky) if sky.any() else (0, 0, W, H)
        if box is not None:
            x0, y0, x1, y1 = box
            # rgb (1 - a) + horizon a, in 8-bit fixed point (a in 1/255 steps, <= 1 DN error).
            a8 = np.rint(255.0 * np.clip(np.asarray(alpha_c, np.float32), 0.0, 1.0)).astype(np.uint8)
            a = smooth_upsample(a8, box, step)  # one channel: resizing three costs 3x
            keep = cv2.bitwise_not(a)  # 255 - a
            haze = cv2.merge([cv2.convertScaleAbs(a, alpha=c / 255.0) for c in opts.sky_horizon_rgb])
            part = rgb[y0:y1, x0:x1]
            cv2.multiply(part, cv2.merge([keep, keep, keep]), dst=part, scale=1.0 / 255.0)
            cv2.add(part, haze, dst=part)
    # No-data ground is black (the warp leaves a fade where partly covered pixels blend in).
    nodata = ~(ground | sky)
    if nodata.any():
        rgb[nodata] = 0
    if sky.any():
        box = mask_box(sky)
        x0, y0, x1, y1 = box
        col = np.clip(np.rint(sky_colour(elev_c, opts.sky_zenith_rgb, opts.sky_horizon_rgb)), 0, 255).astype(np.uint8)
        part = rgb[y0:y1, x0:x1]
        cv2.copyTo(smooth_upsample(col, box, step), sky[y0:y1, x0:x1].view(np.uint8), part)
    return rgb
