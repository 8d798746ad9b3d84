"""Rendering over relief: rays cast against the elevation raster, then cv2.remap of the map.

Rays are cast exactly on a coarse grid of pixels (every `relief_cell_px`), their ground points
interpolated bilinearly inside cells whose four corners agree (all hit ground at similar
depths), and cast again at every pixel of the cells that straddle an occlusion edge or the
skyline. The imagery is then resampled tile by tile from the pyramid level that the local
footprint calls for, as over flat ground.

Ray casting: a ray o + t d (d scaled to unit camera depth, so t is z_c) descends towards the
terrain with steps that cannot cross it: the gap g between the ray and the terrain can shrink
no faster than (d_down + S |d_horizontal|) per unit t, S the steepest terrain slope, so a step
g / (d_down + S |d_h|) is safe (sphere tracing with a Lipschitz bound); a minimum step of half
a DEM cell keeps grazing rays moving, and a crossing is polished by false position.
"""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np

from testbench.core.camera_geometry import PinholeCamera
from testbench.sensors.camera.flat import TILE_PX, merge_tiles
from testbench.sensors.camera.lens import normalized_grid, undistort_pixels
from testbench.sensors.camera.pyramid import DemSampler, RasterPyramid
from testbench.sensors.camera.sky import apply_sky_and_haze, coarse_axes, haze_alpha, upsample

_MAX_ITER = 400
# Minimum step grows with distance (a share of the range): far terrain is seen at a coarse
# footprint, and grazing rays over rough ground would otherwise creep half a cell at a time.
_REL_STEP = 0.02
_REFINE_ITER = 6
_DEPTH_RATIO = 1.15
_OUT = -1.0e5  # map coordinate of "no ground": far outside any map


def cast_rays(dem: DemSampler, centre_ned_m, dirs_ned: np.ndarray, near_m: float, far_m: float):
    """First terrain intersection of rays centre + t dirs (dirs (n, 3) NED, t = camera depth).

    Returns hit (n,) bool and t (n,) (nan where the ray meets no terrain before far_m).
    Outside the raster the terrain continues its edge heights.

    Each iteration takes the longest step known to be safe: the Lipschitz step, or a jump of
    2^j DEM cells horizontally when the ray at the far end of the jump is still above the
    max-filtered terrain around the current cell (empty-space skipping); failing both, half a
    cell. A step that ends under the terrain brackets the crossing, refined by false position.
    """
    C = np.asarray(centre_ned_m, float)
    up0 = -C[2]
    d = np.asarray(dirs_ned, float)
    n = len(d)
    dd = d[:, 2]
    dh = np.hypot(d[:, 0], d[:, 1])
    dn = np.linalg.norm(d, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = np.where(up0 > dem.h_max, np.where(dd > 0, (up0 - dem.h_max) / dd, np.inf), 0.0)
        t_stop = np.where(dd > 0, (up0 - dem.h_min) / dd,
                          np.where(dd < 0, (dem.h_max - up0) / -dd, np.inf))
    t0 = np.maximum(t0, near_m)
    t_stop = np.minimum(t_stop, far_m)
    rate = dd + dem.slope_max * dh           # fastest closing speed of the gap per unit t
    min_step = 0.5 * dem.raster.gsd_m / dn
    levels = list(range(0, len(dem.max_maps), 2))  # jumps of 1, 4, 16, 64, 256 cells
    jump_m = dem.raster.gsd_m * (2.0 ** np.array(levels, float))[:, None]  # (J, 1)
    hit = np.zeros(n, bool)
    t_hit = np.full(n, np.nan)

    def gap(idx, t):
        p = C + t[:, None] * d[idx]
        return -p[:, 2] - dem.height_at(p[:, 0], p[:, 1])

    idx = np.nonzero((t0 <= t_stop) & (rate > 0))[0]
    t = t0[idx]
    g = gap(idx, t)
    # Already under the terrain at the start (camera below ground): hit at once.
    under = g <= 0
    hit[idx[under]] = True
    t_hit[idx[under]] = t[under]
    idx, t, g = idx[~under], t[~under], g[~under]
    lo_idx, lo_t, lo_g, hi_t, hi_g = [], [], [], [], []
    for _ in range(_MAX_ITER):
        if idx.size == 0:
            break
        step = np.maximum(g / rate[idx], min_step[idx] + _REL_STEP * t)
        # Empty-space skipping over the max-filtered terrain.
        with np.errstate(divide="ignore", invalid="ignore"):
            dt_j = jump_m / dh[idx]                          # (J, m) t to go 2^j cells
            pn = C[0] + t * d[idx, 0]
            pe = C[1] + t * d[idx, 1]
            r, c = dem.cell_index(pn, pe)
            up_end = up0 - (t + dt_j) * dd[idx]
            bounds = np.stack([dem.max_maps[j][r, c] for j in levels])
            ok = (up_end > bounds) & np.isfinite(dt_j)
            jump = np.where(ok, dt_j, 0.0).max(axis=0)
        step = np.maximum(step, jump)
        t_new = np.minimum(t + step, t_stop[idx])
        stuck = t_new <= t  # already at t_stop: no terrain on this ray
        g_new = gap(idx, t_new)
        crossed = (g_new <= 0) & ~stuck
        lo_idx.append(idx[crossed]); lo_t.append(t[crossed]); lo_g.append(g[crossed])
        hi_t.append(t_new[crossed]); hi_g.append(g_new[crossed])
        keep = ~crossed & ~stuck
        idx, t, g = idx[keep], t_new[keep], g_new[keep]
    if idx.size:  # grazing rays that never settled: take where they are
        hit[idx] = True
        t_hit[idx] = t
    if lo_idx:
        bi = np.concatenate(lo_idx)
        a, ga = np.concatenate(lo_t), np.concatenate(lo_g)
        b, gb = np.concatenate(hi_t), np.concatenate(hi_g)
        for _ in range(_REFINE_ITER):
            frac = np.clip(ga / (ga - gb), 0.05, 0.95)
            m = a + frac * (b - a)
            gm = gap(bi, m)
            below = gm <= 0
            b = np.where(below, m, b); gb = np.where(below, gm, gb)
            a = np.where(below, a, m); ga = np.where(below, ga, gm)
        hit[bi] = True
        t_hit[bi] = a + ga / (ga - gb) * (b - a)
    return hit, t_hit


@lru_cache(maxsize=8)
def _coarse_rays(camera: PinholeCamera, step: int) -> tuple[np.ndarray, np.ndarray]:
    """Undistorted normalised coordinates (ny, nx, 2) of the coarse grid pixels."""
    cu, cv_ = coarse_axes(camera.width_px, camera.height_px, step)
    U, V = np.meshgrid(cu, cv_)
    x, y = undistort_pixels(camera, U, V)
    out = np.stack([x, y], axis=-1)
    out.setflags(write=False)
    return out


def _dirs(xy: np.ndarray, R_nc) -> np.ndarray:
    """NED directions (..., 3) of normalised camera coordinates (..., 2), unit camera depth."""
    ones = np.ones(xy.shape[:-1] + (1,))
    return np.concatenate([xy, ones], axis=-1) @ np.asarray(R_nc, float).T


def _cell_scale(col: np.ndarray, row: np.ndarray, step: int) -> np.ndarray:
    """Largest singular value of d(col,row)/d(u,v) per coarse cell (ny-1, nx-1)."""
    a = (col[:-1, 1:] - col[:-1, :-1]) / step
    c = (row[:-1, 1:] - row[:-1, :-1]) / step
    b = (col[1:, :-1] - col[:-1, :-1]) / step
    d = (row[1:, :-1] - row[:-1, :-1]) / step
    fro = a * a + b * b + c * c + d * d
    det = a * d - b * c
    return np.sqrt(0.5 * (fro + np.sqrt(np.maximum(fro * fro - 4 * det * det, 0.0))))


def render_relief(camera: PinholeCamera, centre_ned_m, R_nc, pyr: RasterPyramid, dem: DemSampler, opts):
    """Render `camera` (lens distortion included) over the DEM.

    Returns rgb (H, W, 3) uint8, valid (H, W) bool, sky (H, W) bool and a function that gives
    the ground points (H, W, 3) NED on demand.
    """
    W, H = camera.width_px, camera.height_px
    k = int(opts.relief_cell_px)
    if k < 1 or k > 32 or (k & (k - 1)):
        raise ValueError(f"relief_cell_px must be a power of two <= 32 (got {k})")
    C = np.asarray(centre_ned_m, float)
    xy_c = _coarse_rays(camera, k)
    ny, nx = xy_c.shape[:2]
    d_c = _dirs(xy_c, R_nc).reshape(-1, 3)
    hit_c, t_c = cast_rays(dem, C, d_c, opts.near_m, opts.far_m)
    A = pyr.map_from_ne
    with np.errstate(invalid="ignore"):
        gn = C[0] + t_c * d_c[:, 0]
        ge = C[1] + t_c * d_c[:, 1]
    col_c = np.where(hit_c, A[0, 0] * ge + A[0, 2], _OUT).reshape(ny, nx)
    row_c = np.where(hit_c, A[1, 1] * gn + A[1, 2], _OUT).reshape(ny, nx)
    hit2 = hit_c.reshape(ny, nx)
    t2 = np.where(hit_c, t_c, np.inf).reshape(ny, nx)

    corners_hit = np.stack([hit2[:-1, :-1], hit2[1:, :-1], hit2[:-1, 1:], hit2[1:, 1:]])
    corners_t = np.stack([t2[:-1, :-1], t2[1:, :-1], t2[:-1, 1:], t2[1:, 1:]])
    all_hit = corners_hit.all(axis=0)
    mixed = corners_hit.any(axis=0) & ~all_hit
    with np.errstate(invalid="ignore"):
        deep = all_hit & (corners_t.max(axis=0) > _DEPTH_RATIO * corners_t.min(axis=0))
    refine = mixed | deep

    coarse = np.ascontiguousarray(np.stack([col_c, row_c], axis=-1), np.float32)
    maps = upsample(coarse, W, H, k)
    hit = upsample(hit2.view(np.uint8), W, H, k, cv2.INTER_NEAREST).view(bool)
    if refine.any():
        # Cell (j, i) covers pixels [j k, (j + 1) k) x [i k, (i + 1) k): nearest-neighbour
        # resize by the integer factor k (src = floor(dst / k)).
        r8 = refine.view(np.uint8)
        pix = cv2.resize(r8, (r8.shape[1] * k, r8.shape[0] * k), interpolation=cv2.INTER_NEAREST)[:H, :W].view(bool)
        vv, uu = np.nonzero(pix)
        xy = normalized_grid(camera)[vv, uu]
        d_r = _dirs(xy, R_nc)
        hit_r, t_r = cast_rays(dem, C, d_r, opts.near_m, opts.far_m)
        with np.errstate(invalid="ignore"):
            maps[vv, uu, 0] = np.where(hit_r, A[0, 0] * (C[1] + t_r * d_r[:, 1]) + A[0, 2], _OUT)
            maps[vv, uu, 1] = np.where(hit_r, A[1, 1] * (C[0] + t_r * d_r[:, 0]) + A[1, 2], _OUT)
        hit[vv, uu] = hit_r

    # Pyramid level per tile from the footprint of its fully-hit cells.
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(all_hit & ~deep, _cell_scale(col_c, row_c, k), 0.0)
        lod = np.log2(np.maximum(s, 1e-12)) + opts.lod_bias
    cells_per_tile = TILE_PX // k
    nty, ntx = -(-H // TILE_PX), -(-W // TILE_PX)
    pad = np.full((nty * cells_per_tile, ntx * cells_per_tile), -np.inf)
    pad[: lod.shape[0], : lod.shape[1]] = lod[: nty * cells_per_tile, : ntx * cells_per_tile]
    tile_lod = pad.reshape(nty, cells_per_tile, ntx, cells_per_tile).max(axis=(1, 3))
    any_hit = np.zeros((nty * cells_per_tile, ntx * cells_per_tile), bool)
    ah = corners_hit.any(axis=0)
    any_hit[: ah.shape[0], : ah.shape[1]] = ah[: nty * cells_per_tile, : ntx * cells_per_tile]
    tile_hit = any_hit.reshape(nty, cells_per_tile, ntx, cells_per_tile).any(axis=(1, 3))
    lvl = np.clip(np.floor(np.where(np.isfinite(tile_lod), tile_lod, 0.0) + 0.5), 0, pyr.max_level)
    lvl = np.where(tile_hit, lvl, -1).astype(int)
    xs = np.minimum(np.arange(ntx + 1) * TILE_PX, W)
    ys = np.minimum(np.arange(nty + 1) * TILE_PX, H)
    rgba = np.zeros((H, W, 4), np.uint8)
    for x0, y0, x1, y1, L in merge_tiles(lvl, xs, ys):
        m = maps[y0:y1, x0:x1]
        if L:
            m = m * np.float32(0.5**L)
        rgba[y0:y1, x0:x1] = cv2.remap(pyr.levels[L], m, None, cv2.INTER_LINEAR,
                                       borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0, 0))
    rgb = cv2.cvtColor(rgba, cv2.COLOR_RGBA2RGB)
    valid = hit & (cv2.extractChannel(rgba, 3) >= 128)
    sky = ~hit
    dcn = d_c.reshape(ny, nx, 3)
    norm = np.linalg.norm(dcn, axis=-1)
    elev = np.arcsin(np.clip(-dcn[..., 2] / norm, -1.0, 1.0)).astype(np.float32)
    alpha = haze_alpha(np.minimum(t2 * norm, 1e9), opts.haze_visibility_m) if opts.haze_visibility_m else None
    rgb = apply_sky_and_haze(rgb, sky, valid, elev, alpha, k, opts)

    def ground_points() -> np.ndarray:
        inv = np.linalg.inv(A)
        east = inv[0, 0] * maps[..., 0].astype(np.float64) + inv[0, 2]
        north = inv[1, 1] * maps[..., 1].astype(np.float64) + inv[1, 2]
        down = -dem.height_at(north, east)
        pts = np.stack([north, east, down], axis=-1)
        pts[~hit] = np.nan
        return pts

    return rgb, valid, sky, ground_points, (t2, k)
