"""Canyon world: a plateau of layered rock cut by a meandering main canyon with tributaries,
terraced walls (hard and soft strata), then flow-accumulation-driven gully incision and thermal
erosion at coarse resolution, upsampled with fine roughness; hillshade-consistent colouring."""

from __future__ import annotations

import cv2
import numpy as np

from testbench.world.procedural.appearance import hillshade, terrain_shadow, tint
from testbench.world.procedural.bands import Terrain
from testbench.world.procedural.features import paint_trees, water_colour
from testbench.world.procedural.linework import distance_to, draw_paths, meander, smooth_path
from testbench.world.procedural.noise import CoarseGrid, Fbm, ValueNoise, fbm, smoothstep, stream

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


class Canyon(Terrain):
    """Canyon world: relief eroded on a coarse grid (k x k full-res pixels per cell), the
    look painted band by band at full resolution."""

    name = "canyon"
    halo_m = 30.0

    def __init__(self, seed, shape, gsd_m, season):
        super().__init__(seed, shape, gsd_m, season)
        h, w = shape
        rng_l = stream(seed, "canyon-layout")
        rng_a = stream(seed, f"canyon-look-{season.name}")
        n_target = int(min(512, max(64, h // 4)))
        kc = max(1, int(round(h / n_target)))
        cgrid = CoarseGrid(shape, gsd_m, kc, 0)
        cs = cgrid.shape
        n = cs[1]
        cg = kc * gsd_m  # coarse cell (m)
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
                ok = (pts[:, 0] >= 0) & (pts[:, 0] < cs[1]) & (pts[:, 1] >= 0) & (pts[:, 1] < cs[0])
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
        zc = zc.astype(np.float32)
        # D8 incision and talus moves leave cell-sized steps: upsampled and hillshaded they
        # print the coarse grid as a cross-hatch on steep walls; smooth them off first
        self.zc = cgrid.field(cv2.GaussianBlur(zc, (0, 0), 0.9), cubic=True)
        self.rough = Fbm(rng_l, self.grid, shape, 25.0 / gsd_m, 3, min_cell_px=2)
        self.river_d = cgrid.field(distance_to(draw_paths(cs, [main])) * np.float32(cg))
        # --- appearance fields
        self.band_n = Fbm(rng_l, self.grid, shape, 400.0 / gsd_m, 2)
        self.rock_a = Fbm(rng_a, self.grid, shape, 60.0 / gsd_m, 4)
        self.rock_g = ValueNoise(rng_a, shape, 2.0 / gsd_m)
        self.veg_n = ValueNoise(rng_l, shape, 80 / gsd_m)
        self.scrub_n = ValueNoise(rng_l, shape, 200 / gsd_m)
        self.crowns_s = ValueNoise(rng_l, shape, max(3.0 / gsd_m, 1.2))
        self.crowns_r = ValueNoise(rng_l, shape, max(6.0 / gsd_m, 1.2))
        self.shadow = cgrid.field(terrain_shadow(zc, cg, season, max_len_px=n // 2))

    def rows(self, a, b):
        gsd, season = self.gsd_m, self.season
        z = self.zc.rows(a, b)
        z += np.float32(1.5) * self.rough.rows(a, b)
        river_d = self.river_d.rows(a, b)
        z -= np.float32(4.0) * smoothstep(30.0, 0.0, river_d)
        # --- appearance: rock colour by stratum, slope; benches with scrub; river and riparian
        gy = cv2.Sobel(z, cv2.CV_32F, 0, 1, ksize=3) / np.float32(8 * gsd)
        gx = cv2.Sobel(z, cv2.CV_32F, 1, 0, ksize=3) / np.float32(8 * gsd)
        slope = np.sqrt(gx * gx + gy * gy)
        del gx, gy
        # strata bands of 9 m: on steep walls a band is narrower than a pixel, so fade the
        # banding out where its phase changes faster than ~1 rad per pixel (no hatching moire)
        phase_per_px = slope * np.float32(gsd / 9.0)
        band_amp = smoothstep(1.2, 0.4, phase_per_px)
        band = np.sin((z + np.float32(1000.0)) / np.float32(9.0) + np.float32(1.2) * self.band_n.rows(a, b))
        band *= band_amp
        band *= np.float32(0.5)
        band += np.float32(0.5)
        del phase_per_px, band_amp
        rock_a = np.float32([0.66, 0.42, 0.28])
        rock_b = np.float32([0.80, 0.66, 0.50])
        rgb = rock_a + (rock_b - rock_a) * band[..., None]
        del band
        tex = self.rock_a.rows(a, b)
        tex *= np.float32(0.06)
        tex += np.float32(0.05) * self.rock_g.rows(a, b)
        tex += np.float32(1.0)
        rgb *= tex[..., None]
        del tex
        flat = smoothstep(0.5, 0.15, slope)
        veg = np.float32([[0.42, 0.42, 0.30], [0.50, 0.44, 0.32], [0.80, 0.80, 0.80], [0.40, 0.44, 0.28]][season.index])
        tint(rgb, flat * (0.35 + 0.3 * self.veg_n.rows(a, b)), veg, 1.0)
        if season.snow > 0:
            tint(rgb, flat * smoothstep(-40.0, 20.0, z), (0.88, 0.88, 0.90), season.snow)
        scrub = flat * smoothstep(0.3, 0.7, self.scrub_n.rows(a, b))
        paint_trees(rgb, scrub, self.crowns_s.rows(a, b), season, gsd, 4.0, 0.25)
        half = 12.0 + 4.0 * season.water_level
        wet = river_d < half
        rgb[wet] = water_colour(1 - river_d[wet] / half, season) * np.float32([1.4, 1.3, 1.0])
        rip = ((river_d >= half) & (river_d < half + 15.0)).astype(np.float32) * 0.7
        paint_trees(rgb, rip, self.crowns_r.rows(a, b), season, gsd, 8.0, 0.6)
        del flat, scrub, rip, slope, river_d
        hs = hillshade(z, gsd, season)
        sh = cv2.GaussianBlur(self.shadow.rows(a, b), (0, 0), 2.0)
        sh *= np.float32(-0.85)
        sh += np.float32(1.0)
        hs *= sh
        hs *= np.float32(0.95)
        hs += np.float32(0.25)
        rgb *= hs[..., None]
        return rgb, z
