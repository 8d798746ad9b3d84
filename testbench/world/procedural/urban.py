"""Urban world: a street grid (arterials and local streets, two grid orientations) with blocks
of buildings (gable and flat roofs, cast shadows), street trees, parks, parking, cars."""

from __future__ import annotations

import cv2
import numpy as np

from testbench.world.procedural.appearance import Season, finish, tint
from testbench.world.procedural.features import crowns, draw_buildings, paint_trees
from testbench.world.procedural.noise import fbm, grid_coords, stream, value_noise


def make_urban(seed: int, shape, gsd_m: float, season: Season):
    h, w = shape
    rng_l = stream(seed, "urban-layout")
    rng_a = stream(seed, f"urban-look-{season.name}")
    east, north = grid_coords(shape, gsd_m)
    z = (3.0 * fbm(rng_l, shape, 2000.0 / gsd_m, 3, min_cell_px=8)).astype(np.float32)
    # two districts with different grid orientations, split by a warped line
    split = (east * 0.6 + north * 0.8 + 150.0 * fbm(rng_l, shape, 1500 / gsd_m, 2)) > rng_l.uniform(-300, 300)
    th_a, th_b = rng_l.uniform(-0.1, 0.1), rng_l.uniform(0.35, 0.7)
    th = np.where(split, np.float32(th_a), np.float32(th_b))
    u = east * np.cos(th) + north * np.sin(th)
    v = -east * np.sin(th) + north * np.cos(th)
    del th
    bu, bv = rng_l.uniform(90, 130), rng_l.uniform(120, 200)
    iu, iv = np.floor(u / bu), np.floor(v / bv)
    fu, fv = u / bu - iu, v / bv - iv
    du = np.minimum(fu, 1 - fu) * bu
    dv = np.minimum(fv, 1 - fv) * bv
    arterial_u = (iu.astype(np.int64) % 5 == 0) & (fu < 0.5) | ((iu.astype(np.int64) + 1) % 5 == 0) & (fu >= 0.5)
    half = np.where(arterial_u, np.float32(11.0), np.float32(6.0))
    street = (du < half) | (dv < 6.0)
    sidewalk = ((du < half + 2.5) | (dv < 8.5)) & ~street
    block = ((iu.astype(np.int64) * 7919 + iv.astype(np.int64) * 104729 + split * 31) % 1009).astype(np.int32)
    del iu, iv
    # block use: 0 residential, 1 commercial, 2 park, 3 parking
    use_tab = rng_l.choice(4, 1009, p=[0.6, 0.22, 0.1, 0.08])
    use = use_tab[block]
    rgb = np.empty(shape + (3,), np.float32)
    grass = np.float32([[0.34, 0.42, 0.22], [0.45, 0.44, 0.28], [0.82, 0.82, 0.83], [0.36, 0.46, 0.22]][season.index])
    rgb[...] = grass
    rgb *= (1 + 0.08 * fbm(rng_a, shape, 15.0 / gsd_m, 3) + 0.04 * value_noise(rng_a, shape, 2 / gsd_m))[..., None]
    tint(rgb, use == 3, (0.42, 0.42, 0.43), 1.0)
    tint(rgb, use == 1, (0.55, 0.54, 0.52), 0.8)
    tint(rgb, street, (0.27, 0.27, 0.28), 1.0)
    tint(rgb, sidewalk, (0.66, 0.65, 0.62), 1.0)
    if gsd_m <= 1.0:
        mark = street & (np.abs(du - 0.0) < 0.3 * gsd_m + 0.15) & arterial_u
        tint(rgb, mark, (0.85, 0.82, 0.55), 0.8)
    # buildings: residential houses along the block edges, commercial big boxes
    blds = []
    cols = np.arange(0, w, max(1, int(8 / gsd_m)))
    rows = np.arange(0, h, max(1, int(8 / gsd_m)))
    rr, cc = np.meshgrid(rows, cols, indexing="ij")
    fuu, fvv = fu[rr, cc], fv[rr, cc]
    dd = np.minimum(du[rr, cc], dv[rr, cc])
    uu = use[rr, cc]
    res = (uu == 0) & (dd > 16.0) & (dd < 30.0)
    sel = np.flatnonzero(res.ravel())
    sel = sel[rng_l.random(sel.size) < 0.3]
    def ang(r0, c0):  # the u axis of the local grid, as an image angle
        return -(th_a if split[r0, c0] else th_b)

    for k in sel:
        r0, c0 = int(rr.ravel()[k]), int(cc.ravel()[k])
        blds.append((float(c0), float(r0), rng_l.uniform(10, 16) / gsd_m, rng_l.uniform(8, 12) / gsd_m,
                     ang(r0, c0) + (np.pi / 2 if dv[r0, c0] < du[r0, c0] else 0.0), int(rng_l.integers(0, 7))))
    com = np.flatnonzero(((uu == 1) & (np.abs(fuu - 0.5) < 0.05) & (np.abs(fvv - 0.5) < 0.05)).ravel())
    for k in com:
        r0, c0 = int(rr.ravel()[k]), int(cc.ravel()[k])
        blds.append((float(c0), float(r0), rng_l.uniform(40, 80) / gsd_m, rng_l.uniform(30, 60) / gsd_m,
                     ang(r0, c0), int(rng_l.integers(0, 7))))
    del fuu, fvv, dd, uu
    foot = draw_buildings(rgb, blds, season, gsd_m, 8.0)
    # cars on streets (small coloured rectangles) and in parking lots
    car = (value_noise(rng_l, shape, 2.0 / gsd_m) > 0.83) & (street & ~(du < 1.5) | (use == 3)) & (value_noise(rng_l, shape, 6 / gsd_m) > 0.6)
    colours = np.float32([[0.8, 0.8, 0.8], [0.15, 0.15, 0.17], [0.6, 0.1, 0.1], [0.2, 0.3, 0.5], [0.5, 0.5, 0.5]])
    ci = (value_noise(rng_l, shape, 3.0 / gsd_m) * 5).astype(np.int64).clip(0, 4)
    rgb[car] = colours[ci[car]]
    del ci, car
    # trees: parks, yards, streets
    zone = np.where(use == 2, np.float32(0.8), np.float32(0.0))
    zone[(use == 0) & ~street & ~sidewalk] = 0.45
    zone[sidewalk] = 0.5
    zone[foot | street] = 0
    paint_trees(rgb, zone, crowns(rng_l, shape, gsd_m, 7.0), season, gsd_m, 10.0, 0.45)
    return finish(rgb, season, rng_a, gsd_m), z, np.ones(shape, bool)
