"""Flat-ground rendering: the exact plane homography, mip-mapped warps, clip planes and sky.

Geometry. A pixel p = [u, v, 1] of an ideal pinhole camera has the ray d = M p in NED with
M = R_nc K^-1 (camera->NED times the inverse intrinsics), scaled so that its camera depth is 1.
It meets the plane down = D at d * t with t = h / w, w = m3 . p (m3 the down row of M,
h = D - C_down the height of the optical centre above the plane), and t is the camera depth z_c.
So [east, north, 1] ~ [C_e m3 + h m2; C_n m3 + h m1; m3] p: a homography. Ground is the strip
h / far < w < h / near (clip planes on z_c are lines parallel to the horizon w = 0).

Filtering. The map-pixels-per-image-pixel scale (largest singular value of the homography's
Jacobian) is evaluated at tile corners; each tile is warped from the pyramid level nearest to
log2(scale), and neighbouring tiles of the same level are merged into rectangles, so a nadir
frame is one warp call.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from itertools import groupby

import cv2
import numpy as np

from testbench.core.camera_geometry import PinholeCamera
from testbench.sensors.camera.pyramid import RasterPyramid
from testbench.sensors.camera.sky import COARSE_PX, apply_sky_and_haze, coarse_axes, haze_alpha

TILE_PX = 64
_SKY, _NEAR = -1, -2


@dataclass(frozen=True)
class PlaneView:
    """Homographies of one camera pose over one ground plane.

    H_ne (3, 3): [east, north, 1] ~ H_ne @ [u, v, 1]; H_map: the same onto level-0 map pixels
    (col, row); w_coef (3,): w = w_coef . [u, v, 1]; h_m: height above the plane (m);
    w_far, w_near: ground is w_far < w < w_near.
    """

    H_ne: np.ndarray
    H_map: np.ndarray
    w_coef: np.ndarray
    h_m: float
    w_far: float
    w_near: float


def plane_view(camera: PinholeCamera, centre_ned_m, R_nc, ground_down_m: float,
               map_from_ne: np.ndarray, near_m: float, far_m: float) -> PlaneView:
    """The homographies for an ideal camera at `centre_ned_m` with attitude R_nc (cam->NED)."""
    C = np.asarray(centre_ned_m, float)
    M = np.asarray(R_nc, float) @ np.linalg.inv(camera.K)
    h = float(ground_down_m - C[2])
    H_ne = np.vstack([C[1] * M[2] + h * M[1], C[0] * M[2] + h * M[0], M[2]])
    H_map = map_from_ne @ H_ne
    if h > 0:
        w_far, w_near = h / far_m, h / max(near_m, 1e-9)
    else:  # at or below the plane: no ground in view
        w_far, w_near = np.inf, np.inf
    return PlaneView(H_ne, H_map, M[2].copy(), h, w_far, w_near)


def map_scale(H: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Largest singular value of d(col, row)/d(u, v) of the homography H at pixels (u, v)."""
    w = H[2, 0] * u + H[2, 1] * v + H[2, 2]
    x = (H[0, 0] * u + H[0, 1] * v + H[0, 2]) / w
    y = (H[1, 0] * u + H[1, 1] * v + H[1, 2]) / w
    a = (H[0, 0] - x * H[2, 0]) / w
    b = (H[0, 1] - x * H[2, 1]) / w
    c = (H[1, 0] - y * H[2, 0]) / w
    d = (H[1, 1] - y * H[2, 1]) / w
    fro = a * a + b * b + c * c + d * d
    det = a * d - b * c
    return np.sqrt(0.5 * (fro + np.sqrt(np.maximum(fro * fro - 4.0 * det * det, 0.0))))


def tile_levels(view: PlaneView, width: int, height: int, max_level: int, lod_bias: float):
    """Pyramid level per TILE_PX tile (ny, nx): >= 0, or _SKY / _NEAR for tiles without ground."""
    xs = np.append(np.arange(0, width, TILE_PX), width)
    ys = np.append(np.arange(0, height, TILE_PX), height)
    U, V = np.meshgrid(xs - 0.5, ys - 0.5)
    wc = view.w_coef
    W = wc[0] * U + wc[1] * V + wc[2]
    # Corners beyond the far plane: evaluate the scale where the tile meets the far line.
    w_lim = max(view.w_far, 1e-7 * max(abs(wc[2]), 1e-12)) * (1.0 + 1e-6)
    g2 = wc[0] ** 2 + wc[1] ** 2
    with np.errstate(all="ignore"):  # camera at/below the plane: w_lim = inf, all tiles sky
        if g2 > 0:
            shift = np.where(W < w_lim, (w_lim - W) / g2, 0.0)
            Us, Vs = U + shift * wc[0], V + shift * wc[1]
        else:
            Us, Vs = U, V
        s = map_scale(view.H_map, Us, Vs)
        lod = np.log2(np.maximum(s, 1e-12)) + lod_bias
    lod = np.where(np.isfinite(lod), lod, max_level)
    lvl = np.clip(np.floor(lod + 0.5), 0, max_level).astype(int)
    lvl_t = np.maximum(np.maximum(lvl[:-1, :-1], lvl[1:, :-1]), np.maximum(lvl[:-1, 1:], lvl[1:, 1:]))
    w_lo = np.minimum(np.minimum(W[:-1, :-1], W[1:, :-1]), np.minimum(W[:-1, 1:], W[1:, 1:]))
    w_hi = np.maximum(np.maximum(W[:-1, :-1], W[1:, :-1]), np.maximum(W[:-1, 1:], W[1:, 1:]))
    lvl_t[w_hi <= view.w_far] = _SKY  # every corner beyond the far line
    lvl_t[w_lo >= view.w_near] = _NEAR  # every corner nearer than the near line
    return lvl_t, xs, ys


def merge_tiles(levels: np.ndarray, xs: np.ndarray, ys: np.ndarray) -> list[tuple[int, int, int, int, int]]:
    """Rectangles (x0, y0, x1, y1, level) covering the tiles with ground: horizontal runs of
    one level, merged downwards while the run repeats."""
    # Plain lists and groupby: indexing numpy scalars in these loops cost ~0.2 ms a frame.
    xs_l, ys_l = xs.tolist(), ys.tolist()
    rects: list[list[int]] = []
    open_runs: dict[tuple[int, int, int], list[int]] = {}
    for j, row in enumerate(levels.tolist()):
        new_open = {}
        i = 0
        for level, group in groupby(row):
            k = i + sum(1 for _ in group)
            if level >= 0:
                run = (xs_l[i], xs_l[k], level)
                r = open_runs.get(run)
                if r is not None:
                    r[3] = ys_l[j + 1]
                else:
                    r = [run[0], ys_l[j], run[1], ys_l[j + 1], level]
                    rects.append(r)
                new_open[run] = r
            i = k
        open_runs = new_open
    return [tuple(r) for r in rects]


def warp_ground(pyr: RasterPyramid, H_map: np.ndarray, width: int, height: int,
                rects) -> np.ndarray:
    """(height, width, 4) RGBA warped from the pyramid, rectangle by rectangle."""
    def warp(x0, y0, x1, y1, L, dst=None):
        s = 0.5**L
        Hr = np.diag([s, s, 1.0]) @ H_map @ np.array([[1.0, 0, x0], [0, 1.0, y0], [0, 0, 1.0]])
        return cv2.warpPerspective(pyr.levels[L], Hr, (x1 - x0, y1 - y0), dst=dst,
                                   flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                   borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0, 0))

    if len(rects) == 1 and rects[0][:4] == (0, 0, width, height):
        return warp(*rects[0])
    covered = sum((x1 - x0) * (y1 - y0) for x0, y0, x1, y1, _ in rects)
    out = np.empty((height, width, 4), np.uint8) if covered == width * height else np.zeros((height, width, 4), np.uint8)
    for x0, y0, x1, y1, L in rects:
        warp(x0, y0, x1, y1, L, out[y0:y1, x0:x1])  # straight into the frame (a strided view)
    return out


def samples_inside_map(pyr: RasterPyramid, H_map: np.ndarray, rects) -> bool:
    """True when every pixel of the rectangles samples its pyramid level strictly inside the
    level's pixel grid (the frame's footprint is a convex quadrilateral on the plane, so the
    corners decide; the rectangles must hold ground only, w > 0)."""
    r = np.asarray([rc[:5] for rc in rects], float)  # (n, 5): x0, y0, x1, y1, level
    u = np.stack([r[:, 0], r[:, 2] - 1, r[:, 0], r[:, 2] - 1], axis=1).ravel()
    v = np.stack([r[:, 1], r[:, 1], r[:, 3] - 1, r[:, 3] - 1], axis=1).ravel()
    p = H_map @ np.vstack([u, v, np.ones_like(u)])
    if not (p[2] > 0).all():
        return False
    s = np.repeat(0.5 ** r[:, 4], 4)
    col, row = s * p[0] / p[2], s * p[1] / p[2]
    sizes = np.array([pyr.levels[int(L)].shape[:2] for L in r[:, 4]], float)  # (n, 2): h, w
    h, w = np.repeat(sizes[:, 0], 4), np.repeat(sizes[:, 1], 4)
    return bool((col >= 0).all() and (col <= w - 1).all() and (row >= 0).all() and (row <= h - 1).all())


@lru_cache(maxsize=16)
def constant_mask(height: int, width: int, value: bool) -> np.ndarray:
    """A read-only (height, width) bool mask filled with `value`, shared between frames."""
    m = np.full((height, width), value, bool)
    m.setflags(write=False)
    return m


def ground_sky_masks(view: PlaneView, width: int, height: int) -> tuple[np.ndarray, np.ndarray, bool, bool]:
    """(ground, sky, all_ground, any_sky): (H, W) bool masks from the clip lines, exact per
    pixel, evaluated only in the bands of rows that a line crosses; all_ground: every pixel is
    ground; any_sky: some pixel is sky (both known from the bands, without a pass over the
    masks)."""
    wc = view.w_coef
    # w is linear in (u, v): the frame's corners bound it, so a frame with every corner on
    # ground is ground throughout (the common downward view). Its masks are then the shared
    # read-only constants: fresh 2 MB masks cost ~0.4 ms a frame in page faults alone.
    corners_w = [wc[0] * uu + wc[1] * vv + wc[2] for uu in (0.0, width - 1.0) for vv in (0.0, height - 1.0)]
    if min(corners_w) > view.w_far and max(corners_w) < view.w_near:
        return constant_mask(height, width, True), constant_mask(height, width, False), True, False
    ground = np.ones((height, width), bool)
    sky = np.zeros((height, width), bool)
    any_sky = False  # (all_ground is False from here: some corner, hence some band, is not ground)
    u = np.arange(width, dtype=np.float64)
    for y0 in range(0, height, TILE_PX):
        y1 = min(y0 + TILE_PX, height)
        cw = [wc[0] * uu + wc[1] * vv + wc[2] for uu in (0.0, width - 1.0) for vv in (y0, y1 - 1.0)]
        lo, hi = min(cw), max(cw)
        if lo > view.w_far and hi < view.w_near:
            continue
        if hi <= view.w_far:
            ground[y0:y1] = False
            sky[y0:y1] = True
            any_sky = True
            continue
        v = np.arange(y0, y1, dtype=np.float64)
        w = wc[0] * u[None, :] + (wc[1] * v + wc[2])[:, None]
        sky[y0:y1] = w <= view.w_far
        ground[y0:y1] = (w > view.w_far) & (w < view.w_near)
        any_sky = any_sky or bool(sky[y0:y1].any())
    return ground, sky, False, any_sky


def render_plane(camera: PinholeCamera, centre_ned_m, R_nc, pyr: RasterPyramid,
                 ground_down_m: float, opts) -> tuple[np.ndarray, np.ndarray, np.ndarray, PlaneView, bool]:
    """Render an ideal (undistorted) pinhole frame over flat ground.

    Returns rgb (H, W, 3) uint8, valid (H, W) bool (ground with map data), sky (H, W) bool, the
    PlaneView used and `complete`: True when every pixel is ground with map data (then valid
    is all True and nothing is off the map: callers skip counting).
    """
    W, H = camera.width_px, camera.height_px
    view = plane_view(camera, centre_ned_m, R_nc, ground_down_m, pyr.map_from_ne, opts.near_m, opts.far_m)
    levels, xs, ys = tile_levels(view, W, H, pyr.max_level, opts.lod_bias)
    rects = merge_tiles(levels, xs, ys)
    rgba = warp_ground(pyr, view.H_map, W, H, rects) if rects else np.zeros((H, W, 4), np.uint8)
    rgb = cv2.cvtColor(rgba, cv2.COLOR_RGBA2RGB)
    ground, sky, all_ground, any_sky = ground_sky_masks(view, W, H)
    full = bool(rects) and sum((x1 - x0) * (y1 - y0) for x0, y0, x1, y1, _ in rects) == W * H
    # The common case (the whole frame on ground inside a fully valid map) is known from the
    # geometry alone: no pass over the alpha channel or the masks (each ~0.3 ms at 1080p).
    complete = full and pyr.all_valid and all_ground and samples_inside_map(pyr, view.H_map, rects)
    if complete:
        valid = ground  # every sample inside a fully valid map: alpha is 255 throughout
    else:
        valid = (cv2.extractChannel(rgba, 3) >= 128) & ground
    # Sky colour and haze on a coarse grid.
    need_haze = opts.haze_visibility_m is not None
    if not need_haze and not any_sky:
        if not complete:
            nodata = ~valid
            if nodata.any():
                rgb[nodata] = 0  # black, as apply_sky_and_haze leaves it
    else:
        cu, cv_ = coarse_axes(W, H, COARSE_PX)
        U, V = np.meshgrid(cu, cv_)
        P = np.stack([U, V, np.ones_like(U)], axis=-1)
        M = np.asarray(R_nc, float) @ np.linalg.inv(camera.K)
        d = P @ M.T
        norm = np.linalg.norm(d, axis=-1)
        elev = np.arcsin(np.clip(-d[..., 2] / norm, -1.0, 1.0))
        alpha = None
        if need_haze and view.h_m > 0:
            with np.errstate(all="ignore"):
                rng_m = np.where(d[..., 2] > view.w_far, view.h_m / d[..., 2] * norm, opts.far_m * 10)
            alpha = haze_alpha(np.minimum(rng_m, 1e9), opts.haze_visibility_m)
        # Haze only on pixels with data: no-data stays black.
        rgb = apply_sky_and_haze(rgb, sky, valid, elev.astype(np.float32), alpha, COARSE_PX, opts)
    return rgb, valid, sky, view, complete
