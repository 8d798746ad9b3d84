"""Seeded noise fields for the procedural worlds (vectorised, deterministic).

Every random draw comes from `stream(seed, name)`: a numpy Generator keyed by the world seed
and a stable name, so that the LAYOUT streams do not depend on the season (appearance streams
add the season to the name) and adding a feature does not reshuffle the others.
"""

from __future__ import annotations

import zlib

import cv2
import numpy as np


def stream(seed: int, name: str) -> np.random.Generator:
    """Independent Generator for (seed, name); stable across runs and platforms."""
    return np.random.default_rng([int(seed) & 0xFFFFFFFF, zlib.crc32(name.encode())])


def value_noise(rng: np.random.Generator, shape: tuple[int, int], cell_px: float) -> np.ndarray:
    """Smooth noise in [0, 1] with feature size ~cell_px: a random lattice, bicubically resized.

    shape (H, W); returns float32 (H, W). The lattice has one node per cell plus a margin, and
    the resize is cropped so that the result is stationary up to the edges.
    """
    h, w = shape
    cell = max(float(cell_px), 1.0)
    gh, gw = int(np.ceil(h / cell)) + 3, int(np.ceil(w / cell)) + 3
    grid = rng.random((gh, gw), dtype=np.float32)
    if cell <= 1.0:
        return grid[:h, :w].copy()
    big = cv2.resize(grid, (int(round(gw * cell)), int(round(gh * cell))),
                     interpolation=cv2.INTER_CUBIC)
    o = int(round(cell))
    out = big[o:o + h, o:o + w]
    return np.clip(out, 0.0, 1.0)


def fbm(rng: np.random.Generator, shape: tuple[int, int], cell_px: float, octaves: int = 5,
        gain: float = 0.5, lacunarity: float = 2.0, min_cell_px: float = 1.5) -> np.ndarray:
    """Fractal (fBm) value noise, float32 (H, W), zero mean and unit std (approximately).

    cell_px: feature size of the first octave; each next octave is `lacunarity` times finer
    and `gain` times weaker. Octaves finer than min_cell_px are skipped.
    """
    out = np.zeros(shape, np.float32)
    amp, cell = 1.0, float(cell_px)
    for _ in range(octaves):
        if cell < min_cell_px:
            break
        out += np.float32(amp) * (value_noise(rng, shape, cell) - np.float32(0.5))
        amp *= gain
        cell /= lacunarity
    s = out.std()
    if s > 0:
        out *= np.float32(1.0 / s)
    return out


def smoothstep(e0: float, e1: float, x: np.ndarray) -> np.ndarray:
    """Hermite step from 0 at e0 to 1 at e1 (float32)."""
    t = np.clip((x - np.float32(e0)) / np.float32(e1 - e0), 0.0, 1.0)
    return t * t * (np.float32(3.0) - np.float32(2.0) * t)


def grid_coords(shape: tuple[int, int], gsd_m: float):
    """Local east (1, W) and north (H, 1) coordinates (m) of pixel centres, world centred at 0."""
    h, w = shape
    east = ((np.arange(w, dtype=np.float32) + 0.5 - w / 2) * gsd_m)[None, :]
    north = ((h / 2 - np.arange(h, dtype=np.float32) - 0.5) * gsd_m)[:, None]
    return east, north


def resize_to(a: np.ndarray, shape: tuple[int, int], interp=cv2.INTER_LINEAR) -> np.ndarray:
    """Resize a 2-D/3-D array to (H, W) with OpenCV."""
    return cv2.resize(a, (shape[1], shape[0]), interpolation=interp)
