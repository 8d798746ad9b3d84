"""Lines of the procedural worlds: meandering rivers and washes, roads, distance fields."""

from __future__ import annotations

import cv2
import numpy as np


def meander(rng: np.random.Generator, shape: tuple[int, int], step_px: float,
            wiggle: float = 0.25, start=None, heading=None, max_steps: int | None = None):
    """A meandering path (N, 2) of (col, row) pixel coordinates crossing the image.

    Heading follows a mean-reverting random process (meanders); starts on the west edge with an
    eastward heading unless `start` / `heading` are given; stops when it leaves the image (with
    a margin) or after max_steps.
    """
    h, w = shape
    if start is None:
        start = (-0.05 * w, rng.uniform(0.2, 0.8) * h)
    if heading is None:
        heading = rng.uniform(-0.5, 0.5)
    mean_heading = heading
    pts = [np.array(start, float)]
    turn = 0.0
    max_steps = max_steps or int(4 * (h + w) / step_px)
    for _ in range(max_steps):
        turn = 0.85 * turn + rng.normal(0.0, wiggle)
        heading += 0.35 * turn - 0.08 * (heading - mean_heading)
        # bounded deviation: meanders, never loops back across itself
        heading = mean_heading + float(np.clip(heading - mean_heading, -1.1, 1.1))
        p = pts[-1] + step_px * np.array([np.cos(heading), np.sin(heading)])
        pts.append(p)
        if not (-0.1 * w <= p[0] <= 1.1 * w and -0.1 * h <= p[1] <= 1.1 * h):
            break
    return np.array(pts)


def smooth_path(path: np.ndarray, times: int = 2) -> np.ndarray:
    """Chaikin corner cutting: a smoother polyline with the same ends."""
    for _ in range(times):
        q = 0.75 * path[:-1] + 0.25 * path[1:]
        r = 0.25 * path[:-1] + 0.75 * path[1:]
        mid = np.empty((2 * len(q), 2))
        mid[0::2], mid[1::2] = q, r
        path = np.vstack([path[:1], mid, path[-1:]])
    return path


def draw_paths(shape, paths, width_px: float = 1.0) -> np.ndarray:
    """Rasterise polylines (list of (N, 2) col,row) into a uint8 (H, W) mask (255 on lines)."""
    m = np.zeros(shape, np.uint8)
    pts = [np.round(p * 4).astype(np.int32).reshape(-1, 1, 2) for p in paths if len(p) > 1]
    if pts:
        cv2.polylines(m, pts, False, 255, thickness=max(1, int(round(width_px))),
                      lineType=cv2.LINE_AA, shift=2)
    return m


def distance_to(mask_u8: np.ndarray) -> np.ndarray:
    """Distance (px, float32) of every pixel to the nearest non-zero pixel of mask."""
    inv = np.where(mask_u8 > 127, 0, 255).astype(np.uint8)
    return cv2.distanceTransform(inv, cv2.DIST_L2, 5)
