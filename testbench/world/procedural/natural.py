"""Grassland (rolling hills, creek with gallery trees, tracks, stock ponds, shrubs) and desert
(dunes, rock outcrops, dry washes, sparse shrubs)."""

from __future__ import annotations

import cv2
import numpy as np

from testbench.world.procedural.appearance import cast_shadow, hillshade, tint
from testbench.world.procedural.bands import Terrain
from testbench.world.procedural.features import Buildings, paint_trees, water_colour
from testbench.world.procedural.linework import PathDistance, distance_to, draw_paths, meander, smooth_path
from testbench.world.procedural.noise import Fbm, ValueNoise, smoothstep, stream


def _shade(rgb, z, gsd_m, season, strength=0.6, exaggeration=1.0):
    hs = hillshade(z, gsd_m, season, exaggeration)
    flat = np.float32(np.sin(season.sun_elevation_rad))
    hs *= np.float32(strength) / flat
    hs += np.float32(1 - strength)
    rgb *= hs[..., None]


def _tracks(rng, shape, gsd_m, n, wiggle=0.08):
    h, w = shape
    paths = []
    for _ in range(n):
        start = (rng.uniform(0, w), -0.05 * h) if rng.random() < 0.5 else (-0.05 * w, rng.uniform(0, h))
        heading = rng.uniform(0.3, 1.2) if start[1] < 0 else rng.uniform(-0.6, 0.6)
        paths.append(smooth_path(meander(rng, shape, 30.0 / gsd_m, wiggle, start=start, heading=heading)))
    return paths


def _shrubs(rgb, crown, zone, season, gsd_m, colour, height_m=1.5, density=0.12):
    zone *= crown
    m = zone > np.float32(1 - density)
    sh = cast_shadow(m, height_m, gsd_m, season, steps=3)
    sh *= np.float32(-0.4)
    sh += np.float32(1.0)
    rgb *= sh[..., None]
    tint(rgb, m, colour, 0.85)
    return m


class Grassland(Terrain):
    name = "grassland"
    halo_m = 40.0

    def __init__(self, seed, shape, gsd_m, season):
        super().__init__(seed, shape, gsd_m, season)
        h, w = shape
        g = self.grid
        rng_l = stream(seed, "grass-layout")
        rng_a = stream(seed, f"grass-look-{season.name}")
        self.z1 = Fbm(rng_l, g, shape, 1400.0 / gsd_m, 5, min_cell_px=6)
        self.z2 = Fbm(rng_l, g, shape, 120.0 / gsd_m, 3, min_cell_px=4)
        creek = smooth_path(meander(rng_l, shape, 30.0 / gsd_m, 0.45))
        self.cd = PathDistance(g, shape, [creek], near_px=int(60.0 / gsd_m) + 4)
        self.mix_n = Fbm(rng_l, g, shape, 300.0 / gsd_m, 4)
        self.tex_a = Fbm(rng_a, g, shape, 90.0 / gsd_m, 4)
        self.tex_l = Fbm(rng_l, g, shape, 20.0 / gsd_m, 3)
        self.grain_a = ValueNoise(rng_a, shape, 2.0 / gsd_m)
        if season.snow > 0:
            self.snow_v = ValueNoise(rng_a, shape, 150.0 / gsd_m)
            self.snow_f = Fbm(rng_a, g, shape, 20.0 / gsd_m, 3)
        n_ponds = max(1, int(h * w * gsd_m ** 2 / 2.5e6))
        self.ponds = [(rng_l.uniform(0, w), rng_l.uniform(0, h), rng_l.uniform(12, 35) / gsd_m,
                       rng_l.uniform(0, 180)) for _ in range(n_ponds)]
        self.tracks = _tracks(rng_l, shape, gsd_m, 3)
        self.gallery_n = ValueNoise(rng_l, shape, 50 / gsd_m)
        self.clump_n = Fbm(rng_l, g, shape, 250.0 / gsd_m, 3, min_cell_px=4)
        self.crowns = ValueNoise(rng_l, shape, max(7.0 / gsd_m, 1.2))
        self.shrub_zone_n = ValueNoise(rng_l, shape, 400 / gsd_m)
        self.shrub_n = ValueNoise(rng_l, shape, max(2.5 / gsd_m, 1.0))
        p = self.tracks[0][len(self.tracks[0]) // 2]
        blds = [(p[0] + rng_l.uniform(20, 60) / gsd_m * s1, p[1] + rng_l.uniform(20, 60) / gsd_m * s2,
                 rng_l.uniform(10, 30) / gsd_m, rng_l.uniform(8, 14) / gsd_m, rng_l.uniform(0, np.pi),
                 rng_l.integers(0, 7)) for s1, s2 in ((1, 1), (-1, 1), (1, -1))]
        self.buildings = Buildings(blds, 6.0)

    def rows(self, a, b):
        gsd, season = self.gsd_m, self.season
        shape = (b - a, self.shape[1])
        z = self.z1.rows(a, b)
        z *= np.float32(22.0)
        z += np.float32(2.5) * self.z2.rows(a, b)
        cd = self.cd.rows(a, b)
        cd *= np.float32(gsd)
        z -= np.float32(14.0) * np.exp(cd / np.float32(-220.0))
        moist = np.exp(cd / np.float32(-120.0)) + np.float32(0.3) * smoothstep(5.0, -25.0, z)
        base = np.float32([[0.50, 0.50, 0.30], [0.66, 0.58, 0.40], [0.74, 0.70, 0.60], [0.40, 0.50, 0.24]][season.index])
        greener = np.float32([[0.30, 0.40, 0.18], [0.46, 0.44, 0.26], [0.60, 0.58, 0.50], [0.26, 0.40, 0.15]][season.index])
        mix = np.clip(moist * 0.8 + 0.25 * self.mix_n.rows(a, b), 0, 1)[..., None]
        del moist
        rgb = base + (greener - base) * mix
        del mix
        tex = self.tex_a.rows(a, b)
        tex *= np.float32(0.07)
        tex += np.float32(0.05) * self.tex_l.rows(a, b)
        tex += np.float32(0.04) * self.grain_a.rows(a, b)
        tex += np.float32(1.0)
        rgb *= tex[..., None]
        del tex
        if season.snow > 0:
            snow = smoothstep(0.2, 0.8, self.snow_v.rows(a, b) + 0.25 * self.snow_f.rows(a, b))
            tint(rgb, snow, (0.86, 0.87, 0.89), season.snow)
            del snow
        # stock ponds and creek
        ponds = np.zeros(shape, np.uint8)
        for cc, rr, r, ang in self.ponds:
            if rr + 2 * r >= a and rr - 2 * r < b:
                cv2.ellipse(ponds, ((cc, rr - a), (2 * r, 1.6 * r), ang), 255, -1)
        pond = ponds > 0
        if pond.any():
            pd = distance_to(ponds) * np.float32(gsd)
            tint(rgb, (pd > 0) & (pd < 6.0), (0.55, 0.48, 0.38), 0.8)
            rgb[pond] = water_colour(np.full(int(pond.sum()), 0.5), season)
            del pd
        half = 2.0 + 1.0 * season.water_level
        wet = cd < half
        rgb[wet] = water_colour(1 - cd[wet] / half, season)
        # tracks (two-track dirt roads) and a ranch
        tm = draw_paths(shape, self.tracks, 3.5 / gsd, row0=a) > 127
        soil = np.float32([0.62, 0.55, 0.45]) if season.name != "winter" else np.float32([0.70, 0.68, 0.64])
        tint(rgb, tm, soil, 0.75)
        if gsd <= 1.0:
            mid = draw_paths(shape, self.tracks, 1.0, row0=a) > 200
            tint(rgb, mid & tm, base, 0.6)
        # gallery trees along the creek, scattered clumps, shrubs
        zone = np.clip(np.exp(cd / np.float32(-35.0)) * 1.3, 0, 1)
        zone *= 0.5 + 0.5 * self.gallery_n.rows(a, b)
        zone[self.clump_n.rows(a, b) > 2.0] = 0.8
        off = wet | pond | tm
        zone[off] = 0
        paint_trees(rgb, zone, self.crowns.rows(a, b), season, gsd, 9.0, 0.6)
        shrub_zone = self.shrub_zone_n.rows(a, b)
        shrub_zone *= np.float32(0.6)
        shrub_zone += np.float32(0.4)
        shrub_zone[off] = 0
        _shrubs(rgb, self.shrub_n.rows(a, b), shrub_zone, season, gsd, (0.25, 0.30, 0.18), density=0.10)
        self.buildings.draw(rgb, a, season, gsd)
        _shade(rgb, z, gsd, season, 0.55)
        return rgb, z


class Desert(Terrain):
    name = "desert"
    halo_m = 30.0

    def __init__(self, seed, shape, gsd_m, season):
        super().__init__(seed, shape, gsd_m, season)
        g = self.grid
        rng_l = stream(seed, "desert-layout")
        rng_a = stream(seed, f"desert-look-{season.name}")
        self.wind = rng_l.uniform(0, np.pi)
        self.lam = rng_l.uniform(90.0, 150.0)
        self.warp_n = Fbm(rng_l, g, shape, 500.0 / gsd_m, 3)
        self.dune_n = Fbm(rng_l, g, shape, 1200.0 / gsd_m, 3)
        self.z_n = Fbm(rng_l, g, shape, 1500.0 / gsd_m, 4, min_cell_px=6)
        self.rock_n = Fbm(rng_l, g, shape, 700.0 / gsd_m, 5, min_cell_px=2)
        self.ridge_n = Fbm(rng_l, g, shape, 120.0 / gsd_m, 4, min_cell_px=2)
        washes = []
        for _ in range(3):
            p0 = smooth_path(meander(rng_l, shape, 25.0 / gsd_m, 0.3))
            washes.append(p0)
            washes.append(p0 + rng_l.normal(0, 6.0 / gsd_m, p0.shape))
        self.wd = PathDistance(g, shape, washes, near_px=int(40.0 / gsd_m) + 4, width_px=2)
        self.tone_l = Fbm(rng_l, g, shape, 250.0 / gsd_m, 4)
        self.tone_a = Fbm(rng_a, g, shape, 30.0 / gsd_m, 3)
        self.grain_a = ValueNoise(rng_a, shape, 1.5 / gsd_m)
        self.strata_n = Fbm(rng_l, g, shape, 200.0 / gsd_m, 2)
        self.shrub_zone_n = ValueNoise(rng_l, shape, 300 / gsd_m)
        self.shrub_n = ValueNoise(rng_l, shape, max(2.5 / gsd_m, 1.0))
        self.tracks = _tracks(rng_l, shape, gsd_m, 2, 0.05)
        self.ripple_n = ValueNoise(rng_l, shape, max(1.5 / gsd_m, 1.0))

    def rows(self, a, b):
        gsd, season = self.gsd_m, self.season
        shape = (b - a, self.shape[1])
        east, north = self.coords(a, b)
        u = self.warp_n.rows(a, b)
        u *= np.float32(45.0)
        u += east * np.float32(np.cos(self.wind))
        u += north * np.float32(np.sin(self.wind))
        u *= np.float32(1.0 / self.lam)
        ph = u - np.floor(u)
        del u
        slip = ph >= 0.75  # steep lee face
        prof = np.where(slip, (1 - ph) / np.float32(0.25), ph / np.float32(0.75))  # gentle stoss
        del ph
        prof *= np.float32(12.0) * smoothstep(-1.8, -0.2, self.dune_n.rows(a, b))
        z = cv2.GaussianBlur(prof, (0, 0), max(1.0, 3.0 / gsd))
        dunes = z.copy()
        del prof
        z += np.float32(25.0) * self.z_n.rows(a, b)
        rock = smoothstep(1.1, 1.5, self.rock_n.rows(a, b))
        ridges = np.abs(self.ridge_n.rows(a, b))
        z += rock * (30.0 + 15.0 * (1.5 - ridges))
        del ridges
        wd = self.wd.rows(a, b)
        wd *= np.float32(gsd)
        wash = smoothstep(22.0, 8.0, wd)
        z -= np.float32(3.0) * wash
        sand = np.float32([[0.80, 0.68, 0.52], [0.78, 0.66, 0.50], [0.74, 0.66, 0.56], [0.80, 0.69, 0.53]][season.index])
        tone = self.tone_l.rows(a, b)
        tone *= np.float32(0.06)
        tone += np.float32(0.03) * self.tone_a.rows(a, b)
        tone += np.float32(0.03) * self.grain_a.rows(a, b)
        # wind ripples on the stoss slopes, coarser sand on the slip faces: dune texture that
        # survives a high sun
        tone += np.float32(0.035) * (self.ripple_n.rows(a, b) - np.float32(0.5)) * (dunes > 1.0)
        tone -= np.float32(0.025) * slip * smoothstep(0.5, 3.0, dunes)
        tone += np.float32(1.0)
        del slip
        rgb = np.empty(shape + (3,), np.float32)
        rgb[...] = sand
        rgb *= tone[..., None]
        del tone
        rock_rgb = np.float32([0.50, 0.34, 0.24])
        strata = np.sin(z / np.float32(3.0) + np.float32(2.0) * self.strata_n.rows(a, b))
        strata *= np.float32(0.5 * 0.35)
        strata += np.float32(0.8 + 0.5 * 0.35)
        rr = rock_rgb * strata[..., None]
        rr -= rgb
        rr *= (rock * 0.9)[..., None]
        rgb += rr
        del rr, strata
        tint(rgb, wash, (0.86, 0.80, 0.68), 0.35)
        shrub_zone = np.float32(0.35) + np.float32(0.45) * np.exp(wd / np.float32(-30.0))
        shrub_zone += np.float32(0.25) * self.shrub_zone_n.rows(a, b)
        shrub_zone *= 1 - rock
        col = (0.32, 0.33, 0.22) if season.name != "spring" else (0.30, 0.38, 0.18)
        _shrubs(rgb, self.shrub_n.rows(a, b), shrub_zone, season, gsd, col, density=0.08)
        tm = draw_paths(shape, self.tracks, 4.0 / gsd, row0=a) > 127
        tint(rgb, tm, (0.70, 0.62, 0.52), 0.6)
        # dunes shaded with an exaggerated relief: a 12 m dune under a 60 deg sun still reads
        _shade(rgb, z + np.float32(0.6) * dunes, gsd, season, 0.75, 1.0)
        return rgb, z
