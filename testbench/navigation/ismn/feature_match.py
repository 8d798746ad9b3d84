"""Feature-based scene matchers: ORB and SIFT (SIFT stands in for the paper's SURF, which is
not free in OpenCV), Lowe ratio test, robust homography with cv2.USAC_MAGSAC.

Quality = inlier ratio x min(1, inliers / min_inliers_full); the correspondences are the
inliers; covariance of one correspondence from the inlier residuals about the homography.
Both images are CLAHE-equalised first (the map is another season or year).
"""

from __future__ import annotations

import cv2
import numpy as np

from testbench.core.interfaces import SceneMatcher
from testbench.core.registry import ParamsModel, register
from testbench.navigation.ismn.types import MatchPrior, MatchResult


class FeatureMatcherBase(SceneMatcher):
    class Params(ParamsModel):
        n_features: int = 3000
        ratio: float = 0.8  # Lowe ratio test
        ransac_px: float = 3.0
        min_inliers: int = 8
        min_inliers_full: int = 40  # inlier count giving full quality
        max_prior_distance_factor: float = 1.5  # keep matches within this x search radius

    def __init__(self, params=None, *, ctx=None):
        self.p = params if params is not None else self.Params()
        self._clahe = cv2.createCLAHE(clipLimit=2.0, tileGridSize=(8, 8))

    def _detector(self):
        raise NotImplementedError

    def _norm(self) -> int:
        raise NotImplementedError

    def _prep(self, img, valid):
        u8 = img if img.dtype == np.uint8 else np.clip(img * 255, 0, 255).astype(np.uint8)
        mask = None if valid is None else cv2.erode(valid.astype(np.uint8) * 255, np.ones((7, 7), np.uint8))
        return self._clahe.apply(u8), mask

    def match(self, ortho_frame: np.ndarray, map_window: np.ndarray, prior: MatchPrior) -> MatchResult | None:
        p = self.p
        det = self._detector()
        a, ma = self._prep(ortho_frame, prior.ortho_valid)
        b, mb = self._prep(map_window, prior.map_valid)
        ka, da = det.detectAndCompute(a, ma)
        kb, db = det.detectAndCompute(b, mb)
        if da is None or db is None or len(ka) < p.min_inliers or len(kb) < 2:
            return None
        pairs = cv2.BFMatcher(self._norm()).knnMatch(da, db, k=2)
        good = [m[0] for m in pairs if len(m) == 2 and m[0].distance < p.ratio * m[1].distance]
        if len(good) < p.min_inliers:
            return None
        pa = np.float64([ka[m.queryIdx].pt for m in good])
        pb = np.float64([kb[m.trainIdx].pt for m in good])
        origin = np.asarray(prior.origin_px, float)
        # The prior bounds how far a correspondence may be from its predicted place.
        near = np.hypot(*(pb - pa - origin).T) <= p.max_prior_distance_factor * prior.search_radius_px + 30.0
        pa, pb = pa[near], pb[near]
        if len(pa) < p.min_inliers:
            return None
        H, inl = cv2.findHomography(pa, pb, cv2.USAC_MAGSAC, p.ransac_px)
        if H is None:
            return None
        inl = inl.ravel().astype(bool)
        n_in = int(inl.sum())
        if n_in < p.min_inliers:
            return None
        pa, pb = pa[inl], pb[inl]
        resid = pb - cv2.perspectiveTransform(pa[:, None, :], H)[:, 0, :]
        var = max(float((resid**2).sum()) / (2 * max(1, n_in - 8)), 0.1)
        ratio = n_in / len(good)
        quality = float(np.clip(ratio, 0, 1) * min(1.0, n_in / p.min_inliers_full))
        offset = np.median(pb - pa - origin, axis=0)
        return MatchResult(offset, pa, pb, quality, np.eye(2) * var, float(ratio), self.registered_name)


@register("matcher", "orb")
class OrbMatcher(FeatureMatcherBase):
    """ORB keypoints (cv2.ORB_create), Hamming distance."""

    def _detector(self):
        return cv2.ORB_create(nfeatures=self.p.n_features)

    def _norm(self):
        return cv2.NORM_HAMMING


@register("matcher", "sift")
class SiftMatcher(FeatureMatcherBase):
    """SIFT keypoints (cv2.SIFT_create), L2 distance."""

    def _detector(self):
        return cv2.SIFT_create(nfeatures=self.p.n_features)

    def _norm(self):
        return cv2.NORM_L2
