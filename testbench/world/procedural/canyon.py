"""Canyon world: a plateau of layered rock cut by a meandering main canyon with tributaries,
terraced walls (hard and soft strata), then flow-accumulation-driven gully incision and thermal
erosion at coarse resolution, upsampled with fine roughness; hillshade-consistent colouring."""

from __future__ import annotations

import cv2
import numpy as np

from testbench.world.procedural.appearance import Season, finish, hillshade, terrain_shadow, tint
from testbench.world.procedural.features import crowns, paint_trees, water_colour
from testbench.world.procedural.linework import distance_to, draw_paths, meander, smooth_path
from testbench.world.procedural.noise import fbm, resize_to, smoothstep, stream, value_noise

_D8 = [(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)]


def _flow_accumulation(z: np.ndarray, iters: int) -> np.ndarray:
    """D8 flow accumulation (cells draining through each cell) by repeated pushing (vectorised)."""
    h, w = z.shape
    zp = np.pad(z, 1, mode="edge")
    best = np.zeros((h, w), np.float32)
    rcv = np.full((h, w), -1, np.int64)
    idx = np.arange(h * w).reshape(h, w)
    rr, cc = np.mgrid[0:h, 0:w]
    for dr, dc in _D8:
        drop = (z - zp[1 + dr:1 + dr + h, 1 + dc:1 + dc + w]) / np.hypot(dr, dc)
        sel = drop > best
        best[sel] = drop[sel]
        tr = np.clip(rr + dr, 0, h - 1)
        tc = np.clip(cc + dc, 0, w - 1)
        rcv[sel] = idx[tr, tc][sel]
    has = rcv.ravel() >= 0
    src = np.flatnonzero(has)
    dst = rcv.ravel()[has]
    acc = np.ones(h * w, np.float64)
    flow = np.ones(h * w, np.float64)
    for _ in range(iters):
        moved = np.bincount(dst, weights=flow[src], minlength=h * w)
        if not moved.any():
            break
        acc += moved
        flow = moved
    return acc.reshape(h, w).astype(np.float32), best


def _thermal(z, talus, iters, rate=0.25):
    for _ in range(iters):
        zp = np.pad(z, 1, mode="edge")
        dz = np.zeros_like(z)
        for dr, dc in _D8[1::2]:
            nb = zp[1 + dr:1 + dr + z.shape[0], 1 + dc:1 + dc + z.shape[1]]
            d = z - nb
            mv = np.where(d > talus, (d - talus) * rate * 0.25, 0.0)
            dz -= mv
            dz += np.roll(np.roll(mv, dr, 0), dc, 1)
        z = z + dz
    return z


def make_canyon(seed: int, shape, gsd_m: float, season: Season):
    h, w = shape
    rng_l = stream(seed, "canyon-layout")
    rng_a = stream(seed, f"canyon-look-{season.name}")
    size_m = h * gsd_m
    n = int(min(512, max(64, h // 4)))
    cg = size_m / n  # coarse cell (m)
    cs = (n, n)
    plateau = 18.0 * fbm(rng_l, cs, 2500.0 / cg, 4)
    depth = rng_l.uniform(220.0, 320.0)
    main = smooth_path(meander(rng_l, cs, 60.0 / cg, 0.3))
    paths = [main]
    widths = [rng_l.uniform(450.0, 650.0)]
    for k in rng_l.integers(len(main) // 8, len(main) - len(main) // 8, 9):
        side = rng_l.choice([-1.0, 1.0])
        d = main[min(k + 1, len(main) - 1)] - main[k]
        hd = np.arctan2(d[1], d[0]) + side * rng_l.uniform(0.9, 1.6)
        trib = smooth_path(meander(rng_l, cs, 50.0 / cg, 0.4, start=tuple(main[k]), heading=hd,
                                   max_steps=int(rng_l.uniform(600.0, 1800.0) / 50.0)))
        paths.append(trib)
        widths.append(rng_l.uniform(150.0, 300.0))
    cut = np.zeros(cs, np.float32)
    wall_noise = 0.25 * fbm(rng_l, cs, 300.0 / cg, 4, min_cell_px=1)
    for i, (p, wd) in enumerate(zip(paths, widths)):
        dist = distance_to(draw_paths(cs, [p])) * np.float32(cg)
        x = dist / np.float32(wd) * (1.0 + wall_noise)
        prof = np.clip(1.0 - x, 0.0, 1.0) ** 1.6
        if i > 0:  # tributaries: shallower, fading towards their heads
            along = np.linspace(1.0, 0.2, len(p))
            fade = np.zeros(cs, np.float32)
            pts = np.round(p).astype(int)
            ok = (pts[:, 0] >= 0) & (pts[:, 0] < n) & (pts[:, 1] >= 0) & (pts[:, 1] < n)
            fade[pts[ok, 1], pts[ok, 0]] = along[ok]
            fade = cv2.dilate(fade, np.ones((int(2 * wd / cg) | 1,) * 2, np.uint8))
            prof *= fade * 0.8
        cut = np.maximum(cut, prof)
    # strata: hard layers form cliffs, soft layers benches (terraced walls)
    zc = plateau - depth * cut
    layer = 38.0
    t = (zc + 1000.0) / layer
    frac = t - np.floor(t)
    zc = (np.floor(t) + smoothstep(0.0, 0.35, frac) * 0.8 + 0.2 * frac) * layer - 1000.0
    zc = zc.astype(np.float32) + 2.0 * fbm(rng_l, cs, 60.0 / cg, 3, min_cell_px=1)
    # gullies: incision by stream power (accumulated flow, local slope), then talus slumping
    for _ in range(3):
        acc, slope = _flow_accumulation(zc, 3 * n)
        zc -= np.clip(0.5 * np.sqrt(acc) * np.minimum(slope, 2.0), 0, 12.0)
        zc = _thermal(zc, talus=1.2 * cg, iters=4)
    acc = _flow_accumulation(zc, 3 * n)[0]
    # upsample: cubic + fine roughness
    z = resize_to(zc.astype(np.float32), shape, cv2.INTER_CUBIC)
    z += 1.5 * fbm(rng_l, shape, 25.0 / gsd_m, 3, min_cell_px=2)
    river_d = distance_to(draw_paths(cs, [main])) * np.float32(cg)
    river_d = resize_to(river_d, shape)
    z -= 4.0 * smoothstep(30.0, 0.0, river_d)
    # --- appearance: rock colour by stratum, slope; benches with scrub; river and riparian
    band = np.sin((z + 1000.0) / 9.0 + 1.2 * fbm(rng_l, shape, 400.0 / gsd_m, 2)) * 0.5 + 0.5
    rock_a = np.float32([0.66, 0.42, 0.28])
    rock_b = np.float32([0.80, 0.66, 0.50])
    rgb = rock_a + (rock_b - rock_a) * band[..., None]
    del band
    rgb *= (1 + 0.06 * fbm(rng_a, shape, 60.0 / gsd_m, 4) + 0.05 * value_noise(rng_a, shape, 2.0 / gsd_m))[..., None]
    gy = cv2.Sobel(z, cv2.CV_32F, 0, 1, ksize=3) / np.float32(8 * gsd_m)
    gx = cv2.Sobel(z, cv2.CV_32F, 1, 0, ksize=3) / np.float32(8 * gsd_m)
    slope = np.sqrt(gx * gx + gy * gy)
    del gx, gy
    flat = smoothstep(0.5, 0.15, slope)
    veg = np.float32([[0.42, 0.42, 0.30], [0.50, 0.44, 0.32], [0.80, 0.80, 0.80], [0.40, 0.44, 0.28]][season.index])
    tint(rgb, flat * (0.35 + 0.3 * value_noise(rng_l, shape, 80 / gsd_m)), veg, 1.0)
    if season.snow > 0:
        tint(rgb, flat * smoothstep(-40.0, 20.0, z), (0.88, 0.88, 0.90), season.snow)
    scrub = flat * smoothstep(0.3, 0.7, value_noise(rng_l, shape, 200 / gsd_m))
    paint_trees(rgb, scrub.astype(np.float32), crowns(rng_l, shape, gsd_m, 3.0), season, gsd_m, 4.0, 0.25)
    half = 12.0 + 4.0 * season.water_level
    wet = river_d < half
    rgb[wet] = water_colour(1 - river_d[wet] / half, season) * np.float32([1.4, 1.3, 1.0])
    rip = ((river_d >= half) & (river_d < half + 15.0)).astype(np.float32) * 0.7
    paint_trees(rgb, rip, crowns(rng_l, shape, gsd_m, 6.0), season, gsd_m, 8.0, 0.6)
    del flat, scrub, rip, slope
    hs = hillshade(z, gsd_m, season)
    sh = resize_to(terrain_shadow(zc.astype(np.float32), cg, season, max_len_px=n // 2), shape)
    sh = cv2.GaussianBlur(sh, (0, 0), 2.0)
    light = 0.25 + 0.95 * hs * (1 - 0.85 * sh)
    rgb *= light[..., None]
    del hs, sh, light
    return finish(rgb, season, rng_a, gsd_m), z, np.ones(shape, bool)
