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


def draw_buildings(rgb, buildings, season: Season, gsd_m: float, height_m: float = 7.0):
    """Buildings: list of (centre_col, centre_row, length_px, width_px, angle_rad, colour_idx).

    Gable roofs: the two halves along the ridge are shaded by the sun; walls cast shadows.
    Returns the footprint mask (bool).
    """
    h, w = rgb.shape[:2]
    foot = np.zeros((h, w), np.uint8)
    half_a = np.zeros((h, w), np.uint8)
    idx = np.zeros((h, w), np.uint8)
    for (cc, rr, ln, wd, ang, ci) in buildings:
        box = cv2.boxPoints(((cc, rr), (ln, wd), np.degrees(ang)))
        cv2.fillPoly(foot, [np.round(box * 4).astype(np.int32)], 255, cv2.LINE_8, shift=2)
        cv2.fillPoly(idx, [np.round(box * 4).astype(np.int32)], int(ci) + 1, cv2.LINE_8, shift=2)
        # one half of the gable: the side towards +normal of the ridge
        ca, sa = np.cos(ang), np.sin(ang)
        nx, ny = -sa * wd / 4, ca * wd / 4
        half = cv2.boxPoints(((cc + nx, rr + ny), (ln, wd / 2), np.degrees(ang)))
        cv2.fillPoly(half_a, [np.round(half * 4).astype(np.int32)], 255, cv2.LINE_8, shift=2)
    m = foot > 0
    if not m.any():
        return m
    sh = cast_shadow(m, height_m, gsd_m, season)
    rgb *= (1.0 - 0.6 * sh)[..., None]
    col = ROOF_COLOURS[(idx[m].astype(np.int64) - 1) % len(ROOF_COLOURS)]
    ha = half_a[m] > 0
    # sun-facing half brighter; the normal of half A points (nx, ny) in image = (east, south)
    light = np.float32(1.12)
    dark = np.float32(0.80)
    rgb[m] = col * np.where(ha, light, dark)[:, None]
    if season.name == "winter":
        rgb[m] = rgb[m] * 0.35 + np.float32(0.88) * 0.65
    return m
