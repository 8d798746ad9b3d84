"""Shared scene elements: tree canopies, buildings with gable roofs, water surfaces."""

from __future__ import annotations

import cv2
import numpy as np

from testbench.world.procedural.appearance import Season, cast_shadow
from testbench.world.procedural.noise import value_noise

TREE_COLOURS = {
    "summer": ((0.10, 0.17, 0.07), (0.20, 0.28, 0.12)),
    "autumn": ((0.30, 0.22, 0.08), (0.45, 0.34, 0.12)),
    "winter": ((0.22, 0.20, 0.18), (0.34, 0.31, 0.28)),
    "spring": ((0.16, 0.25, 0.09), (0.30, 0.40, 0.16)),
}


def crowns(rng: np.random.Generator, shape, gsd_m: float, crown_m: float = 5.0) -> np.ndarray:
    """Crown field 0..1 (float32): blobs of about crown_m across (individual tree crowns)."""
    c = value_noise(rng, shape, max(crown_m / gsd_m, 1.2))
    return c


def paint_trees(rgb, zone: np.ndarray, crown: np.ndarray, season: Season, gsd_m: float,
                tree_height_m: float = 10.0, density: float = 0.5) -> np.ndarray:
    """Paint tree canopy where zone (H, W float 0..1) and the crown field allow; cast shadows.

    density 0..1: fraction of the zone covered by crowns. Returns the canopy mask (bool).
    """
    dens = density * (0.55 if season.name == "winter" else 1.0)
    canopy = (crown * zone) > np.float32(1.0 - dens)
    # shadows first (they fall on the ground beside the trees)
    sh = cast_shadow(canopy, tree_height_m, gsd_m, season)
    rgb *= (1.0 - 0.55 * sh)[..., None]
    dark, light = (np.asarray(c, np.float32) for c in TREE_COLOURS[season.name])
    t = np.clip((crown[canopy] - (1.0 - dens)) / max(dens, 1e-3) * 1.6, 0, 1)[:, None]
    rgb[canopy] = dark + (light - dark) * t
    return canopy


def water_colour(depth01: np.ndarray, season: Season) -> np.ndarray:
    """RGB (N, 3) of water with relative depth 0 (shore) .. 1 (deep)."""
    d = np.clip(depth01, 0, 1)[:, None].astype(np.float32)
    if season.name == "winter":
        return np.float32([0.70, 0.74, 0.78]) + np.float32([0.05, 0.05, 0.05]) * d
    shallow = np.float32([0.22, 0.25, 0.20])
    deep = np.float32([0.07, 0.11, 0.13])
    return shallow + (deep - shallow) * np.sqrt(d)


ROOF_COLOURS = np.float32([
    [0.72, 0.73, 0.74], [0.55, 0.22, 0.17], [0.40, 0.40, 0.42], [0.85, 0.85, 0.83],
    [0.30, 0.31, 0.33], [0.60, 0.45, 0.35], [0.48, 0.52, 0.55],
])


def boxes(cc, rr, ln, wd, ang) -> np.ndarray:
    """Corners (N, 4, 2) (col, row) of rectangles centred (cc, rr), length ln along the image
    angle ang (rad, from +col towards +row), width wd (as cv2.boxPoints, vectorised)."""
    cc, rr, ln, wd, ang = (np.asarray(x, np.float64).reshape(-1) for x in (cc, rr, ln, wd, ang))
    ux, uy = np.cos(ang) * ln / 2, np.sin(ang) * ln / 2
    vx, vy = -np.sin(ang) * wd / 2, np.cos(ang) * wd / 2
    sx = np.array([1, 1, -1, -1])[None, :]
    sy = np.array([1, -1, -1, 1])[None, :]
    return np.stack([cc[:, None] + sx * ux[:, None] + sy * vx[:, None],
                     rr[:, None] + sx * uy[:, None] + sy * vy[:, None]], axis=2)


def fill_polys(canvas: np.ndarray, polys: np.ndarray, row0: int, value) -> None:
    """Fill polygons (N, K, 2) (col, row image coordinates) into canvas whose row 0 is row0."""
    if len(polys):
        p = np.round((polys - np.array([0.0, row0])) * 4).astype(np.int32)
        cv2.fillPoly(canvas, list(p), value, cv2.LINE_8, shift=2)


class Buildings:
    """Buildings: rows of (centre_col, centre_row, length_px, width_px, angle_rad, colour_idx),
    drawn band by band (gable roofs shaded by the sun, walls casting shadows)."""

    def __init__(self, items, height_m: float = 7.0, tone=None):
        a = np.asarray(items, np.float64).reshape(-1, 6)
        self.height_m = height_m
        self.ci = a[:, 5].astype(np.int64) % len(ROOF_COLOURS)
        self.box = boxes(a[:, 0], a[:, 1], a[:, 2], a[:, 3], a[:, 4])
        ca, sa = np.cos(a[:, 4]), np.sin(a[:, 4])
        nx, ny = -sa * a[:, 3] / 4, ca * a[:, 3] / 4
        self.half = boxes(a[:, 0] + nx, a[:, 1] + ny, a[:, 2], a[:, 3] / 2, a[:, 4])
        self.rmin = self.box[:, :, 1].min(axis=1)
        self.rmax = self.box[:, :, 1].max(axis=1)
        # per-building brightness (weathering, material): breaks the palette look
        self.tone = np.ones(len(a), np.float32) if tone is None else np.asarray(tone, np.float32)

    def draw(self, rgb, row0: int, season: Season, gsd_m: float, texture=None) -> np.ndarray:
        """Paint the buildings on rgb (n, W, 3) float32 whose row 0 is image row row0.

        texture: optional (n, W) float32 multiplicative roof texture around 1.
        Returns the footprint mask (n, W) bool.
        """
        h, w = rgb.shape[:2]
        sel = np.flatnonzero((self.rmax >= row0 - 1) & (self.rmin <= row0 + h + 1))
        m = np.zeros((h, w), bool)
        if sel.size == 0:
            return m
        idx = np.zeros((h, w), np.int32)  # building index + 1 (colour, tone)
        half_a = np.zeros((h, w), np.uint8)
        p = np.round((self.box[sel] - np.array([0.0, row0])) * 4).astype(np.int32)
        for j, k in enumerate(sel):
            cv2.fillPoly(idx, [p[j]], int(k) + 1, cv2.LINE_8, shift=2)
        fill_polys(half_a, self.half[sel], row0, 255)
        m = idx > 0
        if not m.any():
            return m
        sh = cast_shadow(m, self.height_m, gsd_m, season)
        sh *= np.float32(-0.6)
        sh += np.float32(1.0)
        rgb *= sh[..., None]
        bid = idx[m].astype(np.int64) - 1
        col = ROOF_COLOURS[self.ci[bid]] * self.tone[bid][:, None]
        ha = half_a[m] > 0
        # sun-facing half brighter; the normal of half A points (nx, ny) in image = (east, south)
        col *= np.where(ha, np.float32(1.12), np.float32(0.80))[:, None]
        if texture is not None:
            col *= texture[m][:, None]
        if season.name == "winter":
            col = col * 0.35 + np.float32(0.88) * 0.65
        rgb[m] = col
        return m


def draw_buildings(rgb, buildings, season: Season, gsd_m: float, height_m: float = 7.0):
    """Whole-image form of Buildings.draw (list of (cc, rr, length, width, angle, colour))."""
    if len(buildings) == 0:
        return np.zeros(rgb.shape[:2], bool)
    return Buildings(buildings, height_m).draw(rgb, 0, season, gsd_m)
