"""The translation between two images of the same ground, to a hundredth of a pixel: what an
optical-flow sensor's chip computes from two consecutive frames.

`image_shift(prev, curr)` finds d (2,) px such that curr(x + d) = prev(x) (the content moved by
d from the earlier image to the later one): cv2.phaseCorrelate first, which finds a shift of
several pixels but whose sub-pixel part is a centroid biased towards whole pixels (a quarter
of the shift lost on the smooth images of a 1 m map seen at 0.8 m/px), then Lucas-Kanade
(Gauss-Newton on the sum of squared differences, with the earlier image's gradients, Lucas &
Kanade 1981; Baker & Matthews 2004) from there, with the brightness offset taken out.

Its covariance is the least-squares one, s^2 H^-1, where H = sum over pixels of g g' (g the
earlier image's gradient, DN/px) and s^2 the residual's variance after the fit (both images'
noise and whatever else does not move as one translation). It takes the residuals as white:
a renderer's or a lens's blur correlates neighbouring residuals, so the true spread is larger
by a factor a user calibrates (the navigator's optical_flow.sigma_scale). Weak texture, or
texture in one direction only (crop rows, a road: the aperture problem), shows as a small
eigenvalue of H, along which the claim is wide.

A flow that is not one translation (a rotating camera's: off-centre pixels move more) is read
as a weighted mean of itself: to first order the fit reads H^-1 sum g g' f(x) of a flow field f
(px). `fields` gives such fields, and the result says what the fit reads of each: a flow
sensor's way to tell its navigator how its own rotation enters the shift.

Shapes: images (h, w) float32 grey levels (DN); shift (u, v) along image columns and rows;
fields (k, h, w, 2) px.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class ImageShift:
    """shift_px (2,): (du, dv), the content's move from the earlier image to the later (px);
    cov_px2 (2, 2): its least-squares covariance (px^2, white residuals); residual_dn: the
    residual's standard deviation after the fit (DN); texture_dn2: the smaller eigenvalue of
    H over the pixels used, per pixel (DN^2 / px^2): the squared gradient along the weakest
    direction; iterations: Gauss-Newton steps taken."""

    shift_px: np.ndarray
    cov_px2: np.ndarray
    residual_dn: float
    texture_dn2: float
    iterations: int
    field_response_px: np.ndarray | None = None
    """(k, 2): what the fit reads of each of the given flow fields (px), or None without them."""


def image_shift(prev: np.ndarray, curr: np.ndarray, *, max_iterations: int = 10, tol_px: float = 1e-3,
                border_px: int = 2, fields: np.ndarray | None = None) -> ImageShift | None:
    """The translation from `prev` to `curr` (same shape, float32 grey levels), or None where
    it cannot be found: no texture (H singular) or the fit leaving the images (a shift
    larger than the frame less its border). border_px: pixels at the edge left out of the
    sums (the gradient filter's reach); fields (k, h, w, 2) px: flow fields whose reading by
    the fit is wanted (ImageShift.field_response_px)."""
    if prev.shape != curr.shape or prev.ndim != 2:
        raise ValueError(f"image_shift: two grey images of one shape expected, got {prev.shape} and {curr.shape}")
    h, w = prev.shape
    prev = np.ascontiguousarray(prev, np.float32)
    curr = np.ascontiguousarray(curr, np.float32)
    # Copies: cv2.phaseCorrelate multiplies its inputs by the window in place (OpenCV 4-5).
    (du, dv), _ = cv2.phaseCorrelate(prev.copy(), curr.copy(), _hanning(h, w))
    d = np.array([du, dv], float)
    # The earlier image's gradients (Scharr, DN/px) over its interior: H does not change with d.
    gx = cv2.Scharr(prev, cv2.CV_32F, 1, 0, scale=1.0 / 32.0)
    gy = cv2.Scharr(prev, cv2.CV_32F, 0, 1, scale=1.0 / 32.0)
    xs, ys = _grid(h, w)
    inner = np.zeros((h, w), bool)
    inner[border_px:h - border_px, border_px:w - border_px] = True
    it = 0
    for it in range(1, max_iterations + 1):
        fit = _fit(prev, curr, gx, gy, xs, ys, inner, d)
        if fit is None:
            return None
        step = fit[0]
        d += step
        if not np.all(np.abs(d) < min(h, w) / 2):
            return None
        if np.abs(step).max() < tol_px:
            break
    fit = _fit(prev, curr, gx, gy, xs, ys, inner, d)
    if fit is None:
        return None
    _, H, e, use = fit
    s2 = float(e.var())
    n = e.size
    lam_min = float(np.linalg.eigvalsh(H)[0])
    H_inv = np.linalg.inv(H)
    response = None
    if fields is not None:
        # Over the pixels of the last fit: H^-1 sum g g' f, per field.
        g = np.stack([gx[use], gy[use]], axis=1).astype(np.float64)  # (m, 2)
        f = np.asarray(fields, float)[:, use, :]  # (k, m, 2)
        gf = np.einsum("mi,kmi->km", g, f)  # g' f per pixel
        response = np.einsum("ij,kmj,km->ki", H_inv, g[None], gf)
    return ImageShift(d, s2 * H_inv, math.sqrt(s2), lam_min / n, it, response)


def _fit(prev, curr, gx, gy, xs, ys, inner, d):
    """One Gauss-Newton step from d: (step (2,), H (2, 2), residuals (m,), the pixels used (h, w)
    bool: those whose shifted sample lies inside `curr`), or None without enough of them or
    without texture."""
    warped = cv2.remap(curr, xs + np.float32(d[0]), ys + np.float32(d[1]), cv2.INTER_LINEAR,
                       borderMode=cv2.BORDER_CONSTANT, borderValue=float("nan"))
    use = inner & np.isfinite(warped)
    if use.sum() < 16:
        return None
    g_u = gx[use].astype(np.float64)
    g_v = gy[use].astype(np.float64)
    e = warped[use].astype(np.float64) - prev[use]
    e -= e.mean()  # the brightness offset between frames (exposure, gain)
    H = np.array([[g_u @ g_u, g_u @ g_v], [g_u @ g_v, g_v @ g_v]])
    if not np.linalg.det(H) > 1e-12 * max(np.trace(H), 1e-300) ** 2:
        return None
    step = -np.linalg.solve(H, np.array([g_u @ e, g_v @ e]))
    return step, H, e, use


_GRIDS: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}
_WINDOWS: dict[tuple[int, int], np.ndarray] = {}


def _grid(h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    """Pixel coordinates (h, w) float32 for cv2.remap, one pair per image size."""
    if (h, w) not in _GRIDS:
        xs, ys = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
        _GRIDS[(h, w)] = (xs, ys)
    return _GRIDS[(h, w)]


def _hanning(h: int, w: int) -> np.ndarray:
    """The Hanning window phase correlation weighs the images by (no wrap-around edges)."""
    if (h, w) not in _WINDOWS:
        _WINDOWS[(h, w)] = cv2.createHanningWindow((w, h), cv2.CV_32F)
    return _WINDOWS[(h, w)]
