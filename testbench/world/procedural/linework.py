"""Lines of the procedural worlds: meandering rivers and washes, roads, distance fields."""

from __future__ import annotations

import cv2
import numpy as np

from testbench.world.procedural.noise import CoarseGrid, Field


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


def draw_paths(shape, paths, width_px: float = 1.0, row0: int = 0) -> np.ndarray:
    """Rasterise polylines (list of (N, 2) col,row) into a uint8 (H, W) mask (255 on lines).

    row0: the mask's first row is image row row0 (a band of a larger image).
    """
    m = np.zeros(shape, np.uint8)
    off = np.array([0.0, float(row0)])
    pts = [np.round((p - off) * 4).astype(np.int32).reshape(-1, 1, 2) for p in paths if len(p) > 1]
    if pts:
        cv2.polylines(m, pts, False, 255, thickness=max(1, int(round(width_px))),
                      lineType=cv2.LINE_AA, shift=2)
    return m


def distance_to(mask_u8: np.ndarray) -> np.ndarray:
    """Distance (px, float32) of every pixel to the nearest non-zero pixel of mask."""
    inv = np.where(mask_u8 > 127, 0, 255).astype(np.uint8)
    if inv.all():  # nothing drawn here: "far away", finite
        return np.full(mask_u8.shape, 1e6, np.float32)
    return cv2.distanceTransform(inv, cv2.DIST_L2, 5)


class PathDistance(Field):
    """Distance (px, float32) to polylines, by rows: exact (chamfer 5x5 at full resolution) up to
    near_px, beyond that from a distance transform on the coarse grid (far field, smooth)."""

    def __init__(self, grid: CoarseGrid, shape, paths, near_px: int, width_px: float = 1.0):
        self.width = shape[1]
        self.paths, self.near, self.lw = [np.asarray(p, float) for p in paths], int(near_px), width_px
        cp = [grid.to_px(p) for p in self.paths]
        far = distance_to(draw_paths(grid.shape, cp, max(1.0, width_px / grid.k))) * np.float32(grid.k)
        self.far = grid.field(far)

    def rows(self, r0, r1):
        a, b = r0 - self.near, r1 + self.near
        far = self.far.rows(r0, r1)
        m = draw_paths((b - a, self.width), self.paths, self.lw, row0=a)
        if not (m > 127).any():
            return np.maximum(far, np.float32(self.near), out=far)
        fine = distance_to(m)[self.near:self.near + r1 - r0]
        lim = np.float32(self.near)
        return np.where(fine < lim, fine, np.maximum(far, lim))
