"""Grassland (rolling hills, creek with gallery trees, tracks, stock ponds, shrubs) and desert
(dunes, rock outcrops, dry washes, sparse shrubs)."""

from __future__ import annotations

import numpy as np

from testbench.world.procedural.appearance import Season, cast_shadow, finish, hillshade, tint
from testbench.world.procedural.features import crowns, draw_buildings, paint_trees, water_colour
from testbench.world.procedural.linework import distance_to, draw_paths, meander, smooth_path
from testbench.world.procedural.noise import fbm, grid_coords, smoothstep, stream, value_noise


def _shade(rgb, z, gsd_m, season, strength=0.6, exaggeration=1.0):
    hs = hillshade(z, gsd_m, season, exaggeration)
    flat = np.float32(np.sin(season.sun_elevation_rad))
    rgb *= ((1 - strength) + strength * hs / flat)[..., None]


def _tracks(rng, shape, gsd_m, n, wiggle=0.08):
    h, w = shape
    paths = []
    for _ in range(n):
        start = (rng.uniform(0, w), -0.05 * h) if rng.random() < 0.5 else (-0.05 * w, rng.uniform(0, h))
        heading = rng.uniform(0.3, 1.2) if start[1] < 0 else rng.uniform(-0.6, 0.6)
        paths.append(smooth_path(meander(rng, shape, 30.0 / gsd_m, wiggle, start=start, heading=heading)))
    return paths


def _shrubs(rgb, rng_l, zone, season, gsd_m, colour, height_m=1.5, density=0.12):
    c = value_noise(rng_l, zone.shape, max(2.5 / gsd_m, 1.0))
    m = (c * zone) > np.float32(1 - density)
    rgb *= (1 - 0.4 * cast_shadow(m, height_m, gsd_m, season, steps=3))[..., None]
    tint(rgb, m, colour, 0.85)
    return m


def make_grassland(seed: int, shape, gsd_m: float, season: Season):
    h, w = shape
    rng_l = stream(seed, "grass-layout")
    rng_a = stream(seed, f"grass-look-{season.name}")
    z = (22.0 * fbm(rng_l, shape, 1400.0 / gsd_m, 5, min_cell_px=6)).astype(np.float32)
    z += 2.5 * fbm(rng_l, shape, 120.0 / gsd_m, 3, min_cell_px=4)
    creek = smooth_path(meander(rng_l, shape, 30.0 / gsd_m, 0.45))
    cd = distance_to(draw_paths(shape, [creek])) * np.float32(gsd_m)
    z -= 14.0 * np.exp(-cd / 220.0)
    moist = np.exp(-cd / 120.0) + 0.3 * smoothstep(5.0, -25.0, z)
    base = np.float32([[0.50, 0.50, 0.30], [0.66, 0.58, 0.40], [0.74, 0.70, 0.60], [0.40, 0.50, 0.24]][season.index])
    greener = np.float32([[0.30, 0.40, 0.18], [0.46, 0.44, 0.26], [0.60, 0.58, 0.50], [0.26, 0.40, 0.15]][season.index])
    mix = np.clip(moist * 0.8 + 0.25 * fbm(rng_l, shape, 300.0 / gsd_m, 4), 0, 1)[..., None]
    rgb = base + (greener - base) * mix
    del mix
    tex = 0.07 * fbm(rng_a, shape, 90.0 / gsd_m, 4) + 0.05 * fbm(rng_l, shape, 20.0 / gsd_m, 3)
    tex += 0.04 * value_noise(rng_a, shape, 2.0 / gsd_m)
    rgb *= (1 + tex)[..., None]
    del tex
    if season.snow > 0:
        snow = smoothstep(0.2, 0.8, value_noise(rng_a, shape, 150.0 / gsd_m) + 0.25 * fbm(rng_a, shape, 20 / gsd_m, 3))
        tint(rgb, snow, (0.86, 0.87, 0.89), season.snow)
    # stock ponds and creek
    ponds = np.zeros(shape, np.uint8)
    import cv2
    for _ in range(max(1, int(h * w * gsd_m ** 2 / 2.5e6))):
        cc, rr = rng_l.uniform(0, w), rng_l.uniform(0, h)
        r = rng_l.uniform(12, 35) / gsd_m
        cv2.ellipse(ponds, ((cc, rr), (2 * r, 1.6 * r), rng_l.uniform(0, 180)), 255, -1)
    pd = distance_to(ponds) * np.float32(gsd_m)
    rim = (pd > 0) & (pd < 6.0)
    tint(rgb, rim, (0.55, 0.48, 0.38), 0.8)
    pond = ponds > 0
    rgb[pond] = water_colour(np.full(int(pond.sum()), 0.5), season)
    half = 2.0 + 1.0 * season.water_level
    wet = cd < half
    rgb[wet] = water_colour(1 - cd[wet] / half, season)
    # tracks (two-track dirt roads) and a ranch
    tracks = _tracks(rng_l, shape, gsd_m, 3)
    tm = draw_paths(shape, tracks, 3.5 / gsd_m) > 127
    soil = np.float32([0.62, 0.55, 0.45]) if season.name != "winter" else np.float32([0.70, 0.68, 0.64])
    tint(rgb, tm, soil, 0.75)
    if gsd_m <= 1.0:
        mid = draw_paths(shape, tracks, 1.0) > 200
        tint(rgb, mid & tm, base, 0.6)
    # gallery trees along the creek, scattered clumps, shrubs
    zone = np.clip(np.exp(-cd / 35.0) * 1.3, 0, 1) * (0.5 + 0.5 * value_noise(rng_l, shape, 50 / gsd_m))
    clump = fbm(rng_l, shape, 250.0 / gsd_m, 3, min_cell_px=4) > 2.0
    zone[clump] = 0.8
    zone[wet | pond | tm] = 0
    paint_trees(rgb, zone.astype(np.float32), crowns(rng_l, shape, gsd_m, 7.0), season, gsd_m, 9.0, 0.6)
    shrub_zone = (0.4 + 0.6 * value_noise(rng_l, shape, 400 / gsd_m)).astype(np.float32)
    shrub_zone[wet | pond | tm] = 0
    _shrubs(rgb, rng_l, shrub_zone, season, gsd_m, (0.25, 0.30, 0.18), density=0.10)
    p = tracks[0][len(tracks[0]) // 2]
    blds = [(p[0] + rng_l.uniform(20, 60) / gsd_m * s1, p[1] + rng_l.uniform(20, 60) / gsd_m * s2,
             rng_l.uniform(10, 30) / gsd_m, rng_l.uniform(8, 14) / gsd_m, rng_l.uniform(0, np.pi), rng_l.integers(0, 7))
            for s1, s2 in ((1, 1), (-1, 1), (1, -1))]
    draw_buildings(rgb, blds, season, gsd_m, 6.0)
    _shade(rgb, z, gsd_m, season, 0.55)
    return finish(rgb, season, rng_a, gsd_m), z, np.ones(shape, bool)


def make_desert(seed: int, shape, gsd_m: float, season: Season):
    h, w = shape
    rng_l = stream(seed, "desert-layout")
    rng_a = stream(seed, f"desert-look-{season.name}")
    east, north = grid_coords(shape, gsd_m)
    wind = rng_l.uniform(0, np.pi)
    lam = rng_l.uniform(90.0, 150.0)
    warp = 45.0 * fbm(rng_l, shape, 500.0 / gsd_m, 3)
    u = (east * np.float32(np.cos(wind)) + north * np.float32(np.sin(wind)) + warp) / np.float32(lam)
    del warp
    ph = u - np.floor(u)
    prof = np.where(ph < 0.75, ph / 0.75, (1 - ph) / 0.25)  # gentle stoss, steep slip face
    del u, ph
    dune_amp = 12.0 * smoothstep(-1.8, -0.2, fbm(rng_l, shape, 1200.0 / gsd_m, 3))
    z = (dune_amp * prof).astype(np.float32)
    del prof
    import cv2
    z = cv2.GaussianBlur(z, (0, 0), max(1.0, 3.0 / gsd_m))
    z += 25.0 * fbm(rng_l, shape, 1500.0 / gsd_m, 4, min_cell_px=6)
    rock_pot = fbm(rng_l, shape, 700.0 / gsd_m, 5, min_cell_px=2)
    rock = smoothstep(1.1, 1.5, rock_pot)
    ridges = np.abs(fbm(rng_l, shape, 120.0 / gsd_m, 4, min_cell_px=2))
    z += rock * (30.0 + 15.0 * (1.5 - ridges))
    washes = []
    for _ in range(3):
        p0 = smooth_path(meander(rng_l, shape, 25.0 / gsd_m, 0.3))
        washes.append(p0)
        washes.append(p0 + rng_l.normal(0, 6.0 / gsd_m, p0.shape))
    wd = distance_to(draw_paths(shape, washes, 2)) * np.float32(gsd_m)
    wash = smoothstep(22.0, 8.0, wd)
    z -= 3.0 * wash
    sand = np.float32([[0.80, 0.68, 0.52], [0.78, 0.66, 0.50], [0.74, 0.66, 0.56], [0.80, 0.69, 0.53]][season.index])
    tone = 0.06 * fbm(rng_l, shape, 250.0 / gsd_m, 4) + 0.03 * fbm(rng_a, shape, 30.0 / gsd_m, 3)
    tone += 0.03 * value_noise(rng_a, shape, 1.5 / gsd_m)
    rgb = np.empty(shape + (3,), np.float32)
    rgb[...] = sand
    rgb *= (1 + tone)[..., None]
    del tone
    rock_rgb = np.float32([0.50, 0.34, 0.24])
    strata = 0.5 + 0.5 * np.sin(z / 3.0 + 2.0 * fbm(rng_l, shape, 200.0 / gsd_m, 2))
    rr = rock_rgb * (0.8 + 0.35 * strata)[..., None]
    rgb += (rr - rgb) * (rock * 0.9)[..., None]
    del rr, strata
    tint(rgb, wash, (0.86, 0.80, 0.68), 0.35)
    shrub_zone = (0.35 + 0.45 * np.exp(-wd / 30.0) + 0.25 * value_noise(rng_l, shape, 300 / gsd_m)) * (1 - rock)
    col = (0.32, 0.33, 0.22) if season.name != "spring" else (0.30, 0.38, 0.18)
    _shrubs(rgb, rng_l, shrub_zone.astype(np.float32), season, gsd_m, col, density=0.08)
    tracks = _tracks(rng_l, shape, gsd_m, 2, 0.05)
    tm = draw_paths(shape, tracks, 4.0 / gsd_m) > 127
    tint(rgb, tm, (0.70, 0.62, 0.52), 0.6)
    _shade(rgb, z, gsd_m, season, 0.75, 1.0)
    return finish(rgb, season, rng_a, gsd_m), z, np.ones(shape, bool)
