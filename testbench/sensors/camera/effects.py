"""Image-formation effects after the scene: motion blur, vignetting, exposure gain, noise.

Order follows the light: the scene is smeared during the exposure (motion blur), the lens
darkens the corners (vignetting), the exposure/gain scales the signal and saturates, then the
sensor adds noise and quantises to 8 bits.
"""

from __future__ import annotations

from functools import lru_cache

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


@lru_cache(maxsize=8)
def _vignetting_rgb(camera: PinholeCamera, strength: float, gain: float) -> np.ndarray:
    """(H, W, 3) float32 vignetting times gain, cached per camera."""
    g = vignetting_gain(camera, strength) * np.float32(gain)
    out = np.ascontiguousarray(np.repeat(g[..., None], 3, axis=-1))
    out.setflags(write=False)
    return out


def apply_effects(img: np.ndarray, camera: PinholeCamera, opts, rng: np.random.Generator | None) -> np.ndarray:
    """Apply the optional effects of `opts` (RenderOptions) to img (H, W, 3) uint8.

    camera: the camera of this (region of the) frame, for the vignetting geometry. Noise needs
    rng; without one no noise is added. May modify img in place; returns the result.
    """
    kernel = motion_blur_kernel(*opts.motion_blur_px)
    if kernel is not None:
        img = cv2.filter2D(img, -1, kernel, borderType=cv2.BORDER_REFLECT)
    if opts.vignetting > 0:
        scale = _vignetting_rgb(camera, float(opts.vignetting), float(opts.gain))
        img = cv2.multiply(img, scale, dtype=cv2.CV_8U)
    elif opts.gain != 1.0:
        img = cv2.convertScaleAbs(img, alpha=float(opts.gain))  # gain > 0: saturating scale
    if rng is not None and (opts.noise_std > 0 or opts.noise_mean != 0):
        img = add_noise(img, float(opts.noise_mean), float(opts.noise_std), rng)
    return img


# A fresh normal draw per pixel costs several times a whole warp at 1080p. The noise is made
# of windows of a fixed field instead, at offsets drawn from the injected generator (so a
# frame's noise is still a pure function of the scenario's seed stream): each band of
# _NOISE_BAND_PX rows takes its own window. Two windows share a pattern only shifted by a random
# offset; at the noise levels of a camera (a few DN on scenes with tens of DN of texture) that
# correlation is far below the scene's. Bands keep the field small (~3 MB a part at 1080p), so
# it stays in the last-level cache between frames: a frame-sized field (27 MB) did not, and its
# two passes cost 0.3 ms more a frame.
_NOISE_BAND_PX = 128
_NOISE_FIELD_ROWS = 3 * _NOISE_BAND_PX
_NOISE_MARGIN_PX = 509  # odd and prime-ish: offsets do not line up with texture periods
_NOISE_SEED = 0x5EED_CA3


@lru_cache(maxsize=4)
def _noise_field(height: int, width: int, channels: int, mean: float, std: float) -> tuple[np.ndarray, np.ndarray]:
    """(positive, negative) uint8 parts of a rounded N(mean, std^2) field of the given size
    (noise = positive - negative, at most one of them non-zero per element), fixed seed."""
    g = np.random.default_rng(_NOISE_SEED)
    n = g.standard_normal((height, width, channels), dtype=np.float32)
    n *= np.float32(std)
    n += np.float32(mean)
    np.rint(n, out=n)
    np.clip(n, -255, 255, out=n)
    pos = np.maximum(n, 0).astype(np.uint8)
    neg = np.maximum(-n, 0).astype(np.uint8)
    pos.setflags(write=False)
    neg.setflags(write=False)
    return pos, neg


def add_noise(img: np.ndarray, mean: float, std: float, rng: np.random.Generator) -> np.ndarray:
    """img (H, W, C) uint8 plus rounded Gaussian noise N(mean, std^2) per element, saturated
    to 0..255, in place (returned). Draws 2 * ceil(H / 128) integers from rng (the band offsets)."""
    h, w = img.shape[:2]
    c = img.shape[2] if img.ndim == 3 else 1
    # Fields are cached per 256-px width class so that regions of interest share one field.
    fw = -(-w // 256) * 256 + _NOISE_MARGIN_PX
    pos, neg = _noise_field(_NOISE_FIELD_ROWS, fw, c, mean, std)
    if not (img.flags.c_contiguous and img.flags.writeable):
        img = np.array(img, order="C")
    n_bands = -(-h // _NOISE_BAND_PX)
    offsets = rng.integers(0, [_NOISE_FIELD_ROWS - _NOISE_BAND_PX + 1, fw - w + 1], size=(n_bands, 2))
    for b, (dy, dx) in enumerate(offsets.tolist()):
        y0 = b * _NOISE_BAND_PX
        band = img[y0:y0 + _NOISE_BAND_PX]  # rows of a C-contiguous image: contiguous
        rows = band.shape[0]
        p = pos[dy:dy + rows, dx:dx + w].reshape(band.shape)
        n = neg[dy:dy + rows, dx:dx + w].reshape(band.shape)
        cv2.add(band, p, dst=band)  # saturating: img + max(n, 0), then - max(-n, 0) = sat(img + n)
        cv2.subtract(band, n, dst=band)
    return img
