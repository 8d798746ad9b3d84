"""Image-formation effects after the scene: motion blur, vignetting, exposure gain, noise.

Order follows the light: the scene is smeared during the exposure (motion blur), the lens
darkens the corners (vignetting), the exposure/gain scales the signal and saturates, then the
sensor adds noise and quantises to 8 bits.
"""

from __future__ import annotations

import cv2
import numpy as np

from testbench.core.camera_geometry import PinholeCamera


def motion_blur_kernel(du_px: float, dv_px: float) -> np.ndarray | None:
    """Normalised line kernel for an image motion of (du, dv) pixels during the exposure, or
    None when the motion is under half a pixel."""
    length = float(np.hypot(du_px, dv_px))
    if length < 0.5:
        return None
    r = int(np.ceil(length / 2.0)) + 1
    size = 2 * r + 1
    k = np.zeros((size, size), np.float32)
    n = max(2, int(np.ceil(length * 4)))
    s = np.linspace(-0.5, 0.5, n)
    # Splat sub-pixel samples of the segment bilinearly so short blurs stay smooth.
    x = r + s * du_px
    y = r + s * dv_px
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - x0, y - y0
    for dx, dy, w in ((0, 0, (1 - fx) * (1 - fy)), (1, 0, fx * (1 - fy)), (0, 1, (1 - fx) * fy), (1, 1, fx * fy)):
        np.add.at(k, (y0 + dy, x0 + dx), w)
    return k / k.sum()


def vignetting_gain(camera: PinholeCamera, strength: float) -> np.ndarray:
    """(H, W) float32 factor 1 - strength (1 - cos^4 theta), theta the angle off the optical
    axis of each pixel (ideal pinhole angles; lens distortion's small effect on it ignored)."""
    u = (np.arange(camera.width_px) - camera.cx) / camera.fx
    v = (np.arange(camera.height_px) - camera.cy) / camera.fy
    r2 = u[None, :] ** 2 + v[:, None] ** 2
    cos4 = 1.0 / (1.0 + r2) ** 2
    return (1.0 - strength * (1.0 - cos4)).astype(np.float32)


def apply_effects(img: np.ndarray, camera: PinholeCamera, opts, rng: np.random.Generator | None) -> np.ndarray:
    """Apply the optional effects of `opts` (RenderOptions) to img (H, W, 3) uint8.

    camera: the camera of this (region of the) frame, for the vignetting geometry. Noise needs
    rng; without one no noise is added. Returns a new array when anything is applied.
    """
    kernel = motion_blur_kernel(*opts.motion_blur_px)
    if kernel is not None:
        img = cv2.filter2D(img, -1, kernel, borderType=cv2.BORDER_REFLECT)
    scale = None
    if opts.vignetting > 0:
        scale = vignetting_gain(camera, float(opts.vignetting))
    if opts.gain != 1.0:
        scale = np.full(img.shape[:2], opts.gain, np.float32) if scale is None else scale * np.float32(opts.gain)
    if scale is not None:
        img = cv2.multiply(img, cv2.merge([scale, scale, scale]), dtype=cv2.CV_8U)
    if rng is not None and (opts.noise_std > 0 or opts.noise_mean != 0):
        # cv2.randn is ~3x faster than numpy's normal draws at 1080p; its thread-local generator
        # is re-seeded from the injected Generator every frame, so the noise is still a pure
        # function of the scenario's seed stream.
        noise = np.empty(img.shape, np.int16)
        cv2.setRNGSeed(int(rng.integers(0, 2**31 - 1)))
        cv2.randn(noise, float(opts.noise_mean), float(opts.noise_std))
        img = cv2.add(img, noise, dtype=cv2.CV_8U)
    return img
