"""Local refinement of a global placement by independent tiles, and their robust consensus.

After the whole-frame placement at a coarse level, a grid of tiles of the ortho frame is
searched, each on its own, in a small box around the placed position: first at a middle level
wide enough to cover the coarse level's uncertainty, then at full resolution. Tiles are
independent measurements of the local offset, so their agreement tells a true placement from a
false one (a false peak of one tile lands anywhere; the true offsets of all tiles agree up to
the smooth distortion an attitude error leaves in the ortho view).

Consensus (`tile_consensus`): every tile's offset is a translation hypothesis; the one with the
largest NCC-weighted support within `consensus_px` wins; then an affine map ortho -> map is fitted
to its supporters (iteratively reweighted, Cauchy) and the inliers are those within
`inlier_px` of it. The per-correspondence variance comes from the affine residuals.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from testbench.navigation.ismn.features import robust_image


def subpixel_peak(res: np.ndarray, x: int, y: int) -> tuple[float, float]:
    """Quadratic (parabola) refinement of an integer peak of a score surface, per axis."""
    def fit(l, c, r):
        den = l - 2.0 * c + r
        return 0.0 if den >= 0 else float(np.clip(0.5 * (l - r) / den, -0.5, 0.5))
    dx = fit(res[y, x - 1], res[y, x], res[y, x + 1]) if 0 < x < res.shape[1] - 1 else 0.0
    dy = fit(res[y - 1, x], res[y, x], res[y + 1, x]) if 0 < y < res.shape[0] - 1 else 0.0
    return x + dx, y + dy


# Per-tile reductions through OpenCV: numpy's mean/std cost ~20 us of call overhead on a
# 100 x 100 crop, and a frame makes ~150 of them (about 4 ms of the ~40 ms budget).
def _valid_share(valid: np.ndarray) -> float:
    """Share of True pixels of a bool (H, W) array (its mean)."""
    return cv2.countNonZero(valid.view(np.uint8)) / valid.size if valid.size else float("nan")


def _std(img: np.ndarray) -> float:
    """Population standard deviation of a single-channel image (as ndarray.std())."""
    return float(cv2.meanStdDev(img)[1][0, 0]) if img.size else float("nan")


def feature_crop(img, valid, x, y, w, h, kind, pad=8):
    """Appearance-robust feature of img[y:y+h, x:x+w], computed with `pad` pixels of context."""
    H, W = img.shape
    xa, ya, xb, yb = max(0, x - pad), max(0, y - pad), min(W, x + w + pad), min(H, y + h + pad)
    f, _ = robust_image(img[ya:yb, xa:xb], valid[ya:yb, xa:xb], kind)
    return f[y - ya:y - ya + h, x - xa:x - xa + w]


@dataclass(frozen=True)
class TileMatches:
    """ortho_px, map_px (N, 2) tile centres (col, row) at full resolution; ncc (N,) peak NCC;
    sharp (N,) peak sharpness (NCC drop one pixel away, larger is a better-defined peak)."""

    ortho_px: np.ndarray
    map_px: np.ndarray
    ncc: np.ndarray
    sharp: np.ndarray

    @staticmethod
    def empty() -> "TileMatches":
        z = np.zeros((0, 2))
        return TileMatches(z, z, np.zeros(0), np.zeros(0))


def tile_grid(valid0: np.ndarray, coarse_feat: np.ndarray, sL: int, tile_px: int, nx: int, ny: int,
              max_tiles: int, min_valid: float = 0.9) -> tuple[int, list[tuple[int, int]]]:
    """(tile side T0, [(x0, y0)]) of up to max_tiles candidate tiles on an nx x ny grid over the
    ortho frame, mostly valid, ranked by texture (variance of the coarse feature)."""
    Ho, Wo = valid0.shape
    T0 = int(min(tile_px, Wo // 2, Ho // 2)) // 4 * 4
    if T0 < 16:
        return T0, []
    cands = []
    for j in range(ny):
        for i in range(nx):
            x0 = int(round(i * (Wo - T0) / max(1, nx - 1)))
            y0 = int(round(j * (Ho - T0) / max(1, ny - 1)))
            if _valid_share(valid0[y0:y0 + T0, x0:x0 + T0]) < min_valid:
                continue
            c = coarse_feat[y0 // sL:(y0 + T0) // sL + 1, x0 // sL:(x0 + T0) // sL + 1]
            cands.append((_std(c) ** 2 if c.size else 0.0, x0, y0))
    cands.sort(reverse=True)
    return T0, [(x0, y0) for _, x0, y0 in cands[:max_tiles]]


def refine_tiles(pyr_o, pyr_m, origin0, offset0, radius0_px: float, tiles, T0: int, kind: str,
                 min_ncc: float, final_radius_px: int = 2, map_feat0: np.ndarray | None = None) -> TileMatches:
    """Search each tile around the global placement (origin0 + offset0, full-resolution px).

    radius0_px: full-resolution uncertainty of offset0. The first level searched is the
    coarsest at which the tile is still >= 24 px and the radius <= 6 px; each finer level then
    searches final_radius_px around the previous result (plus the half pixel it had).
    map_feat0: the map window's full-resolution feature image when the caller has it (crops of
    it replace per-tile feature computation on the map side).
    """
    n_lev = len(pyr_o)
    lev0 = 0
    while lev0 + 1 < n_lev and radius0_px / 2 ** lev0 > 6 and T0 / 2 ** (lev0 + 1) >= 24:
        lev0 += 1
    o_list, m_list, n_list, s_list = [], [], [], []
    origin0 = np.asarray(origin0, float)
    for x0, y0 in tiles:
        off = np.array(offset0, float)
        ncc, sharp = -1.0, 0.0
        for lev in range(lev0, -1, -1):
            s = 2**lev
            T = T0 // s
            go, vo = pyr_o[lev]
            gm, vm = pyr_m[lev]
            tx, ty = x0 // s, y0 // s
            r = int(math.ceil(radius0_px / s)) + 1 if lev == lev0 else final_radius_px
            mx = int(round(tx + (origin0[0] + off[0]) / s)) - r
            my = int(round(ty + (origin0[1] + off[1]) / s)) - r
            if mx < 0 or my < 0 or mx + T + 2 * r > gm.shape[1] or my + T + 2 * r > gm.shape[0] \
                    or _valid_share(vm[my:my + T + 2 * r, mx:mx + T + 2 * r]) < 0.95:
                ncc = -1.0
                break
            tmpl = feature_crop(go, vo, tx, ty, T, T, kind)
            if lev == 0 and map_feat0 is not None:
                region = map_feat0[my:my + T + 2 * r, mx:mx + T + 2 * r]
            else:
                region = feature_crop(gm, vm, mx, my, T + 2 * r, T + 2 * r, kind)
            if _std(tmpl) < 1e-4 or _std(region) < 1e-4:
                ncc = -1.0
                break
            res = cv2.matchTemplate(region, tmpl, cv2.TM_CCOEFF_NORMED)
            _, ncc, _, (px, py) = cv2.minMaxLoc(res)
            if not (0 < px < res.shape[1] - 1 and 0 < py < res.shape[0] - 1):
                # The best score on the search box's edge: the true peak lies outside it (the
                # tile is displaced farther than its search allows, e.g. by an unmodelled
                # heading error), and the edge value is no measurement of where.
                ncc = -1.0
                break
            sx, sy = subpixel_peak(res, px, py)
            off = np.array([(mx + sx - tx) * s - origin0[0], (my + sy - ty) * s - origin0[1]])
            if lev == 0:
                nb = [res[py, px - 1] if px > 0 else ncc, res[py, px + 1] if px + 1 < res.shape[1] else ncc,
                      res[py - 1, px] if py > 0 else ncc, res[py + 1, px] if py + 1 < res.shape[0] else ncc]
                sharp = float(ncc - max(nb))
        if ncc < min_ncc:
            continue
        c = np.array([x0 + (T0 - 1) / 2.0, y0 + (T0 - 1) / 2.0])
        o_list.append(c)
        m_list.append(c + origin0 + off)
        n_list.append(ncc)
        s_list.append(sharp)
    if not o_list:
        return TileMatches.empty()
    return TileMatches(np.array(o_list), np.array(m_list), np.array(n_list), np.array(s_list))


@dataclass(frozen=True)
class Consensus:
    """inliers (N,) bool; A (2, 3) affine ortho px -> map px (None if under 6 inliers: then a
    translation); var_px2: variance of one correspondence (per axis) from the residuals;
    support: NCC-weighted share of the tiles that agree."""

    inliers: np.ndarray
    A: np.ndarray | None
    var_px2: float
    support: float


def _fit_affine(o, m, w):
    """Weighted least-squares affine (2, 3) with m ~ A [o, 1]."""
    X = np.c_[o, np.ones(len(o))] * np.sqrt(w)[:, None]
    Y = m * np.sqrt(w)[:, None]
    sol, *_ = np.linalg.lstsq(X, Y, rcond=None)
    return sol.T


def tile_consensus(t: TileMatches, consensus_px: float = 3.0, inlier_px: float = 1.5,
                   min_var_px2: float = 0.02) -> Consensus | None:
    """Robust agreement of the tiles (module docstring); None when no two tiles agree."""
    n = len(t.ncc)
    if n < 2:
        return None
    d = t.map_px - t.ortho_px
    w = np.clip(t.ncc, 0.05, 1.0)
    # Translation hypotheses: each tile's offset; support = NCC weight of those within reach.
    dist = np.hypot(*(d[:, None, :] - d[None, :, :]).transpose(2, 0, 1))
    close = dist < consensus_px
    score = close.astype(float) @ w
    best = int(np.argmax(score))
    inl = close[best].copy()
    if inl.sum() < 2:
        return None
    def model(inl):
        """(A or None, predicted map px of every tile) from the tiles in inl."""
        if inl.sum() >= 6:
            o, m, ww = t.ortho_px[inl], t.map_px[inl], w[inl]
            A = _fit_affine(o, m, ww)
            for _ in range(3):  # Cauchy IRLS: a stray tile does not bend the fit
                r = np.hypot(*(m - (o @ A[:, :2].T + A[:, 2])).T)
                A = _fit_affine(o, m, ww / (1.0 + (r / inlier_px) ** 2))
            return A, t.ortho_px @ A[:, :2].T + A[:, 2]
        return None, t.ortho_px + np.average(d[inl], axis=0, weights=w[inl])

    for _ in range(3):
        A, pred = model(inl)
        new = np.hypot(*(t.map_px - pred).T) < (inlier_px if A is not None else consensus_px)
        if new.sum() < 2 or (new == inl).all():
            break
        inl = new
    A, pred = model(inl)
    k = int(inl.sum())
    resid = (t.map_px - pred)[inl]
    dof = 2 * k - (6 if A is not None else 2)
    var = float((resid**2).sum()) / dof if dof > 0 else 0.5
    return Consensus(inl, A, max(var, min_var_px2), float(w[inl].sum() / w.sum()))
