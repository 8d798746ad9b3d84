"""Local refinement of a global placement by independent tiles, and their robust consensus.

After the whole-frame placement at a coarse level, a grid of tiles of the ortho frame is
searched, each on its own, in a small box around the placed position: first at a middle level
wide enough to cover the coarse level's uncertainty, then at full resolution. Tiles are
independent measurements of the local offset, so their agreement tells a true placement from a
false one (a false peak of one tile lands anywhere; the true offsets of all tiles agree up to
the smooth distortion an attitude error leaves in the ortho view).

Consensus (`tile_consensus`): every tile's offset is a translation hypothesis; the one with the
largest NCC-weighted support within `consensus_px` wins; then a map ortho -> map is fitted to its
supporters (iteratively reweighted, Cauchy) and the inliers are those within `inlier_px` of it.
The per-correspondence variance comes from the fit's residuals.

The fitted map is an affine when six tiles or more agree (else a translation), or, with
projective=True, a homography (8 dof) when ten or more agree. The ortho view is the ground plane
seen through the estimated camera; an attitude error of that estimate maps it onto the true
ground by a plane homography, whose projective part grows as 1 / cos^2 off nadir (a 120 deg
view over +-44..60 deg: up to three times the nadir shift). An affine cannot follow it, and its
inlier gate keeps the outer tiles whose noise happens to flatten that pattern and drops the
others: the surviving correspondences under-read the tilt signature, and the pose solve turns
the rest into position (paper_ismn_800m frames, prior tilted by 3 mrad: the outer tiles'
displacement read 10-20 % short, a third of the tiles dropped, the fix moved by 0.8-1.2 m; with
the homography 1-2 % and 0.1-0.5 m). See AreaMatcherBase.Params.consensus_model for why the
affine is still the default.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from testbench.navigation.ismn.features import robust_image


def _parabola_vertex(left: float, centre: float, right: float) -> float:
    """Offset in [-0.5, 0.5] of the vertex of the parabola through (-1, left), (0, centre),
    (1, right); 0 when it is not a maximum (or a value is not finite)."""
    den = left - 2.0 * centre + right
    if not den < 0.0:
        return 0.0
    return min(0.5, max(-0.5, 0.5 * (left - right) / den))


def subpixel_peak(res: np.ndarray, x: int, y: int) -> tuple[float, float]:
    """Quadratic (parabola) refinement of an integer peak of a score surface, per axis."""
    # Python floats, not numpy scalars: a frame refines ~50 peaks, and numpy's scalar clip and
    # arithmetic cost ~30 us a peak.
    h, w = res.shape
    c = float(res[y, x])
    dx = _parabola_vertex(float(res[y, x - 1]), c, float(res[y, x + 1])) if 0 < x < w - 1 else 0.0
    dy = _parabola_vertex(float(res[y - 1, x]), c, float(res[y + 1, x])) if 0 < y < h - 1 else 0.0
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
    return feature_of_region(lambda xa, ya, xb, yb: (img[ya:yb, xa:xb], valid[ya:yb, xa:xb]), W, H, x, y, w, h, kind, pad)


def feature_of_region(crop, W, H, x, y, w, h, kind, pad=8):
    """Appearance-robust feature of columns x:x+w, rows y:y+h of a W x H image that crop(x0,
    y0, x1, y1) -> (grey, valid) serves, computed with `pad` pixels of context (fewer at its
    edges)."""
    xa, ya, xb, yb = max(0, x - pad), max(0, y - pad), min(W, x + w + pad), min(H, y + h + pad)
    f, _ = robust_image(*crop(xa, ya, xb, yb), kind)
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


def tile_grid(ortho, coarse_feat: np.ndarray, sL: int, tile_px: int, nx: int, ny: int,
              max_tiles: int, min_valid: float = 0.9) -> tuple[int, list[tuple[int, int]]]:
    """(tile side T0, [(x0, y0)]) of up to max_tiles candidate tiles on an nx x ny grid over the
    ortho frame (an OrthoFrame: it answers each candidate's valid share), mostly valid, ranked
    by texture (variance of the coarse feature)."""
    Ho, Wo = ortho.shape
    T0 = int(min(tile_px, Wo // 2, Ho // 2)) // 4 * 4
    if T0 < 16:
        return T0, []
    cands = []
    for j in range(ny):
        for i in range(nx):
            x0 = int(round(i * (Wo - T0) / max(1, nx - 1)))
            y0 = int(round(j * (Ho - T0) / max(1, ny - 1)))
            if ortho.valid_share(x0, y0, T0, T0) < min_valid:
                continue
            c = coarse_feat[y0 // sL:(y0 + T0) // sL + 1, x0 // sL:(x0 + T0) // sL + 1]
            cands.append((_std(c) ** 2 if c.size else 0.0, x0, y0))
    cands.sort(reverse=True)
    return T0, [(x0, y0) for _, x0, y0 in cands[:max_tiles]]


def refine_tiles(ortho, pyr_m, origin0, offset0, radius0_px: float, tiles, T0: int, kind: str,
                 min_ncc: float, final_radius_px: int = 2, map_feat0: np.ndarray | None = None) -> TileMatches:
    """Search each tile around the global placement (origin0 + offset0, full-resolution px).

    ortho: the ortho frame (an OrthoFrame: the tiles' regions are cut or warped from it at each
    level); pyr_m: the map window's area.Pyramid.

    radius0_px: full-resolution uncertainty of offset0. The first level searched is the
    coarsest at which the tile is still >= 24 px and the radius <= 6 px; each finer level then
    searches final_radius_px around the previous result (plus the half pixel it had).
    map_feat0: the map window's full-resolution feature image when the caller has it (crops of
    it replace per-tile feature computation on the map side).
    """
    n_lev = len(pyr_m)
    Ho, Wo = ortho.shape
    lev0 = 0
    while lev0 + 1 < n_lev and radius0_px / 2 ** lev0 > 6 and T0 / 2 ** (lev0 + 1) >= 24:
        lev0 += 1
    o_list, m_list, n_list, s_list = [], [], [], []
    origin0 = np.asarray(origin0, float)
    # Whether a level's map window is valid everywhere (a map that covers the whole search
    # window: the usual case): one count over the window instead of one per tile.
    map_all_valid: dict[int, bool] = {}
    for x0, y0 in tiles:
        off = np.array(offset0, float)
        ncc, sharp = -1.0, 0.0
        for lev in range(lev0, -1, -1):
            s = 2**lev
            T = T0 // s
            gm, vm = pyr_m[lev]
            tx, ty = x0 // s, y0 // s
            r = int(math.ceil(radius0_px / s)) + 1 if lev == lev0 else final_radius_px
            mx = int(round(tx + (origin0[0] + off[0]) / s)) - r
            my = int(round(ty + (origin0[1] + off[1]) / s)) - r
            if lev not in map_all_valid:
                map_all_valid[lev] = cv2.countNonZero(vm.view(np.uint8)) == vm.size
            if mx < 0 or my < 0 or mx + T + 2 * r > gm.shape[1] or my + T + 2 * r > gm.shape[0] \
                    or (not map_all_valid[lev] and _valid_share(vm[my:my + T + 2 * r, mx:mx + T + 2 * r]) < 0.95):
                ncc = -1.0
                break
            tmpl = feature_of_region(lambda xa, ya, xb, yb, _l=lev: ortho.crop(_l, xa, ya, xb, yb),
                                     Wo >> lev, Ho >> lev, tx, ty, T, T, kind)
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


#: Fewest agreeing tiles for each model of the consensus (fewer: a translation).
MIN_TILES_AFFINE = 6
MIN_TILES_HOMOGRAPHY = 10


@dataclass(frozen=True)
class Consensus:
    """inliers (N,) bool; H (3, 3) the fitted map ortho px -> map px in homogeneous
    coordinates (H[2, 2] = 1; None for a translation), kind: "homography", "affine" (H's last
    row [0, 0, 1]) or "translation"; var_px2: variance of one correspondence (per axis) from
    the residuals; support: NCC-weighted share of the tiles that agree."""

    inliers: np.ndarray
    H: np.ndarray | None
    kind: str
    var_px2: float
    support: float


def _fit_affine(o, m, w):
    """Weighted least-squares affine as a (3, 3) homogeneous map with m ~ A [o, 1].

    Normal equations about the weighted centroids (a 2 x 2 solve; an SVD least squares cost
    ~60 us, and a frame fits a dozen); a degenerate layout (the tiles on one line) falls back to
    the minimum-norm least squares."""
    ws = w / w.sum()
    o_bar, m_bar = ws @ o, ws @ m
    oc = o - o_bar
    ocw = oc * w[:, None]
    M = ocw.T @ oc  # (2, 2) weighted scatter of the tile positions
    # Collinear tiles: exactly singular when they share a row, merely ill-conditioned (rounding)
    # on a diagonal, where a solve would return a huge A instead of failing.
    if not M[0, 0] * M[1, 1] - M[0, 1] ** 2 > 1e-9 * (M[0, 0] + M[1, 1]) ** 2:
        X = np.c_[o, np.ones(len(o))] * np.sqrt(w)[:, None]
        sol, *_ = np.linalg.lstsq(X, m * np.sqrt(w)[:, None], rcond=None)
        return np.vstack([sol.T, [0.0, 0.0, 1.0]])
    A = np.linalg.solve(M, ocw.T @ (m - m_bar)).T  # (2, 2): m - m_bar ~ A (o - o_bar)
    return np.array([[A[0, 0], A[0, 1], m_bar[0] - A[0] @ o_bar],
                     [A[1, 0], A[1, 1], m_bar[1] - A[1] @ o_bar], [0.0, 0.0, 1.0]])


def _similarity_normaliser(p):
    """(3, 3) T moving points p (N, 2) to zero mean and mean distance sqrt(2) (Hartley)."""
    c = p.mean(axis=0)
    d = float(np.mean(np.hypot(*(p - c).T)))
    k = math.sqrt(2.0) / d if d > 0 else 1.0
    return np.array([[k, 0.0, -k * c[0]], [0.0, k, -k * c[1]], [0.0, 0.0, 1.0]])


def _fit_homography(o, m, w):
    """Weighted normalised DLT homography (3, 3), H[2, 2] = 1, with m ~ H [o, 1] (Hartley and
    Zisserman 2004, alg. 4.2); None when degenerate. Written here rather than
    cv2.findHomography because the IRLS needs per-tile weights, which OpenCV does not take."""
    To, Tm = _similarity_normaliser(o), _similarity_normaliser(m)
    on = o @ To[:2, :2].T + To[:2, 2]
    mn = m @ Tm[:2, :2].T + Tm[:2, 2]
    x, y, u, v = on[:, 0], on[:, 1], mn[:, 0], mn[:, 1]
    # Two DLT rows per tile, each scaled by sqrt(w), filled column by column: this fit runs a
    # dozen times per frame (IRLS, inlier rounds), and np.c_ of nine columns cost more than the SVD.
    sw = np.sqrt(w)
    rows = np.zeros((2 * len(o), 9))
    ev, od = rows[0::2], rows[1::2]
    ev[:, 0], ev[:, 1], ev[:, 2] = -x * sw, -y * sw, -sw
    od[:, 3], od[:, 4], od[:, 5] = -x * sw, -y * sw, -sw
    ev[:, 6], ev[:, 7], ev[:, 8] = u * x * sw, u * y * sw, u * sw
    od[:, 6], od[:, 7], od[:, 8] = v * x * sw, v * y * sw, v * sw
    _, _, vt = np.linalg.svd(rows, full_matrices=False)  # (2n, 9): the 2n x 2n U is not needed
    H = np.linalg.solve(Tm, vt[-1].reshape(3, 3) @ To)
    return H / H[2, 2] if abs(H[2, 2]) > 1e-12 else None


def _apply(H, p):
    """Points p (N, 2) through the homogeneous map H (3, 3)."""
    q = p @ H[:2, :2].T + H[:2, 2]
    z = p @ H[2, :2] + H[2, 2]
    return q / z[:, None]


def tile_consensus(t: TileMatches, consensus_px: float = 3.0, inlier_px: float = 1.5,
                   min_var_px2: float = 0.02, projective: bool = False) -> Consensus | None:
    """Robust agreement of the tiles (module docstring); None when no two tiles agree.
    projective: fit a homography (ten tiles or more) instead of an affine."""
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
        """(H or None, kind, predicted map px of every tile) from the tiles in inl."""
        k = int(inl.sum())
        if k >= MIN_TILES_AFFINE:
            o, m, ww = t.ortho_px[inl], t.map_px[inl], w[inl]
            fit, kind = ((_fit_homography, "homography") if projective and k >= MIN_TILES_HOMOGRAPHY
                         else (_fit_affine, "affine"))
            H = fit(o, m, ww)
            for _ in range(3):  # Cauchy IRLS: a stray tile does not bend the fit
                if H is None:
                    break
                r = np.hypot(*(m - _apply(H, o)).T)
                H_next = fit(o, m, ww / (1.0 + (r / inlier_px) ** 2))
                if H_next is None:  # keep the last good fit
                    break
                H = H_next
            if H is None:  # degenerate layout: the affine (always defined) instead
                H, kind = _fit_affine(o, m, ww), "affine"
            return H, kind, _apply(H, t.ortho_px)
        return None, "translation", t.ortho_px + np.average(d[inl], axis=0, weights=w[inl])

    # Up to three rounds of inliers <- tiles near the model of the inliers; the model is fitted
    # again only when the inliers changed (it is a function of them alone: a round that keeps
    # them would refit the same four weighted fits for the same result).
    H, kind, pred = model(inl)
    for _ in range(3):
        new = np.hypot(*(t.map_px - pred).T) < (inlier_px if H is not None else consensus_px)
        if new.sum() < 2 or (new == inl).all():
            break
        inl = new
        H, kind, pred = model(inl)
    k = int(inl.sum())
    resid = (t.map_px - pred)[inl]
    dof = 2 * k - {"homography": 8, "affine": 6, "translation": 2}[kind]
    var = float((resid**2).sum()) / dof if dof > 0 else 0.5
    return Consensus(inl, H, kind, max(var, min_var_px2), float(w[inl].sum() / w.sum()))
