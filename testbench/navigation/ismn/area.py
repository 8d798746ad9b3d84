"""Area-based scene matchers: normalised cross-correlation ("ncc") and phase correlation
("phase") on appearance-robust images, coarse to fine.

1. Global placement at a coarse pyramid level: the whole ortho frame (masked template) against
   the map window, restricted to the search radius; sub-pixel peak by quadratic fits; peak
   quality from the peak-to-second-peak ratio (second peak outside an exclusion radius).
2. Local refinement: a grid of tiles, each searched a few pixels around its predicted place at
   every finer level down to full resolution. The tiles follow the smooth distortion an attitude
   error leaves in the ortho view, and become correspondences (ortho px <-> map px) for the
   pose solve. A RANSAC homography keeps the tiles that agree.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from testbench.core.interfaces import SceneMatcher
from testbench.core.registry import ParamsModel, register
from testbench.navigation.ismn.features import robust_image
from testbench.navigation.ismn.types import MatchPrior, MatchResult


def subpixel_peak(res: np.ndarray, x: int, y: int) -> tuple[float, float]:
    """Quadratic (parabola) refinement of an integer peak of a score surface, per axis."""
    def fit(l, c, r):
        den = l - 2.0 * c + r
        return 0.0 if den >= 0 else float(np.clip(0.5 * (l - r) / den, -0.5, 0.5))
    dx = fit(res[y, x - 1], res[y, x], res[y, x + 1]) if 0 < x < res.shape[1] - 1 else 0.0
    dy = fit(res[y - 1, x], res[y, x], res[y + 1, x]) if 0 < y < res.shape[0] - 1 else 0.0
    return x + dx, y + dy


def peak_and_second(res: np.ndarray, exclusion_px: int):
    """(x, y, peak, second): integer argmax and the best score outside the exclusion box."""
    _, p, _, (x, y) = cv2.minMaxLoc(res)
    r = res.copy()
    r[max(0, y - exclusion_px): y + exclusion_px + 1, max(0, x - exclusion_px): x + exclusion_px + 1] = -np.inf
    s = float(r.max()) if np.isfinite(r).any() else -1.0
    return x, y, float(p), s


def distinctiveness(peak: float, second: float) -> float:
    """Peak quality in [0, 1]: 0 when the second peak is as high as the first, 1 when it is at
    most half of it (a unique, sharp match)."""
    if not np.isfinite(peak) or peak <= 0:
        return 0.0
    return float(np.clip(2.0 * (1.0 - max(second, 0.0) / peak), 0.0, 1.0))


def as_u8(img: np.ndarray) -> np.ndarray:
    """Grey uint8 view of a float [0, 1] or uint8 image."""
    if img.dtype == np.uint8:
        return img
    return np.clip(img * 255.0 + 0.5, 0, 255).astype(np.uint8)


def pyramid(img: np.ndarray, valid: np.ndarray, levels: int):
    """[(grey uint8, valid bool)] for levels 0..levels, level l reduced 2^l times (INTER_AREA)."""
    out = [(img, valid)]
    g, v8 = img, valid.astype(np.uint8) * 255
    for _ in range(levels):
        # Halve an even-sized crop: OpenCV's exact factor-2 INTER_AREA path is the fast one.
        h, w = (g.shape[0] // 2) * 2, (g.shape[1] // 2) * 2
        g = cv2.resize(g[:h, :w], None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
        v8 = cv2.resize(v8[:h, :w], None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
        v8 = np.where(v8 == 255, np.uint8(255), np.uint8(0))
        out.append((g, v8 == 255))
    return out


def feature_crop(img, valid, x, y, w, h, kind, pad=10):
    """Appearance-robust feature of img[y:y+h, x:x+w], computed with `pad` pixels of context."""
    H, W = img.shape
    xa, ya, xb, yb = max(0, x - pad), max(0, y - pad), min(W, x + w + pad), min(H, y + h + pad)
    f, _ = robust_image(img[ya:yb, xa:xb], valid[ya:yb, xa:xb], kind)
    return f[y - ya:y - ya + h, x - xa:x - xa + w]


class AreaMatcherBase(SceneMatcher):
    """Shared coarse-to-fine machinery; subclasses implement `_global`."""

    class Params(ParamsModel):
        feature: str = "gradmag"  # appearance-robust image: gradmag | clahe
        coarse_size_px: int = 256  # the coarse level's larger side is at most this
        tiles_x: int = 7  # candidate tile grid
        tiles_y: int = 5
        max_tiles: int = 16  # the most textured valid candidates are refined
        tile_px: int = 96  # tile side at full resolution (smaller when the frame is small)
        tile_radius_px: int = 3  # search radius of tiles per level (+2 at the coarsest level)
        min_tile_ncc: float = 0.15
        ransac_px: float = 2.0

    def __init__(self, params=None, *, ctx=None):
        self.p = params if params is not None else self.Params()

    def match(self, ortho_frame: np.ndarray, map_window: np.ndarray, prior: MatchPrior) -> MatchResult | None:
        p = self.p
        o_valid = prior.ortho_valid if prior.ortho_valid is not None else np.ones(ortho_frame.shape, bool)
        m_valid = prior.map_valid if prior.map_valid is not None else np.ones(map_window.shape[:2], bool)
        if o_valid.sum() < 64:
            return None
        Ho, Wo = ortho_frame.shape
        L = max(0, math.ceil(math.log2(max(Ho, Wo) / p.coarse_size_px)))
        pyr_o = pyramid(as_u8(ortho_frame), o_valid, L)
        pyr_m = pyramid(as_u8(map_window), m_valid, L)
        s = 2.0**L
        origin = np.asarray(prior.origin_px, float)
        coarse_o = robust_image(*pyr_o[L], p.feature)
        coarse_m = robust_image(*pyr_m[L], p.feature)
        g_res = self._global(coarse_o, coarse_m, origin / s, prior.search_radius_px / s + 1.0)
        if g_res is None:
            return None
        off_L, peak, second = g_res
        q_global = distinctiveness(peak, second)
        ortho_px, map_px, tile_ncc = self._tiles(pyr_o, pyr_m, coarse_o, coarse_m, origin, off_L * s, L)
        offset = off_L * s
        cov = np.eye(2) * (0.5 * s) ** 2
        n_in, inlier_frac = 0, 0.0
        if len(ortho_px) >= 8:  # tiles agree on one homography (smooth distortion allowed)
            H, inl = cv2.findHomography(ortho_px, map_px, cv2.USAC_MAGSAC, p.ransac_px)
            inl = np.zeros(len(ortho_px), bool) if H is None else inl.ravel().astype(bool)
        elif len(ortho_px) >= 3:  # too few for a homography: agree on the median shift
            d = map_px - ortho_px
            inl = np.hypot(*(d - np.median(d, axis=0)).T) < 2.0 * p.ransac_px
        else:
            inl = np.zeros(len(ortho_px), bool)
        if inl.any():
            n_in, inlier_frac = int(inl.sum()), float(inl.mean())
            ortho_px, map_px = ortho_px[inl], map_px[inl]
            offset = np.median(map_px - ortho_px - origin, axis=0)
            if n_in >= 8:
                pred = cv2.perspectiveTransform(ortho_px[:, None, :], H)[:, 0, :]
                dof = n_in - 8
            else:
                pred = ortho_px + np.median(map_px - ortho_px, axis=0)
                dof = n_in - 1
            resid = map_px - pred
            var = float((resid**2).sum()) / (2 * dof) if dof > 0 else 0.25
            cov = np.eye(2) * max(var, 0.05)
        else:
            ortho_px = map_px = np.zeros((0, 2))
        # A unique global peak, tiles that agree, and enough of them.
        quality = q_global * inlier_frac * min(1.0, n_in / 8.0)
        return MatchResult(offset, ortho_px if len(ortho_px) else None, map_px if len(map_px) else None,
                           float(np.clip(quality, 0, 1)), cov, float(peak), self.registered_name)

    def _tiles(self, pyr_o, pyr_m, coarse_o, coarse_m, origin0, offset0, L):
        """Coarse-to-fine tile search; returns (ortho_px, map_px, ncc) at full resolution.

        Candidate tiles lie on a tiles_x x tiles_y grid; those fully inside the valid ortho area
        are ranked by texture (coarse feature variance) and the best max_tiles are refined.
        Levels visited: L (whole-image coarse features), L-2 when L >= 4, then 0 (features on
        crops around each tile only). The radius at each finer level covers the coarser level's
        half-pixel uncertainty plus tile_radius_px."""
        p = self.p
        v0 = pyr_o[0][1]
        Ho, Wo = v0.shape
        sL = 2**L
        T0 = int(min(p.tile_px, Wo // max(2, p.tiles_x - 1), Ho // max(2, p.tiles_y - 1))) // sL * sL
        empty = np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0)
        if T0 < max(16, 8 * sL):
            return empty
        cands = []
        for j in range(p.tiles_y):
            for i in range(p.tiles_x):
                x0 = int(round(i * (Wo - T0) / max(1, p.tiles_x - 1))) // sL * sL
                y0 = int(round(j * (Ho - T0) / max(1, p.tiles_y - 1))) // sL * sL
                if v0[y0:y0 + T0, x0:x0 + T0].mean() < 0.98:
                    continue
                tex = float(coarse_o[0][y0 // sL:(y0 + T0) // sL, x0 // sL:(x0 + T0) // sL].var())
                cands.append((tex, x0, y0))
        cands.sort(reverse=True)
        levels = [L] + ([L - 2] if L >= 4 else []) + ([0] if L > 0 else [])
        o_list, m_list, n_list = [], [], []
        for _, x0, y0 in cands[: p.max_tiles]:
            off = np.array(offset0, float)  # full-resolution offset of this tile
            ncc, prev = -1.0, None
            for lev in levels:
                s = 2**lev
                T = T0 // s
                go, vo = pyr_o[lev]
                gm, vm = pyr_m[lev]
                tx, ty = x0 // s, y0 // s
                r = p.tile_radius_px + (2 if prev is None else 2 ** (prev - lev) // 2)
                prev = lev
                mx = int(round(tx + (origin0[0] + off[0]) / s)) - r
                my = int(round(ty + (origin0[1] + off[1]) / s)) - r
                if mx < 0 or my < 0 or mx + T + 2 * r > gm.shape[1] or my + T + 2 * r > gm.shape[0] \
                        or vm[my:my + T + 2 * r, mx:mx + T + 2 * r].mean() < 0.95:
                    ncc = -1.0
                    break
                if lev == L:
                    tmpl = coarse_o[0][ty:ty + T, tx:tx + T]
                    region = coarse_m[0][my:my + T + 2 * r, mx:mx + T + 2 * r]
                else:
                    tmpl = feature_crop(go, vo, tx, ty, T, T, p.feature)
                    region = feature_crop(gm, vm, mx, my, T + 2 * r, T + 2 * r, p.feature)
                if float(tmpl.std()) < 1e-4:
                    ncc = -1.0
                    break
                res = cv2.matchTemplate(region, tmpl, cv2.TM_CCOEFF_NORMED)
                _, ncc, _, (px, py) = cv2.minMaxLoc(res)
                sx, sy = subpixel_peak(res, px, py)
                off = np.array([(mx + sx - tx) * s - origin0[0], (my + sy - ty) * s - origin0[1]])
            if ncc < p.min_tile_ncc:
                continue
            c = np.array([x0 + (T0 - 1) / 2.0, y0 + (T0 - 1) / 2.0])
            o_list.append(c)
            m_list.append(c + origin0 + off)
            n_list.append(ncc)
        if not o_list:
            return empty
        return np.array(o_list), np.array(m_list), np.array(n_list)

    def _global(self, f_o, f_m, origin, radius):
        raise NotImplementedError


def _restrict(res: np.ndarray, origin: np.ndarray, radius: float) -> np.ndarray:
    """Scores outside the search box around the predicted placement set to -inf."""
    out = np.full_like(res, -np.inf)
    x0, y0 = int(math.floor(origin[0] - radius)), int(math.floor(origin[1] - radius))
    x1, y1 = int(math.ceil(origin[0] + radius)) + 1, int(math.ceil(origin[1] + radius)) + 1
    x0, y0 = max(0, x0), max(0, y0)
    out[y0:y1, x0:x1] = res[y0:y1, x0:x1]
    return out


@register("matcher", "ncc")
class NccMatcher(AreaMatcherBase):
    """Masked zero-mean normalised cross-correlation (cv2.TM_CCOEFF_NORMED) of gradient images."""

    def _global(self, f_o, f_m, origin, radius):
        fo, vo = f_o
        fm, _ = f_m
        if fo.shape[0] > fm.shape[0] or fo.shape[1] > fm.shape[1]:
            return None
        mask = None if vo.all() else vo.astype(np.float32)
        res = cv2.matchTemplate(fm, fo, cv2.TM_CCOEFF_NORMED, mask=mask)
        res = np.nan_to_num(res, nan=-1.0, posinf=-1.0, neginf=-1.0)
        res = _restrict(res, origin, radius)
        if not np.isfinite(res).any():
            return None
        x, y, peak, second = peak_and_second(res, exclusion_px=3)
        sx, sy = subpixel_peak(np.where(np.isfinite(res), res, -1.0), x, y)
        return np.array([sx, sy]) - origin, peak, second


@register("matcher", "phase")
class PhaseMatcher(AreaMatcherBase):
    """Phase correlation (cv2.phaseCorrelate, Hanning-windowed) of gradient images.

    The ortho frame is pasted into a map-sized canvas at its predicted place; the phase
    correlation peak gives the shift. The second peak is taken from the cross-power spectrum's
    inverse transform (the correlation surface) for the quality figure.
    """

    def _global(self, f_o, f_m, origin, radius):
        fo, vo = f_o
        fm, vm = f_m
        Hm, Wm = fm.shape
        Ho, Wo = fo.shape
        ox, oy = int(round(origin[0])), int(round(origin[1]))
        if ox < 0 or oy < 0 or ox + Wo > Wm or oy + Ho > Hm:
            return None
        canvas = np.zeros_like(fm)
        canvas[oy:oy + Ho, ox:ox + Wo] = np.where(vo, fo - fo[vo].mean(), 0)
        a = np.where(vm, fm - fm[vm].mean(), 0).astype(np.float32)
        win = cv2.createHanningWindow((Wm, Hm), cv2.CV_32F)
        (dx, dy), response = cv2.phaseCorrelate(canvas, a, win)
        # Correlation surface for the second peak (same normalised cross-power spectrum).
        A = np.fft.rfft2(a * win)
        B = np.fft.rfft2(canvas * win)
        R = A * np.conj(B)
        R /= np.abs(R) + 1e-9
        surf = np.fft.fftshift(np.fft.irfft2(R, s=a.shape)).astype(np.float32)
        cy, cx = Hm // 2, Wm // 2
        local = _restrict(surf, np.array([cx, cy], float), radius)
        x, y, peak, second = peak_and_second(local, exclusion_px=3)
        if np.hypot(dx, dy) > radius + 1:
            return None
        return np.array([ox + dx, oy + dy]) - origin, peak, second
