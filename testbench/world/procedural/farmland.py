"""Farmland (and the field layout other terrains reuse): districts of rectangular fields with
varied sizes and orientations, crop rows, margins, section roads, a river, prairie lakes,
shelterbelts and groves, farmsteads. Same seed -> same layout whatever the season.
"""

from __future__ import annotations

import cv2
import numpy as np

from testbench.world.procedural.appearance import Season, finish, hillshade, tint
from testbench.world.procedural.features import (crowns, draw_buildings, paint_trees,
                                                 water_colour)
from testbench.world.procedural.linework import distance_to, draw_paths, meander, smooth_path
from testbench.world.procedural.noise import fbm, grid_coords, resize_to, stream, value_noise

# crop: wheat, corn, soy, fallow, hay, canola. colour per season (summer, autumn, winter, spring)
_CROP_RGB = np.float32([
    # wheat                 corn                  soy                   fallow                hay                   canola
    [[0.62, 0.58, 0.36], [0.22, 0.34, 0.13], [0.30, 0.44, 0.17], [0.47, 0.41, 0.29], [0.44, 0.49, 0.28], [0.76, 0.70, 0.26]],
    [[0.72, 0.65, 0.50], [0.63, 0.56, 0.39], [0.56, 0.47, 0.28], [0.34, 0.28, 0.22], [0.52, 0.50, 0.35], [0.62, 0.57, 0.44]],
    [[0.86, 0.86, 0.86], [0.74, 0.72, 0.68], [0.84, 0.84, 0.84], [0.80, 0.80, 0.81], [0.83, 0.83, 0.82], [0.80, 0.79, 0.77]],
    [[0.36, 0.43, 0.22], [0.44, 0.36, 0.28], [0.40, 0.33, 0.26], [0.38, 0.31, 0.24], [0.36, 0.48, 0.22], [0.34, 0.40, 0.20]],
])
# row contrast per season and crop
_ROW_AMP = np.float32([
    [0.03, 0.06, 0.05, 0.02, 0.01, 0.02],
    [0.07, 0.08, 0.05, 0.08, 0.02, 0.06],
    [0.06, 0.10, 0.05, 0.04, 0.02, 0.05],
    [0.12, 0.07, 0.06, 0.08, 0.02, 0.10],
])
_N_ATTR = 4093


def field_layout(seed: int, shape, gsd_m: float, mean_field_m: float = 350.0):
    """Partition of the world into districts and rectangular fields.

    Returns dict: district (H, W) int32, u, v (H, W) float32 field-aligned coordinates (m),
    attr (H, W) int32 index 0.._N_ATTR-1 into per-field attribute tables, edge_m (H, W) float32
    distance to the nearest field boundary (m), road_m (H, W) float32 distance to the nearest
    section road (m), belt (H, W) bool shelterbelt boundaries.
    """
    h, w = shape
    rng = stream(seed, "fields")
    east, north = grid_coords(shape, gsd_m)
    size_m = max(h, w) * gsd_m
    # districts: warped Voronoi at quarter resolution
    q = 4
    qs = (max(2, h // q), max(2, w // q))
    k = int(np.clip(round((size_m / 1800.0) ** 2 * 1.5), 2, 60))
    seeds = rng.uniform(-0.6 * size_m, 0.6 * size_m, (k, 2))
    qe, qn = grid_coords(qs, gsd_m * h / qs[0])
    warp = 120.0 * fbm(rng, qs, 700.0 / (gsd_m * q), 3)
    best = np.full(qs, np.inf, np.float32)
    dist_id = np.zeros(qs, np.int32)
    for i, (sn, se) in enumerate(seeds):
        d = (qe + warp - se) ** 2 + (qn - warp - sn) ** 2
        sel = d < best
        best[sel] = d[sel]
        dist_id[sel] = i
    border_q = cv2.morphologyEx(dist_id.astype(np.uint8), cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8)) > 0
    district = resize_to(dist_id, shape, cv2.INTER_NEAREST)
    border = resize_to(border_q.astype(np.uint8) * 255, shape, cv2.INTER_LINEAR) > 127
    theta0 = rng.uniform(-0.25, 0.25)
    dev = rng.choice([0.0, 0.0, 0.0, 1.0], k) * rng.uniform(-0.6, 0.6, k)
    theta = (theta0 + dev).astype(np.float32)
    cs, sn_ = np.cos(theta)[district], np.sin(theta)[district]
    off = rng.uniform(0, 1600.0, (k, 2)).astype(np.float32)
    u = east * cs + north * sn_ + off[district, 0]
    v = -east * sn_ + north * cs
    v += off[district, 1]
    del cs, sn_
    lim = 1.6 * size_m + 3200.0
    # strips across u with varied widths
    widths = rng.choice([0.25, 0.5, 0.5, 1.0, 1.0, 1.5], 4096) * mean_field_m * rng.uniform(0.85, 1.15, 4096)
    ub = np.cumsum(widths) - lim
    ub = ub[: np.searchsorted(ub, lim) + 2].astype(np.float32)
    ns = len(ub)
    s = np.clip(np.searchsorted(ub, u), 1, ns - 1)
    du = np.minimum(u - ub[s - 1], ub[s] - u)
    u_road = (np.arange(ns) % rng.integers(3, 6)) == 0
    u_belt = rng.random(ns) < 0.15
    near_lo = (u - ub[s - 1]) < (ub[s] - u)
    nb = np.where(near_lo, s - 1, s)
    # per-strip field lengths along v (flattened with an offset per strip)
    nv = int(2 * lim / (0.3 * mean_field_m)) + 4
    lens = rng.choice([0.5, 1.0, 1.0, 2.0, 3.0], (ns, nv)) * mean_field_m * rng.uniform(0.8, 1.2, (ns, nv))
    vb = np.cumsum(lens, axis=1) - lim - rng.uniform(0, 2 * mean_field_m, (ns, 1))
    big = np.float32(8.0 * lim)
    flat = (vb + (np.arange(ns)[:, None] * 8.0 * lim)).ravel()
    key = v + s.astype(np.float32) * big
    kk = np.clip(np.searchsorted(flat, key), 1, flat.size - 1)
    dv = np.minimum(key - flat[kk - 1], flat[kk] - key)
    field = (s.astype(np.int64) * nv + kk) * 2654435761 + district.astype(np.int64) * 97531
    attr = (field % _N_ATTR).astype(np.int32)
    del field, key, kk
    edge = np.minimum(du, dv).astype(np.float32)
    # section roads: some strip boundaries plus a regular cross grid in v; district borders
    vspace = float(rng.choice([1600.0, 1600.0, 3200.0]))
    vr = np.abs(((v + 0.5 * vspace) % vspace) - 0.5 * vspace)
    road = np.where(u_road[nb], du, np.float32(1e4))
    road = np.minimum(road, vr).astype(np.float32)
    road[border] = 0.0
    belt = u_belt[nb] & (du < 14.0)
    return dict(district=district, u=u, v=v, attr=attr, edge_m=edge, road_m=road, belt=belt,
                theta=theta)


def make_farmland(seed: int, shape, gsd_m: float, season: Season):
    """Farmland world: (rgb uint8 (H, W, 3), elevation float32 (H, W) m, valid bool)."""
    h, w = shape
    lay = field_layout(seed, shape, gsd_m)
    rng_l = stream(seed, "farm-layout")
    rng_a = stream(seed, f"farm-look-{season.name}")
    # --- relief and water (layout)
    z = (5.0 * fbm(rng_l, shape, 1500.0 / gsd_m, 4, min_cell_px=8)).astype(np.float32)
    river = smooth_path(meander(rng_l, shape, 40.0 / gsd_m, 0.35))
    rd = distance_to(draw_paths(shape, [river])) * np.float32(gsd_m)
    z -= 6.0 * np.exp(-rd / 250.0)
    lake_pot = fbm(rng_l, shape, 450.0 / gsd_m, 5, gain=0.55, min_cell_px=3) - 0.04 * z
    attr_rng = stream(seed, "field-attrs")
    crop = attr_rng.choice(6, _N_ATTR, p=[0.26, 0.22, 0.2, 0.1, 0.14, 0.08])
    row_dir = attr_rng.random(_N_ATTR) < 0.5
    row_period = attr_rng.uniform(3.0, 7.0, _N_ATTR).astype(np.float32)
    tram = attr_rng.uniform(16.0, 28.0, _N_ATTR).astype(np.float32)
    jitter = attr_rng.normal(0, 0.035, (_N_ATTR, 3)).astype(np.float32)
    # --- field colours (appearance)
    a = lay["attr"]
    sidx = season.index
    base = _CROP_RGB[sidx][crop][a] + jitter[a]
    along = np.where(row_dir[a], lay["u"], lay["v"])
    per = row_period[a]
    amp = _ROW_AMP[sidx][crop][a] * np.clip((per / gsd_m - 2.0) / 2.0, 0.0, 1.0)
    rows = np.sin(along * (2 * np.pi) / per) * amp
    tl = np.abs(((along + 3.0) % tram[a]) - 0.5 * tram[a]) < max(0.8, 0.6 * gsd_m)
    rows -= np.where(tl & (crop[a] < 3) & (sidx != 2), np.float32(0.06), np.float32(0.0))
    del along, per, amp, tl
    patch = 0.045 * fbm(rng_a, shape, 180.0 / gsd_m, 5) + 0.04 * fbm(rng_l, shape, 60.0 / gsd_m, 4)
    patch += 0.03 * value_noise(rng_a, shape, 2.5 / gsd_m)
    wet = np.clip(-z / 12.0, -0.5, 1.0) * 0.05  # low ground is darker (moisture)
    shade = (1.0 + patch - wet + rows).astype(np.float32)
    del patch, rows, wet
    rgb = base * shade[..., None]
    del base, shade
    if season.name == "winter":
        snow_var = 0.08 * fbm(rng_a, shape, 60.0 / gsd_m, 3)
        rgb += snow_var[..., None]
        del snow_var
    # --- field margins and shelterbelts
    grass = np.float32([[0.36, 0.44, 0.22], [0.50, 0.47, 0.30], [0.80, 0.80, 0.80], [0.38, 0.48, 0.22]][sidx])
    margin = lay["edge_m"] < np.float32(max(1.2, 1.0 * gsd_m))
    rgb[margin] = grass * (0.9 + 0.2 * value_noise(rng_a, shape, 3.0)[margin][:, None])
    del margin
    # --- lakes and wetland (water level by season)
    level = np.float32(2.0 - 0.15 * season.water_level)
    shore = (lake_pot > level - 0.12) & (lake_pot <= level)
    rim = (lake_pot > level - 0.03) & (lake_pot <= level) & (season.water_level < 0.5)
    wet_rgb = np.float32([[0.25, 0.33, 0.16], [0.42, 0.38, 0.24], [0.78, 0.78, 0.77], [0.24, 0.32, 0.15]][sidx])
    tint(rgb, shore, wet_rgb, 0.8)
    tint(rgb, rim, np.float32([0.80, 0.78, 0.74]), 0.7)  # salt / mud rim of prairie potholes
    lake = lake_pot > level
    rgb[lake] = water_colour((lake_pot[lake] - level) / 0.8, season)
    # --- river
    half = (7.0 + 2.0 * season.water_level) / gsd_m
    riv = rd < half * gsd_m
    rgb[riv] = water_colour(1.0 - rd[riv] / (half * gsd_m), season)
    water = lake | riv
    # --- roads
    road_w = np.float32(3.5)
    on_road = (lay["road_m"] < road_w) & ~water
    gravel = np.float32([[0.66, 0.62, 0.55], [0.64, 0.60, 0.53], [0.62, 0.60, 0.58], [0.60, 0.56, 0.50]][sidx])
    rn = value_noise(rng_a, shape, 2.0)[on_road][:, None]
    rgb[on_road] = gravel * (0.9 + 0.15 * rn)
    del rn
    rgb[(lay["road_m"] > road_w) & (lay["road_m"] < road_w + 1.5) & ~water] *= np.float32(0.85)
    hw_path = smooth_path(meander(rng_l, shape, 200.0 / gsd_m, 0.02, start=(rng_l.uniform(0.2, 0.8) * w, -0.05 * h),
                                  heading=np.pi / 2 + rng_l.uniform(-0.3, 0.3)))
    hw = draw_paths(shape, [hw_path], 9.0 / gsd_m) > 127
    rgb[hw] = np.float32([0.30, 0.30, 0.31]) * (0.95 + 0.1 * value_noise(rng_a, shape, 3.0)[hw][:, None])
    roads = on_road | hw
    # --- trees: shelterbelts, riparian, groves
    zone = np.zeros(shape, np.float32)
    zone[lay["belt"] & ~roads] = 1.0
    rip = (rd < half * gsd_m + 30.0) & ~riv
    zone[rip] = np.maximum(zone[rip], (0.4 + 0.6 * value_noise(rng_l, shape, 60.0 / gsd_m)[rip]))
    grove = fbm(rng_l, shape, 400.0 / gsd_m, 3, min_cell_px=4) > 1.7
    zone[grove & ~water & ~roads] = 1.0
    zone[water | roads] = 0.0
    cr = crowns(rng_l, shape, gsd_m, 6.0)
    paint_trees(rgb, zone, cr, season, gsd_m, 12.0, 0.55)
    del zone, cr, rip, grove
    # --- farmsteads next to roads
    high_water = (lake_pot > np.float32(2.0 - 0.15)) | (rd < 10.0)  # season-independent
    _farmsteads(rgb, rng_l, lay["road_m"], high_water, season, gsd_m)
    # --- gentle relief shading
    hs = hillshade(z, gsd_m, season, exaggeration=3.0)
    flat = np.float32(np.sin(season.sun_elevation_rad))
    rgb *= (0.75 + 0.25 * hs / max(flat, 1e-3))[..., None]
    z[high_water] -= 1.0  # layout only: the DEM is the same in every season
    out = finish(rgb, season, rng_a, gsd_m)
    return out, z, np.ones(shape, bool)


def _farmsteads(rgb, rng, road_m, water, season, gsd_m):
    h, w = road_m.shape
    n = max(1, int(h * w * gsd_m * gsd_m / 1.2e6))
    cand = np.flatnonzero((road_m.ravel()[:: 97] < 2.0))
    if cand.size == 0:
        return
    picks = rng.choice(cand, min(n, cand.size), replace=False) * 97
    blds = []
    yard = np.zeros((h, w), np.uint8)
    belt = np.zeros((h, w), np.uint8)
    for p in picks:
        r0, c0 = divmod(int(p), w)
        ang = rng.uniform(0, np.pi)
        off = 55.0 / gsd_m
        cc, rr = c0 + off * np.cos(ang), r0 + off * np.sin(ang)
        if not (0 <= rr < h and 0 <= cc < w) or water[int(rr), int(cc)]:
            continue
        a2 = rng.uniform(0, np.pi)
        ys, xs = 70.0 / gsd_m, 90.0 / gsd_m
        box = cv2.boxPoints(((cc, rr), (xs, ys), np.degrees(a2)))
        cv2.fillPoly(yard, [np.round(box * 4).astype(np.int32)], 255, cv2.LINE_8, shift=2)
        cv2.line(yard, (c0 * 4, r0 * 4), (int(cc * 4), int(rr * 4)), 255, max(1, int(4 / gsd_m)), cv2.LINE_8, shift=2)
        wb = cv2.boxPoints(((cc, rr), (xs + 60 / gsd_m, ys + 60 / gsd_m), np.degrees(a2)))
        cv2.polylines(belt, [np.round(wb[:3] * 4).astype(np.int32)], False, 255, max(1, int(18 / gsd_m)), cv2.LINE_8, shift=2)
        ca, sa = np.cos(a2), np.sin(a2)
        for _ in range(rng.integers(3, 7)):
            dx, dy = rng.uniform(-0.35, 0.35) * xs, rng.uniform(-0.3, 0.3) * ys
            blds.append((cc + dx * ca - dy * sa, rr + dx * sa + dy * ca, rng.uniform(12, 40) / gsd_m,
                         rng.uniform(8, 18) / gsd_m, a2 + rng.choice([0, np.pi / 2]), rng.integers(0, 7)))
    ym = yard > 0
    gcol = np.float32([0.60, 0.57, 0.50]) if season.name != "winter" else np.float32([0.75, 0.74, 0.72])
    tint(rgb, ym, gcol, 0.85)
    bz = (belt > 0) & ~ym
    if bz.any():
        paint_trees(rgb, bz.astype(np.float32), crowns(rng, (h, w), gsd_m, 6.0), season, gsd_m, 12.0, 0.7)
    draw_buildings(rgb, blds, season, gsd_m, 7.0)
