"""Farmland (and the field layout other terrains reuse): districts of rectangular fields with
varied sizes and orientations, crop rows, margins, section roads, a river, prairie lakes,
shelterbelts and groves, farmsteads. Same seed -> same layout whatever the season.
"""

from __future__ import annotations

import cv2
import numpy as np

from testbench.world.procedural.appearance import Season, hillshade, tint
from testbench.world.procedural.bands import Terrain
from testbench.world.procedural.features import Buildings, boxes, fill_polys, paint_trees, water_colour
from testbench.world.procedural.linework import PathDistance, draw_paths, meander, smooth_path
from testbench.world.procedural.noise import CoarseGrid, Fbm, ValueNoise, fbm, stream

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



class FieldLayout:
    """Partition of the world into districts and rectangular fields (layout only).

    Global tables are drawn once; at(east, north, district, border) evaluates the layout at any
    points (a band of rows, or scattered samples) and returns a dict: u, v field-aligned
    coordinates (m), attr int32 index 0.._N_ATTR-1 into per-field attribute tables, edge_m
    distance to the nearest field boundary (m), road_m distance to the nearest section road (m),
    belt bool shelterbelt boundaries.
    """

    def __init__(self, seed: int, shape, gsd_m: float, grid: CoarseGrid, mean_field_m: float = 350.0):
        h, w = shape
        rng = stream(seed, "fields")
        size_m = max(h, w) * gsd_m
        # districts: warped Voronoi on the coarse grid
        k = int(np.clip(round((size_m / 1800.0) ** 2 * 1.5), 2, 60))
        seeds = rng.uniform(-0.6 * size_m, 0.6 * size_m, (k, 2))
        warp = 120.0 * fbm(rng, grid.shape, 700.0 / (gsd_m * grid.k), 3)
        best = np.full(grid.shape, np.inf, np.float32)
        dist_id = np.zeros(grid.shape, np.int32)
        for i, (sn, se) in enumerate(seeds):
            d = (grid.east + warp - np.float32(se)) ** 2 + (grid.north - warp - np.float32(sn)) ** 2
            sel = d < best
            best[sel] = d[sel]
            dist_id[sel] = i
        border = cv2.morphologyEx(dist_id.astype(np.uint8), cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8)) > 0
        self.dist_id = dist_id
        self.district = grid.field(dist_id.astype(np.float32))
        # roads along district borders: a blurred coarse mask, cut at a level -> smooth curves
        self.border = grid.field(cv2.GaussianBlur(border.astype(np.float32), (0, 0), 1.0))
        theta0 = rng.uniform(-0.25, 0.25)
        dev = rng.choice([0.0, 0.0, 0.0, 1.0], k) * rng.uniform(-0.6, 0.6, k)
        self.theta = (theta0 + dev).astype(np.float32)
        self.off = rng.uniform(0, 1600.0, (k, 2)).astype(np.float32)
        lim = 1.6 * size_m + 3200.0
        # strips across u with varied widths
        widths = rng.choice([0.25, 0.5, 0.5, 1.0, 1.0, 1.5], 4096) * mean_field_m * rng.uniform(0.85, 1.15, 4096)
        ub = np.cumsum(widths) - lim
        self.ub = ub[: np.searchsorted(ub, lim) + 2].astype(np.float32)
        ns = len(self.ub)
        self.u_road = (np.arange(ns) % rng.integers(3, 6)) == 0
        self.u_belt = rng.random(ns) < 0.15
        # per-strip field lengths along v (flattened with an offset per strip)
        self.nv = nv = int(2 * lim / (0.3 * mean_field_m)) + 4
        lens = rng.choice([0.5, 1.0, 1.0, 2.0, 3.0], (ns, nv)) * mean_field_m * rng.uniform(0.8, 1.2, (ns, nv))
        vb = np.cumsum(lens, axis=1) - lim - rng.uniform(0, 2 * mean_field_m, (ns, 1))
        self.big = np.float32(8.0 * lim)
        self.flat = (vb + (np.arange(ns)[:, None] * 8.0 * lim)).ravel().astype(np.float32)
        self.vspace = float(rng.choice([1600.0, 1600.0, 3200.0]))
        # field attribute index = (field * 2654435761 + district * 97531) mod _N_ATTR, by tables
        self.field_attr = ((np.arange(2 * ns * nv + 1, dtype=np.int64) * 2654435761) % _N_ATTR).astype(np.int32)
        self.district_attr = ((np.arange(k, dtype=np.int64) * 97531) % _N_ATTR).astype(np.int32)

    def rows(self, east, north, a: int, b: int):
        """Layout of image rows [a, b) (east (1, W), north (b-a, 1))."""
        district = self.district.nearest(a, b).astype(np.int32)
        border = self.border.rows(a, b) > 0.42
        return self.at(east, north, district, border)

    def at(self, east, north, district, border):
        cs, sn_ = np.cos(self.theta)[district], np.sin(self.theta)[district]
        u = east * cs + north * sn_
        u += self.off[district, 0]
        v = north * cs - east * sn_
        v += self.off[district, 1]
        del cs, sn_
        ub, ns = self.ub, len(self.ub)
        s = np.clip(np.searchsorted(ub, u), 1, ns - 1)
        lo, hi = u - ub[s - 1], ub[s] - u
        du = np.minimum(lo, hi)
        nb = np.where(lo < hi, s - 1, s)
        del lo, hi
        key = v + s.astype(np.float32) * self.big
        kk = np.clip(np.searchsorted(self.flat, key), 1, self.flat.size - 1)
        dv = np.minimum(key - self.flat[kk - 1], self.flat[kk] - key)
        del key
        kk += s * self.nv
        attr = self.field_attr[kk]
        attr += self.district_attr[district]
        attr[attr >= _N_ATTR] -= _N_ATTR
        del kk, s
        edge = np.minimum(du, dv)
        # section roads: some strip boundaries plus a regular cross grid in v; district borders
        vs = self.vspace
        vr = np.abs(((v + np.float32(0.5 * vs)) % np.float32(vs)) - np.float32(0.5 * vs))
        road = np.where(self.u_road[nb], du, np.float32(1e4))
        np.minimum(road, vr, out=road)
        road[border] = 0.0
        belt = self.u_belt[nb] & (du < 14.0)
        return dict(u=u, v=v, attr=attr, edge_m=edge.astype(np.float32), road_m=road.astype(np.float32),
                    belt=belt)


class Farmland(Terrain):
    """Farmland world (see the module docstring)."""

    name = "farmland"

    def __init__(self, seed, shape, gsd_m, season):
        super().__init__(seed, shape, gsd_m, season)
        h, w = shape
        g = self.grid
        self.lay = FieldLayout(seed, shape, gsd_m, g)
        rng_l = stream(seed, "farm-layout")
        rng_a = stream(seed, f"farm-look-{season.name}")
        # --- relief and water (layout)
        self.z_n = Fbm(rng_l, g, shape, 1500.0 / gsd_m, 4, min_cell_px=8)
        self.river = smooth_path(meander(rng_l, shape, 40.0 / gsd_m, 0.35))
        self.rd = PathDistance(g, shape, [self.river], near_px=int(60.0 / gsd_m) + 4)
        self.lake_n = Fbm(rng_l, g, shape, 450.0 / gsd_m, 5, gain=0.55, min_cell_px=3)
        attr_rng = stream(seed, "field-attrs")
        self.crop = attr_rng.choice(6, _N_ATTR, p=[0.26, 0.22, 0.2, 0.1, 0.14, 0.08])
        self.row_dir = attr_rng.random(_N_ATTR) < 0.5
        self.row_period = attr_rng.uniform(3.0, 7.0, _N_ATTR).astype(np.float32)
        self.tram = attr_rng.uniform(16.0, 28.0, _N_ATTR).astype(np.float32)
        self.jitter = attr_rng.normal(0, 0.035, (_N_ATTR, 3)).astype(np.float32)
        sidx = season.index
        # per-field tables of this season: colour, row contrast, tramline darkening
        self.base_tab = _CROP_RGB[sidx][self.crop] + self.jitter
        self.amp_tab = (_ROW_AMP[sidx][self.crop]
                        * np.clip((self.row_period / np.float32(gsd_m) - 2.0) / 2.0, 0.0, 1.0)).astype(np.float32)
        self.tram_tab = np.where((self.crop < 3) & (sidx != 2), np.float32(0.06), np.float32(0.0))
        # --- appearance noise
        self.patch_a = Fbm(rng_a, g, shape, 180.0 / gsd_m, 5)
        self.patch_l = Fbm(rng_l, g, shape, 60.0 / gsd_m, 4)
        self.grain_a = ValueNoise(rng_a, shape, 2.5 / gsd_m)
        self.snow_n = Fbm(rng_a, g, shape, 60.0 / gsd_m, 3) if season.name == "winter" else None
        self.margin_n = ValueNoise(rng_a, shape, 3.0)
        self.gravel_n = ValueNoise(rng_a, shape, 2.0)
        self.hw_path = smooth_path(meander(rng_l, shape, 200.0 / gsd_m, 0.02,
                                           start=(rng_l.uniform(0.2, 0.8) * w, -0.05 * h),
                                           heading=np.pi / 2 + rng_l.uniform(-0.3, 0.3)))
        self.asphalt_n = ValueNoise(rng_a, shape, 3.0)
        self.rip_n = ValueNoise(rng_l, shape, 60.0 / gsd_m)
        self.grove_n = Fbm(rng_l, g, shape, 400.0 / gsd_m, 3, min_cell_px=4)
        self.crowns = ValueNoise(rng_l, shape, max(6.0 / gsd_m, 1.2))
        self._farmsteads(rng_l)

    # --- layout helpers
    def _z_water(self, a, b):
        """Relief without the water dip, river distance (m), lake potential of rows [a, b)."""
        gsd = self.gsd_m
        z = self.z_n.rows(a, b)
        z *= np.float32(5.0)
        rd = self.rd.rows(a, b)
        rd *= np.float32(gsd)
        z -= np.float32(6.0) * np.exp(rd / np.float32(-250.0))
        lake_pot = self.lake_n.rows(a, b)
        lake_pot -= np.float32(0.04) * z
        return z, rd, lake_pot

    def _farmsteads(self, rng):
        """Farmsteads next to roads: yards, a drive, a shelterbelt on three sides, buildings."""
        h, w = self.shape
        gsd = self.gsd_m
        n = max(1, int(h * w * gsd * gsd / 1.2e6))
        # candidates: layout samples on the coarse grid close to a road
        g = self.grid
        lay = self.lay.at(g.east, g.north, self.lay.dist_id, np.zeros(g.shape, bool))
        rows_c = (np.arange(g.shape[0]) + 0.5) * g.k - g.margin - 0.5
        cols_c = (np.arange(g.shape[1]) + 0.5) * g.k - 0.5
        inside = (rows_c >= 0) & (rows_c < h)
        near = (lay["road_m"] < 2.0 * g.k * gsd) & inside[:, None]
        cand = np.flatnonzero(near.ravel()[::7]) * 7
        self.yards, self.drives, self.belts, blds = [], [], [], []
        if cand.size:
            picks = rng.choice(cand, min(n, cand.size), replace=False)
            for p in picks:
                jr, ic = divmod(int(p), g.shape[1])
                r0, c0 = float(rows_c[jr]), float(cols_c[ic])
                ang = rng.uniform(0, np.pi)
                off = 55.0 / gsd
                cc, rr = c0 + off * np.cos(ang), r0 + off * np.sin(ang)
                if not (0 <= rr < h and 0 <= cc < w):
                    continue
                ri = int(rr)
                z, rd, lp = self._z_water(ri, ri + 1)
                if lp[0, int(cc)] > 2.0 - 0.15 or rd[0, int(cc)] < 10.0:
                    continue
                a2 = rng.uniform(0, np.pi)
                ys, xs = 70.0 / gsd, 90.0 / gsd
                self.yards.append(boxes(cc, rr, xs, ys, a2)[0])
                self.drives.append(np.array([[c0, r0], [cc, rr]]))
                self.belts.append(boxes(cc, rr, xs + 60 / gsd, ys + 60 / gsd, a2)[0][:3])
                ca, sa = np.cos(a2), np.sin(a2)
                for _ in range(rng.integers(3, 7)):
                    dx, dy = rng.uniform(-0.35, 0.35) * xs, rng.uniform(-0.3, 0.3) * ys
                    blds.append((cc + dx * ca - dy * sa, rr + dx * sa + dy * ca, rng.uniform(12, 40) / gsd,
                                 rng.uniform(8, 18) / gsd, a2 + rng.choice([0, np.pi / 2]), rng.integers(0, 7)))
        self.yards = np.array(self.yards).reshape(-1, 4, 2)
        self.buildings = Buildings(blds, 7.0, rng.uniform(0.85, 1.1, len(blds)))

    def rows(self, a, b):
        gsd, season = self.gsd_m, self.season
        sidx = season.index
        shape = (b - a, self.shape[1])
        east, north = self.coords(a, b)
        lay = self.lay.rows(east, north, a, b)
        z, rd, lake_pot = self._z_water(a, b)
        # --- field colours (appearance)
        at = lay["attr"]
        base = self.base_tab[at]
        along = np.where(self.row_dir[at], lay["u"], lay["v"])
        del lay["u"], lay["v"]
        rows = along * np.float32(2 * np.pi)
        rows /= self.row_period[at]
        np.sin(rows, out=rows)
        rows *= self.amp_tab[at]
        tr = self.tram[at]
        along += np.float32(3.0)
        along %= tr
        tr *= np.float32(0.5)
        along -= tr
        tl = np.abs(along, out=along) < max(0.8, 0.6 * gsd)
        rows -= np.where(tl, self.tram_tab[at], np.float32(0.0))
        del along, tl, tr, at
        shade = self.patch_a.rows(a, b)
        shade *= np.float32(0.045)
        shade += np.float32(0.04) * self.patch_l.rows(a, b)
        shade += np.float32(0.03) * self.grain_a.rows(a, b)
        shade -= np.clip(-z / np.float32(12.0), -0.5, 1.0) * np.float32(0.05)  # low ground: moister
        shade += rows
        shade += np.float32(1.0)
        del rows
        rgb = base
        rgb *= shade[..., None]
        del shade
        if self.snow_n is not None:
            rgb += (np.float32(0.08) * self.snow_n.rows(a, b))[..., None]
        # --- field margins and shelterbelts
        grass = np.float32([[0.36, 0.44, 0.22], [0.50, 0.47, 0.30], [0.80, 0.80, 0.80], [0.38, 0.48, 0.22]][sidx])
        margin = lay["edge_m"] < np.float32(max(1.2, 1.0 * gsd))
        rgb[margin] = grass * (0.9 + 0.2 * self.margin_n.rows(a, b)[margin][:, None])
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
        del shore, rim
        # --- river
        half_m = np.float32(7.0 + 2.0 * season.water_level)
        riv = rd < half_m
        rgb[riv] = water_colour(1.0 - rd[riv] / half_m, season)
        water = lake | riv
        # --- roads
        road_m = lay["road_m"]
        road_w = np.float32(3.5)
        on_road = (road_m < road_w) & ~water
        gravel = np.float32([[0.66, 0.62, 0.55], [0.64, 0.60, 0.53], [0.62, 0.60, 0.58], [0.60, 0.56, 0.50]][sidx])
        rgb[on_road] = gravel * (0.9 + 0.15 * self.gravel_n.rows(a, b)[on_road][:, None])
        rgb[(road_m > road_w) & (road_m < road_w + 1.5) & ~water] *= np.float32(0.85)
        hw = draw_paths(shape, [self.hw_path], 9.0 / gsd, row0=a) > 127
        rgb[hw] = np.float32([0.30, 0.30, 0.31]) * (0.95 + 0.1 * self.asphalt_n.rows(a, b)[hw][:, None])
        roads = on_road | hw
        del on_road, hw
        # --- trees: shelterbelts, riparian, groves
        zone = np.zeros(shape, np.float32)
        zone[lay["belt"] & ~roads] = 1.0
        rip = (rd < half_m + 30.0) & ~riv
        zone[rip] = np.maximum(zone[rip], 0.4 + 0.6 * self.rip_n.rows(a, b)[rip])
        grove = self.grove_n.rows(a, b) > 1.7
        zone[grove & ~water & ~roads] = 1.0
        zone[water | roads] = 0.0
        del rip, grove
        paint_trees(rgb, zone, self.crowns.rows(a, b), season, gsd, 12.0, 0.55)
        del zone
        # --- farmsteads
        high_water = (lake_pot > np.float32(2.0 - 0.15)) | (rd < 10.0)  # season-independent
        del lake_pot, rd, lay
        self._paint_farmsteads(rgb, a, shape)
        # --- gentle relief shading
        hs = hillshade(z, gsd, season, exaggeration=3.0)
        flat = np.float32(np.sin(season.sun_elevation_rad))
        hs *= np.float32(0.25) / max(flat, np.float32(1e-3))
        hs += np.float32(0.75)
        rgb *= hs[..., None]
        z[high_water] -= 1.0  # layout only: the DEM is the same in every season
        return rgb, z

    def _paint_farmsteads(self, rgb, a, shape):
        gsd, season = self.gsd_m, self.season
        if not len(self.yards):
            return
        yard = np.zeros(shape, np.uint8)
        belt = np.zeros(shape, np.uint8)
        fill_polys(yard, self.yards, a, 255)
        off = np.array([0.0, a])
        for d in self.drives:
            p = np.round((d - off) * 4).astype(np.int32)
            cv2.line(yard, (int(p[0, 0]), int(p[0, 1])), (int(p[1, 0]), int(p[1, 1])), 255, max(1, int(4 / gsd)), cv2.LINE_8, shift=2)
        bl = [np.round((p - off) * 4).astype(np.int32) for p in self.belts]
        cv2.polylines(belt, bl, False, 255, max(1, int(18 / gsd)), cv2.LINE_8, shift=2)
        ym = yard > 0
        if ym.any():
            gcol = np.float32([0.60, 0.57, 0.50]) if season.name != "winter" else np.float32([0.75, 0.74, 0.72])
            tint(rgb, ym, gcol, 0.85)
        bz = (belt > 0) & ~ym
        if bz.any():
            paint_trees(rgb, bz.astype(np.float32), self.crowns.rows(a, a + shape[0]), season, gsd, 12.0, 0.7)
        self.buildings.draw(rgb, a, season, gsd)
