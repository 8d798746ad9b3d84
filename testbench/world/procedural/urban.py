"""Urban world: a street grid (arterials and local streets, two grid orientations) with blocks
of buildings (gable and flat roofs, cast shadows), street trees, parks, parking, cars."""

from __future__ import annotations

import numpy as np

from testbench.world.procedural.appearance import tint
from testbench.world.procedural.bands import Terrain
from testbench.world.procedural.features import Buildings, paint_trees
from testbench.world.procedural.noise import Fbm, ValueNoise, stream


class Urban(Terrain):
    name = "urban"
    halo_m = 40.0

    def __init__(self, seed, shape, gsd_m, season):
        super().__init__(seed, shape, gsd_m, season)
        h, w = shape
        g = self.grid
        rng_l = stream(seed, "urban-layout")
        rng_a = stream(seed, f"urban-look-{season.name}")
        self.z_n = Fbm(rng_l, g, shape, 2000.0 / gsd_m, 3, min_cell_px=8)
        # two districts with different grid orientations, split by a warped line
        self.split_n = Fbm(rng_l, g, shape, 1500 / gsd_m, 2)
        self.split_at = rng_l.uniform(-300, 300)
        self.th_a, self.th_b = rng_l.uniform(-0.1, 0.1), rng_l.uniform(0.35, 0.7)
        self.bu, self.bv = rng_l.uniform(90, 130), rng_l.uniform(120, 200)
        # block use: 0 residential, 1 commercial, 2 park, 3 parking
        self.use_tab = rng_l.choice(4, 1009, p=[0.6, 0.22, 0.1, 0.08])
        self.lawn_tab = rng_l.normal(0.0, 0.018, (1009, 3)).astype(np.float32)
        self.tex_a = Fbm(rng_a, g, shape, 15.0 / gsd_m, 3)
        self.grain_a = ValueNoise(rng_a, shape, 2 / gsd_m)
        self.wear_n = Fbm(rng_a, g, shape, 40.0 / gsd_m, 3)
        # buildings: residential houses along the block edges, commercial big boxes
        step = max(1, int(8 / gsd_m))
        blds, tone = [], []
        east, _ = self.coords(0, 1)
        cols = np.arange(0, w, step)
        for r in range(0, h, step):
            _, north = self.coords(r, r + 1)
            gr = self._grid(east[:, cols], north, self.split_n.rows(r, r + 1)[:, cols])
            dd = np.minimum(gr["du"], gr["dv"])[0]
            use = gr["use"][0]
            res = np.flatnonzero((use == 0) & (dd > 16.0) & (dd < 30.0))
            res = res[rng_l.random(res.size) < 0.3]
            for k in res:
                blds.append((float(cols[k]), float(r), rng_l.uniform(9, 17) / gsd_m, rng_l.uniform(7, 12) / gsd_m,
                             -gr["th"][0, k] + (np.pi / 2 if gr["dv"][0, k] < gr["du"][0, k] else 0.0),
                             int(rng_l.integers(0, 7))))
            com = np.flatnonzero((use == 1) & (np.abs(gr["fu"][0] - 0.5) < 0.05) & (np.abs(gr["fv"][0] - 0.5) < 0.05))
            for k in com:
                blds.append((float(cols[k]), float(r), rng_l.uniform(40, 80) / gsd_m, rng_l.uniform(30, 60) / gsd_m,
                             -gr["th"][0, k], int(rng_l.integers(0, 7))))
        tone = rng_l.uniform(0.78, 1.12, len(blds))
        self.buildings = Buildings(blds, 8.0, tone)
        self.roof_n = ValueNoise(rng_a, shape, max(1.5 / gsd_m, 1.0))
        self.car_n = ValueNoise(rng_l, shape, 2.0 / gsd_m)
        self.car_zone_n = ValueNoise(rng_l, shape, 6 / gsd_m)
        self.car_col_n = ValueNoise(rng_l, shape, 3.0 / gsd_m)
        self.crowns = ValueNoise(rng_l, shape, max(7.0 / gsd_m, 1.2))

    def _grid(self, east, north, split_noise):
        """Street-grid coordinates at points (broadcast east, north, split noise)."""
        split = (east * 0.6 + north * 0.8 + 150.0 * split_noise) > self.split_at
        th = np.where(split, np.float32(self.th_a), np.float32(self.th_b))
        c, s = np.cos(th), np.sin(th)
        u = east * c + north * s
        v = north * c - east * s
        bu, bv = self.bu, self.bv
        iu, iv = np.floor(u / bu), np.floor(v / bv)
        fu, fv = u / bu - iu, v / bv - iv
        du = np.minimum(fu, 1 - fu) * bu
        dv = np.minimum(fv, 1 - fv) * bv
        iu, iv = iu.astype(np.int64), iv.astype(np.int64)
        block = ((iu * 7919 + iv * 104729 + split * 31) % 1009).astype(np.int32)
        arterial_u = (iu % 5 == 0) & (fu < 0.5) | ((iu + 1) % 5 == 0) & (fu >= 0.5)
        return dict(th=th, fu=fu, fv=fv, du=du, dv=dv, block=block, use=self.use_tab[block],
                    arterial_u=arterial_u)

    def rows(self, a, b):
        gsd, season = self.gsd_m, self.season
        east, north = self.coords(a, b)
        z = self.z_n.rows(a, b)
        z *= np.float32(3.0)
        gr = self._grid(east, north, self.split_n.rows(a, b))
        du, dv, use, art = gr["du"], gr["dv"], gr["use"], gr["arterial_u"]
        half = np.where(art, np.float32(11.0), np.float32(6.0))
        street = (du < half) | (dv < 6.0)
        sidewalk = ((du < half + 2.5) | (dv < 8.5)) & ~street
        del half
        grass = np.float32([[0.34, 0.42, 0.22], [0.45, 0.44, 0.28], [0.82, 0.82, 0.83], [0.36, 0.46, 0.22]][season.index])
        rgb = grass + self.lawn_tab[gr["block"]]  # lawns differ from block to block
        tex = self.tex_a.rows(a, b)
        tex *= np.float32(0.08)
        tex += np.float32(0.04) * self.grain_a.rows(a, b)
        tex += np.float32(1.0)
        rgb *= tex[..., None]
        del tex
        tint(rgb, use == 3, (0.42, 0.42, 0.43), 1.0)
        tint(rgb, use == 1, (0.55, 0.54, 0.52), 0.8)
        # asphalt and concrete with wear and patches (not flat paint)
        wear = self.wear_n.rows(a, b)
        wear *= np.float32(0.06)
        wear += np.float32(1.0)
        tint(rgb, street, (0.27, 0.27, 0.28), 1.0)
        tint(rgb, sidewalk, (0.62, 0.61, 0.58), 1.0)
        paved = street | sidewalk | (use == 3)
        rgb[paved] *= wear[paved][:, None]
        del wear, paved
        if gsd <= 1.0:
            mark = street & (du < 0.3 * gsd + 0.15) & art
            tint(rgb, mark, (0.85, 0.82, 0.55), 0.8)
        roof = self.roof_n.rows(a, b)
        roof *= np.float32(0.12)
        roof += np.float32(0.94)
        foot = self.buildings.draw(rgb, a, season, gsd, texture=roof)
        del roof
        # cars on streets (small coloured rectangles) and in parking lots
        car = (self.car_n.rows(a, b) > 0.83) & (street & ~(du < 1.5) | (use == 3)) & (self.car_zone_n.rows(a, b) > 0.6)
        colours = np.float32([[0.8, 0.8, 0.8], [0.15, 0.15, 0.17], [0.6, 0.1, 0.1], [0.2, 0.3, 0.5], [0.5, 0.5, 0.5]])
        ci = (self.car_col_n.rows(a, b) * 5).astype(np.int64).clip(0, 4)
        rgb[car] = colours[ci[car]]
        del ci, car
        # trees: parks, yards, streets
        zone = np.where(use == 2, np.float32(0.8), np.float32(0.0))
        zone[(use == 0) & ~street & ~sidewalk] = 0.72  # yard trees
        zone[sidewalk] = 0.8  # street trees
        zone[foot | street] = 0
        paint_trees(rgb, zone, self.crowns.rows(a, b), season, gsd, 10.0, 0.45)
        return rgb, z
