"""Area-based scene matchers: normalised cross-correlation ("ncc") and phase correlation
("phase") on appearance-robust images, coarse to fine.

1. Global placement at a coarse pyramid level: the whole ortho frame (masked template) against
   the map window, restricted to the search radius; sub-pixel peak by quadratic fits; peak
   quality from the peak-to-second-peak ratio (second peak outside an exclusion radius).
2. Local refinement (tiles.py): a grid of tiles, the most textured valid ones, each searched
   on its own at full resolution within the global placement's uncertainty (sub-pixel peak).
   Independent tiles that agree tell a true placement from a false peak: an NCC-weighted
   translation vote picks the supporters, an affine IRLS fit (the smooth distortion an
   attitude error leaves in the ortho view; or a homography, its exact plane-to-plane form:
   Params.consensus_model) keeps the inliers, and its residuals give the per-correspondence
   variance. The inliers are the correspondences for the pose solve.
   Without agreeing tiles the coarse placement alone is returned with a quality below the
   usual floor (no fix by default).
Quality = NCC-weighted share of agreeing tiles x min(1, inliers / 8).
"""

from __future__ import annotations

import math
from typing import Literal

import cv2
import numpy as np

from testbench.core.interfaces import SceneMatcher
from testbench.core.registry import ParamsModel, register
from testbench.navigation.ismn.features import robust_image
from testbench.navigation.ismn.tiles import feature_crop, refine_tiles, subpixel_peak, tile_consensus, tile_grid
from testbench.navigation.ismn.types import MatchPrior, MatchResult, OrthoFrame

__all__ = ["NccMatcher", "PhaseMatcher", "feature_crop", "subpixel_peak"]


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


class Pyramid:
    """Levels 0..levels of a grey image and its valid mask, level l reduced 2^l times.

    Levels are made on demand, each from the level above it by an exact-factor-2 INTER_AREA
    resize of its largest even crop (the 2 x 2 mean: a level costs a quarter of the one before,
    so a coarse level does not cost a pass over the full-resolution image); a reduced pixel is
    valid only when every pixel it covers is. pyr[l] -> (grey uint8, valid). valid None: an
    image without a mask (every level's valid is None, and no mask is reduced).

    source: optional callable level -> (grey, valid) or None that may serve a level already
    made elsewhere (a crop of a cached map's pyramid, MapWindowCache.pyramid_level): it must be
    what this class would make.
    """

    def __init__(self, img: np.ndarray, valid: np.ndarray | None, levels: int, source=None):
        self._levels: dict[int, tuple[np.ndarray, np.ndarray]] = {0: (img, valid)}
        self._v255: dict[int, np.ndarray] = {}
        self._source = source
        self.n = levels + 1

    def __len__(self) -> int:
        return self.n

    def _valid255(self, lev: int) -> np.ndarray:
        """Level lev's valid mask as uint8 0/255 (the form INTER_AREA averages)."""
        v = self._v255.get(lev)
        if v is None:
            v = self._v255[lev] = cv2.compare(self._levels[lev][1].view(np.uint8), 0, cv2.CMP_GT)  # 0/255
        return v

    def __getitem__(self, lev: int) -> tuple[np.ndarray, np.ndarray]:
        if lev < 0 or lev >= self.n:
            raise IndexError(lev)
        out = self._levels.get(lev)
        if out is None and self._source is not None:
            out = self._source(lev)
            if out is not None:
                self._levels[lev] = out
        if out is None:
            img, valid = self[lev - 1]
            h, w = (img.shape[0] // 2) * 2, (img.shape[1] // 2) * 2
            g = cv2.resize(img[:h, :w], (w // 2, h // 2), interpolation=cv2.INTER_AREA)
            if valid is None:
                out = self._levels[lev] = (g, None)
                return out
            v255 = self._valid255(lev - 1)
            v8 = cv2.resize(v255[:h, :w], (w // 2, h // 2), interpolation=cv2.INTER_AREA)
            self._v255[lev] = cv2.compare(v8, 255, cv2.CMP_EQ)  # 255 where all four were valid
            out = self._levels[lev] = (g, v8 == 255)
        return out


def pyramid(img: np.ndarray, valid: np.ndarray, levels: int, source=None) -> Pyramid:
    """Pyramid(img, valid, levels, source) (see Pyramid); valid as bool (a view: no copy of a
    cropped mask, which OpenCV reads row by row)."""
    return Pyramid(img, np.asarray(valid, dtype=bool), levels, source)


class AreaMatcherBase(SceneMatcher):
    """Shared coarse-to-fine machinery; subclasses implement `_global`."""

    class Params(ParamsModel):
        feature: str = "gradmag"  # appearance-robust image: gradmag | clahe
        coarse_size_px: int = 256  # the coarse level's larger side is at most this
        # Candidate tile grid, and the most textured valid candidates that are refined. A fix
        # depends on which tiles it averages: moving the prior by a tenth of a pixel can move
        # the tile grid on the ground by a pixel and the fix by 0.3-0.4 m (paper_ismn_800m
        # frames, 24 tiles of 96 px: the fix's SD over one pixel of prior shift 0.17-0.20 m, as
        # much as half its error variance). More, smaller tiles average that down: 48 of 64 px
        # against 24 of 96 px, 600 s runs: ISMN smooth mean 0.55 -> 0.46 m (paper), 0.28 ->
        # 0.18 m (lowalt), and 1.76 -> 1.52 m against 30 of 96 px (naip), for a latency p95 of
        # 39-41 ms instead of 29-34 ms on one core; 72 of 64 px gained another 10 % for 50 %
        # more latency.
        tiles_x: int = 12
        tiles_y: int = 7
        max_tiles: int = 48
        tile_px: int = 64  # tile side at full resolution (smaller when the frame is small)
        min_tile_ncc: float = 0.15
        tile_radius_coarse: float = 0.6  # tiles search this many coarse-level px (+1 full-res px) around the global placement
        consensus_px: float = 3.0  # tiles within this of a tile's offset support it
        inlier_px: float = 1.5  # final inliers: within this of the affine (or homography) fit of the supporters
        min_inliers: int = 4
        consensus_model: Literal["affine", "homography"] = "affine"
        """The map ortho -> map the tiles must agree with (tiles.py). homography follows the
        1 / cos^2 pattern an attitude error of the prior leaves in a wide view, which the
        affine's inlier gate cuts off: the fix leans far less on the prior tilt, and the filter
        it feeds errs less (paper_ismn_800m, which uses it with its filter's fix error model
        recalibrated: navigation mean 0.42 -> 0.37 m over 600 s). The default stays affine for
        the scenarios whose filters were calibrated with it (naip_ismn_800m: 1.51 / 1.71 m
        smooth / turning with the affine, 1.56 / 1.82 m with the homography); the figures are
        in docs/measurements.md (the tilt lean and the homography consensus)."""

    def __init__(self, params=None, *, ctx=None):
        self.p = params if params is not None else self.Params()

    #: match() also takes an OrthoFrame, whose pixels it asks for by region and level.
    accepts_ortho_frame = True

    def match(self, ortho_frame: np.ndarray | OrthoFrame, map_window: np.ndarray, prior: MatchPrior) -> MatchResult | None:
        """ortho_frame: (H, W) grey image (its mask prior.ortho_valid), or an OrthoFrame (its own
        mask): then only the coarse level and the tiles' regions are warped."""
        p = self.p
        m_valid = prior.map_valid if prior.map_valid is not None else np.ones(map_window.shape[:2], bool)
        if isinstance(ortho_frame, OrthoFrame):
            of = ortho_frame
        else:
            o_valid = prior.ortho_valid if prior.ortho_valid is not None else np.ones(ortho_frame.shape, bool)
            of = OrthoFrame.from_image(as_u8(ortho_frame), o_valid)
        Ho, Wo = of.shape
        L = max(0, math.ceil(math.log2(max(Ho, Wo) / p.coarse_size_px)))
        coarse = of.coarse(L)
        # Fewer than 64 valid pixels (each valid coarse pixel holds 4^L): nothing to match.
        if cv2.countNonZero(coarse[1].view(np.uint8)) * 4**L < 64:
            return None
        pyr_m = pyramid(as_u8(map_window), m_valid, L, prior.map_pyramid if callable(prior.map_pyramid) else None)
        s = 2.0**L
        origin = np.asarray(prior.origin_px, float)
        coarse_o = robust_image(*coarse, p.feature)
        f_m = prior.map_features(p.feature, L) if callable(prior.map_features) else None
        coarse_m = robust_image(*pyr_m[L], p.feature) if f_m is None else (f_m, pyr_m[L][1])
        g_res = self._global(coarse_o, coarse_m, origin / s, prior.search_radius_px / s + 1.0)
        if g_res is None:
            return None
        off_L, peak, second = g_res
        q_global = distinctiveness(peak, second)
        offset = off_L * s
        # A heading error rotates the ortho view against the map, moving a tile r px from the
        # frame's centre by psi r against the global placement. Up to the translation vote's
        # own tolerance (consensus_px) that needs nothing; beyond it, tiles search one sigma of
        # that displacement (at the frame's corner) farther and may disagree by as much before
        # the affine fit (which models the rotation) picks the inliers. Without it, a start with
        # a 1 deg heading uncertainty gave fixes 4-8 m off at quality 0.2-0.5 from the few
        # central tiles that agreed. (Widening in steady flight too, at a heading sigma of
        # ~1 mrad, made every tile search two pyramid levels: latency p95 36 -> 46 ms.)
        rot_px = prior.heading_sigma_rad * 0.5 * math.hypot(Ho, Wo)
        rot_px = rot_px if rot_px > p.consensus_px else 0.0
        T0, cand = tile_grid(of, coarse_o[0], int(s), p.tile_px, p.tiles_x, p.tiles_y, p.max_tiles)
        fm0 = prior.map_features(p.feature, 0) if callable(prior.map_features) else None
        tm = refine_tiles(of, pyr_m, origin, offset, p.tile_radius_coarse * s + 1.0 + rot_px, cand, T0,
                          p.feature, p.min_tile_ncc, map_feat0=fm0)
        con = tile_consensus(tm, p.consensus_px + rot_px, p.inlier_px, projective=p.consensus_model == "homography")
        if con is None or con.inliers.sum() < p.min_inliers:
            # No agreeing tiles: the coarse placement alone, with its coarse uncertainty and a
            # quality under the usual floor (a lone global peak is not trusted by default).
            cov = np.eye(2) * (0.5 * s) ** 2
            return MatchResult(offset, None, None, float(0.1 * q_global), cov, float(peak), self.registered_name)
        inl = con.inliers
        o_px, m_px = tm.ortho_px[inl], tm.map_px[inl]
        offset = np.median(m_px - o_px - origin, axis=0)
        n_in = int(inl.sum())
        # Tiles that agree (the NCC-weighted share), and enough of them.
        quality = con.support * min(1.0, n_in / 8.0)
        return MatchResult(offset, o_px, m_px, float(np.clip(quality, 0, 1)), np.eye(2) * con.var_px2, float(peak),
                           self.registered_name)

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
