"""Appearance-robust images for area-based matching across seasons and years.

The reference map is another season or year than the camera sees: field brightness changes and
even inverts, while boundaries (roads, field edges, shores, buildings) stay. Matching raw
intensity fails; these transforms keep the structure and drop the photometry:

- "gradmag": magnitude of the smoothed image gradient (blind to contrast sign), divided by its
  local mean (blind to local contrast), compressed by a square root;
- "clahe": locally contrast-equalised intensity (for same-season or same-raster work).

Pixels within 2 px of invalid ones are zeroed and dropped from the mask so that frame edges and
no-data borders do not create false gradients.
"""

from __future__ import annotations

import cv2
import numpy as np

FEATURES = ("gradmag", "clahe")


def robust_image(img: np.ndarray, valid: np.ndarray | None, kind: str = "gradmag",
                 sigma_px: float = 1.0, norm_px: int = 15) -> tuple[np.ndarray, np.ndarray]:
    """(feature (H, W) float32, valid (H, W) bool) of a grey image (float32 in [0, 1] or uint8).

    sigma_px: Gaussian pre-smoothing; norm_px: box size of the local normalisation.
    """
    # Called ~26 times per frame on tile crops: the all-valid case (most tiles) skips the mask
    # work, and the steps below run in place, without changing a bit of the result.
    x = img.astype(np.float32)
    if img.dtype == np.uint8:
        x *= np.float32(1 / 255.0)
    all_valid = valid is None or bool(valid.all())
    v8 = None
    if not all_valid:
        # Fill invalid with the valid mean so the border step does not dominate the smoothing.
        mean = float(x[valid].mean()) if valid.any() else 0.0
        x = np.where(valid, x, np.float32(mean))
        v8 = cv2.erode(valid.astype(np.uint8), np.ones((5, 5), np.uint8))
    if kind == "gradmag":
        if sigma_px > 0:
            x = cv2.GaussianBlur(x, (0, 0), sigma_px)
        gx = cv2.Sobel(x, cv2.CV_32F, 1, 0, ksize=3)
        gy = cv2.Sobel(x, cv2.CV_32F, 0, 1, ksize=3)
        # Not cv2.magnitude: through OpenCV's IPP HAL (ippsMagnitude_32f) its last bit depends
        # on the address of the output buffer (mod 32 bytes: which elements go through the
        # vector loop and which through the head and tail code, which round differently, follows
        # it), and numpy puts that buffer wherever the heap has room, so the same frame gave
        # features, hence ISMN fixes, that differed from run to run. A square, a sum and a
        # square root are each correctly rounded whatever code path computes them.
        # In place: gx and gy are this function's own arrays (no extra image-sized buffer).
        mag = np.sqrt(np.add(np.square(gx, out=gx), np.square(gy, out=gy), out=gx), out=gx)
        local = cv2.boxFilter(mag, -1, (norm_px, norm_px))
        local += np.float32(1e-3 + 0.1 * cv2.mean(local)[0])
        f = cv2.sqrt(np.divide(mag, local, out=mag))
    elif kind == "clahe":
        u8 = np.clip(x * 255, 0, 255).astype(np.uint8)
        clahe = cv2.createCLAHE(clipLimit=2.0, tileGridSize=(8, 8))
        f = clahe.apply(u8).astype(np.float32) / 255.0
        if sigma_px > 0:
            f = cv2.GaussianBlur(f, (0, 0), sigma_px)
    else:
        raise ValueError(f"unknown feature kind {kind!r}; expected one of {FEATURES}")
    if all_valid:
        return f, np.ones(f.shape, bool)
    f = f * v8.astype(np.float32)
    return f, v8.astype(bool)
