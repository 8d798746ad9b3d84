"""Classical detectors of other vehicles: the LED/blob detector and the truth oracle.

Both register as kind "detector" and implement core.interfaces.Detector (`detect(image)`),
plus `detect_region(image, origin_uv, truths)` that `regions.detect_regions` calls to get
full-frame coordinates (the oracle needs the frame's truth annotations there).
"""

from __future__ import annotations

from typing import Any, Literal, Sequence

import cv2
import numpy as np
import pydantic

from testbench.core.interfaces import BuildContext, Detector
from testbench.core.registry import ParamsModel, register
from testbench.navigation.relative.types import Detection


@register("detector", "led")
class LedDetector(Detector):
    """Bright, saturated LED blobs grouped into vehicles.

    1. LED mask: HSV value >= v_min and saturation >= s_min (and hue within hue_ranges_deg
       when given): lit LEDs are drawn near-white cores in a saturated glow, brighter than sky
       (value <= ~200 at gain 1) and most ground.
    2. 8-connected components of the mask, kept if area <= max_blob_area_px and brighter by
       min_contrast (value) than the median of a ring around them (bright haze and sky are
       smooth: no contrast).
    3. Blobs closer than group_px join one vehicle (union-find on centroids). With
       anchor_hue_deg (the always-on anchor LED's hue), a group holding blobs of several
       anchors is several vehicles: each of its blobs goes to the nearest anchor blob. Why:
       group_px must span one vehicle's LEDs at the shortest range (about 13 px at 20 m), but
       on the arrowhead's lines of sight two vehicles 100 m apart stand 5-15 px from each other
       at 100-200 m, and one detection centred between them pulled the bearing (a fifth of the
       all-LEDs-lit detections at 100 m sat more than 2 px off laterally, 78 % of those next to
       another vehicle). Off in the shipped scenarios: it sharpens the detections (paper swarm,
       10 s: lateral sd at 100 m 0.64 -> 0.30 px with the anchor alone lit, 1.28 -> 0.82 px with
       all five, beyond 2 px 13 % -> 7 %), but the tracks then split and merge as the two
       anchors' blobs part and join from frame to frame, and the whole run is worse (300 s:
       relnav mean 0.186 -> 0.193 m, max 6.8 -> 11.0 m, track-frame IDs 0.991 -> 0.976,
       formation RMS 2.6 -> 2.9 m, 2026-11-25). With anchor_split "parts" the group stays one
       detection (one track, one blink level) and reports each anchor's share of its blobs as
       a part (Detection.parts_px, its LED centroid): the relative-navigation aid takes the
       bearing of the part its estimate of the track's neighbour predicts. Off in the shipped
       scenarios too: paper swarm, 300 s (2026-11-26), relnav mean 0.178 -> 0.178 m, max 5.5
       -> 4.5 m, rows above 1 m 175 -> 242, formation RMS 2.26 -> 2.34 m; the rows under the
       right ID err as before (0.143 -> 0.139 m at 30-120 s, 0.137 -> 0.140 m at 120-200 s):
       the detections that feed them are seldom merged ones (3 % of the bearings took a part).
       Seed 2: mean 0.190 -> 0.197 m, max 4.8 -> 5.9 m, rows above 1 m 202 -> 276, formation
       RMS 2.17 -> 2.26 m.
    4. Per group: brightness-weighted LED centroid (the vehicle's centre), led_level = sum of
       value/255 over the group's LED pixels (rises with the number of lit LEDs: the blink
       decoder thresholds it) or, with data_hue_deg (anchor LED of another colour than the
       data LEDs, the recommended layout), 0.05 + the sum over the pixels of the data LEDs' hue
       only, which stays clear of zero/non-zero even when LEDs overlap at long range; box = LED bbox grown into the dark body pixels around it
       (grey < body_grey_max connected to the LEDs within body_search_px), else LED bbox
       + box_pad_px.
    """

    centre_reference = "led_centroid"
    box_shows_extent = False

    class Params(ParamsModel):
        v_min: int = pydantic.Field(225, ge=0, le=255)
        s_min: int = pydantic.Field(90, ge=0, le=255)
        min_contrast: int = pydantic.Field(15, ge=0, le=255)
        hue_ranges_deg: list[tuple[float, float]] = []
        max_blob_area_px: int = pydantic.Field(400, gt=0)
        group_px: float = pydantic.Field(15.0, gt=0)
        body_grey_max: int = pydantic.Field(100, ge=0, le=255)
        body_search_px: int = pydantic.Field(12, ge=0)
        box_pad_px: float = pydantic.Field(2.0, ge=0)
        data_hue_deg: float | None = None
        data_hue_tol_deg: float = pydantic.Field(25.0, gt=0, le=90)
        anchor_hue_deg: float | None = None
        anchor_hue_tol_deg: float = pydantic.Field(25.0, gt=0, le=90)
        anchor_split: Literal["detections", "parts"] = "detections"

    def __init__(self, params: "LedDetector.Params | None" = None, *, ctx: BuildContext | None = None, **_: Any):
        self.params = params or self.Params()

    def _mask(self, hsv: np.ndarray) -> np.ndarray:
        """LED pixels (H, W) uint8, 255 where lit (cv2.inRange: 2x a numpy comparison)."""
        p = self.params
        m = cv2.inRange(hsv, (0, p.s_min, p.v_min), (255, 255, 255))
        if p.hue_ranges_deg:
            h = hsv[..., 0].astype(np.float32) * 2.0  # OpenCV hue is degrees / 2
            hm = np.zeros(m.shape, bool)
            for lo, hi in p.hue_ranges_deg:
                hm |= ((h >= lo) & (h <= hi)) if lo <= hi else ((h >= lo) | (h <= hi))
            m[~hm] = 0
        return m

    def detect(self, image: np.ndarray) -> list[Detection]:
        """Detections in `image` (H, W, 3) uint8 RGB, pixel coordinates of that image."""
        p = self.params
        hsv = cv2.cvtColor(image, cv2.COLOR_RGB2HSV)
        mask = self._mask(hsv)
        # Components of the lit pixels' bounding box only (the same components; their order is
        # fixed below): a full frame's lit pixels are a few LEDs, and labelling all its 2 Mpx
        # cost 8 ms of the detector's 18.
        bx, by, bw, bh = cv2.boundingRect(mask)
        if bw == 0 or bh == 0:
            return []
        n, labels, stats, cents = cv2.connectedComponentsWithStats(mask[by:by + bh, bx:bx + bw], connectivity=8)
        stats[:, cv2.CC_STAT_LEFT] += bx
        stats[:, cv2.CC_STAT_TOP] += by
        cents += (bx, by)
        keep = [i for i in range(1, n) if stats[i, cv2.CC_STAT_AREA] <= p.max_blob_area_px
                and self._contrast_ok(hsv[..., 2], stats[i])]
        if not keep:
            return []
        # A canonical order (top row, then left column): OpenCV's label numbering depends on
        # its algorithm and thread count, and the detections' order reaches the record.
        keep.sort(key=lambda i: (stats[i, cv2.CC_STAT_TOP], stats[i, cv2.CC_STAT_LEFT]))
        groups = _group(cents[keep], p.group_px)
        split_groups = p.anchor_hue_deg is not None and p.anchor_split == "detections"
        if split_groups:
            groups = [sub for g in groups for sub in self._split_by_anchor(g, keep, labels, stats, cents, hsv, (bx, by))]
        grey = None
        out = []
        for members in groups:
            comp = [keep[i] for i in members]
            (x0, y0, x1, y1), (cu, cv_), level, n_px, data_c = self._weighted_leds(comp, labels, stats, hsv, (bx, by))
            parts = np.zeros((0, 2))
            if p.anchor_hue_deg is not None and not split_groups:
                subs = self._split_by_anchor(members, keep, labels, stats, cents, hsv, (bx, by))
                if len(subs) > 1:
                    parts = np.array([self._weighted_leds([keep[i] for i in g], labels, stats, hsv, (bx, by))[1]
                                      for g in subs], float)
            if grey is None:
                grey = cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
            box = self._body_box(grey, mask, (x0, y0, x1, y1))
            leds = np.array([cents[c] for c in comp], float).reshape(-1, 2)
            score = float(1.0 - np.exp(-float(n_px) / 3.0))
            out.append(Detection(box, (cu, cv_), score, "vehicle", leds, None, level, parts, data_c))
        return out

    def _weighted_leds(self, comp: list[int], labels: np.ndarray, stats: np.ndarray, hsv: np.ndarray,
                       origin: tuple[int, int]) -> tuple[tuple[int, int, int, int], tuple[float, float], float, int,
                                                         tuple[float, float] | None]:
        """Of the LED components `comp` (labels of the lit bounding box at `origin`): their box
        (x0, y0, x1, y1) px, x1/y1 exclusive; their brightness-weighted centroid (u, v) px; the
        blink level (class docstring, step 4); their pixel count; with data_hue_deg, the
        brightness-weighted centroid (u, v) px of the data LEDs' pixels alone (None without any)."""
        p = self.params
        bx, by = origin
        x0 = min(stats[c, cv2.CC_STAT_LEFT] for c in comp)
        y0 = min(stats[c, cv2.CC_STAT_TOP] for c in comp)
        x1 = max(stats[c, cv2.CC_STAT_LEFT] + stats[c, cv2.CC_STAT_WIDTH] for c in comp)
        y1 = max(stats[c, cv2.CC_STAT_TOP] + stats[c, cv2.CC_STAT_HEIGHT] for c in comp)
        gm = np.isin(labels[y0 - by:y1 - by, x0 - bx:x1 - bx], comp)
        w = hsv[y0:y1, x0:x1, 2].astype(np.float64) / 255.0 * gm
        tot = float(w.sum())
        level = tot
        vv, uu = np.mgrid[y0:y1, x0:x1]
        data_c = None
        if p.data_hue_deg is not None:
            wd = w * (_hue_distance_deg(hsv[y0:y1, x0:x1, 0], p.data_hue_deg) <= p.data_hue_tol_deg)
            tot_d = float(wd.sum())
            level = 0.05 + tot_d
            if tot_d > 0.0:
                data_c = (float((wd * uu).sum() / tot_d), float((wd * vv).sum() / tot_d))
        return (x0, y0, x1, y1), (float((w * uu).sum() / tot), float((w * vv).sum() / tot)), level, int(gm.sum()), data_c

    def _split_by_anchor(self, members: list[int], keep: list[int], labels: np.ndarray, stats: np.ndarray,
                         cents: np.ndarray, hsv: np.ndarray, origin: tuple[int, int]) -> list[list[int]]:
        """One group (indices into keep) split into one group per anchor blob it holds (a blob
        with at least one pixel of the anchor's hue), each blob joining the nearest anchor;
        unchanged when it holds fewer than two."""
        if len(members) < 2:
            return [members]
        p = self.params
        bx, by = origin
        anchors = []
        for i in members:
            c = keep[i]
            x, y, w, h = (int(stats[c, k]) for k in (cv2.CC_STAT_LEFT, cv2.CC_STAT_TOP, cv2.CC_STAT_WIDTH, cv2.CC_STAT_HEIGHT))
            own = labels[y - by:y - by + h, x - bx:x - bx + w] == c
            if np.any(own & (_hue_distance_deg(hsv[y:y + h, x:x + w, 0], p.anchor_hue_deg) <= p.anchor_hue_tol_deg)):
                anchors.append(i)
        if len(anchors) < 2:
            return [members]
        a_xy = cents[[keep[i] for i in anchors]]
        out: dict[int, list[int]] = {}
        for i in members:
            k = int(np.argmin(np.linalg.norm(a_xy - cents[keep[i]], axis=1)))
            out.setdefault(k, []).append(i)
        return [out[k] for k in sorted(out)]

    def _contrast_ok(self, value: np.ndarray, st) -> bool:
        x, y, w, h = (int(st[k]) for k in (cv2.CC_STAT_LEFT, cv2.CC_STAT_TOP, cv2.CC_STAT_WIDTH, cv2.CC_STAT_HEIGHT))
        H, W = value.shape
        x0, y0, x1, y1 = max(x - 3, 0), max(y - 3, 0), min(x + w + 3, W), min(y + h + 3, H)
        win = value[y0:y1, x0:x1]
        ring = np.ones(win.shape, bool)
        ring[y - y0: y - y0 + h, x - x0: x - x0 + w] = False
        if not ring.any():
            return True
        return int(value[y:y + h, x:x + w].max()) - float(np.median(win[ring])) >= self.params.min_contrast

    def _body_box(self, grey: np.ndarray, mask: np.ndarray, led_box) -> tuple[float, float, float, float]:
        p = self.params
        x0, y0, x1, y1 = led_box
        H, W = grey.shape
        s = p.body_search_px
        wx0, wy0, wx1, wy1 = max(x0 - s, 0), max(y0 - s, 0), min(x1 + s, W), min(y1 + s, H)
        fallback = (x0 - 0.5 - p.box_pad_px, y0 - 0.5 - p.box_pad_px, x1 - 0.5 + p.box_pad_px, y1 - 0.5 + p.box_pad_px)
        if s == 0:
            return fallback
        win = ((grey[wy0:wy1, wx0:wx1] <= p.body_grey_max) | (mask[wy0:wy1, wx0:wx1] > 0)).astype(np.uint8)
        # Bridge the glow-to-body seam (anti-aliased edges are mid-grey).
        win = cv2.dilate(win, np.ones((3, 3), np.uint8))
        n, lab = cv2.connectedComponents(win, connectivity=8)
        seeds = np.unique(lab[y0 - wy0: y1 - wy0, x0 - wx0: x1 - wx0][mask[y0:y1, x0:x1] > 0])
        seeds = seeds[seeds > 0]
        if len(seeds) == 0:
            return fallback
        ys, xs = np.nonzero(np.isin(lab, seeds))
        bu0, bv0, bu1, bv1 = xs.min() + wx0 + 1, ys.min() + wy0 + 1, xs.max() + wx0, ys.max() + wy0  # undo dilation
        touches = bu0 <= wx0 + 1 or bv0 <= wy0 + 1 or bu1 >= wx1 - 2 or bv1 >= wy1 - 2
        if touches and (wx1 - wx0) * (wy1 - wy0) > 4 * (x1 - x0) * (y1 - y0):
            return fallback  # dark ground around the vehicle: the body cannot be separated
        return (min(bu0, x0) - 0.5, min(bv0, y0) - 0.5, max(bu1 + 1, x1) - 0.5, max(bv1 + 1, y1) - 0.5)

    def detect_region(self, image: np.ndarray, origin_uv=(0, 0), truths: Sequence[Any] = ()) -> list[Detection]:
        return [d.shifted(origin_uv[0], origin_uv[1]) for d in self.detect(image)]


def _hue_distance_deg(hue_cv: np.ndarray, hue_deg: float) -> np.ndarray:
    """|hue - hue_deg| around the colour circle (deg, 0-180) of OpenCV hues (degrees / 2)."""
    return np.abs((hue_cv.astype(np.float64) * 2.0 - hue_deg + 180.0) % 360.0 - 180.0)


def _group(points: np.ndarray, radius: float) -> list[list[int]]:
    """Connected groups of points closer than `radius` (union-find), as index lists."""
    n = len(points)
    parent = list(range(n))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    d = np.linalg.norm(points[:, None, :] - points[None, :, :], axis=2)
    for i, j in zip(*np.nonzero(np.triu(d < radius, 1))):
        parent[find(i)] = find(j)
    groups: dict[int, list[int]] = {}
    for i in range(n):
        groups.setdefault(find(i), []).append(i)
    return list(groups.values())


@register("detector", "oracle")
class OracleDetector(Detector):
    """Detections from the frame's truth annotations (VehicleTruth), degraded on purpose.

    Each visible vehicle within max_range_m is missed with miss_probability; otherwise its
    centre (and box) moves by N(0, sigma_px^2) per axis and its box size by a factor
    N(1, size_sigma^2). LED states: the lit in-frame LEDs of the truth, each flipped with
    led_flip_probability; led_level = their count. False alarms: Poisson with mean
    false_alarms_per_mpx per megapixel of the searched image, uniformly placed, with a random
    LED level. Randomness from the injected generator only.
    """

    class Params(ParamsModel):
        sigma_px: float = pydantic.Field(0.5, ge=0)
        size_sigma: float = pydantic.Field(0.05, ge=0)
        miss_probability: float = pydantic.Field(0.0, ge=0, le=1)
        false_alarms_per_mpx: float = pydantic.Field(0.0, ge=0)
        led_flip_probability: float = pydantic.Field(0.0, ge=0, le=1)
        max_range_m: float = pydantic.Field(1e9, gt=0)

    def __init__(self, params: "OracleDetector.Params | None" = None, *, ctx: BuildContext | None = None,
                 rng: np.random.Generator | None = None, **_: Any):
        self.params = params or self.Params()
        self.rng = rng if rng is not None else np.random.default_rng(0)

    def detect(self, image: np.ndarray) -> list[Detection]:
        """Without truth annotations the oracle sees only its false alarms."""
        return self.detect_region(image, (0, 0), ())

    def detect_region(self, image: np.ndarray, origin_uv=(0, 0), truths: Sequence[Any] = ()) -> list[Detection]:
        p, rng = self.params, self.rng
        H, W = image.shape[:2]
        ou, ov = origin_uv
        out = []
        for t in truths:
            if not t.visible or t.range_m > p.max_range_m:
                continue
            c = np.asarray(t.centre_px, float)
            if not (ou - 0.5 <= c[0] < ou + W - 0.5 and ov - 0.5 <= c[1] < ov + H - 0.5):
                continue  # another region (or another frame) reports it
            if rng.random() < p.miss_probability:
                continue
            n = rng.normal(0.0, p.sigma_px, 2) if p.sigma_px > 0 else np.zeros(2)
            k = max(0.2, 1.0 + rng.normal(0.0, p.size_sigma)) if p.size_sigma > 0 else 1.0
            u0, v0, u1, v1 = t.bbox_px
            bu, bv = 0.5 * (u0 + u1) - c[0], 0.5 * (v0 + v1) - c[1]  # box centre offset from the vehicle centre
            hw, hh = 0.5 * (u1 - u0) * k, 0.5 * (v1 - v0) * k
            cu, cv_ = c + n
            box = (cu + bu - hw, cv_ + bv - hh, cu + bu + hw, cv_ + bv + hh)
            on = [bool(o) for o, inside in zip(t.led_on, t.led_in_frame) if inside]
            if p.led_flip_probability > 0:
                on = [o ^ bool(rng.random() < p.led_flip_probability) for o in on]
            leds = np.asarray(t.led_px, float).reshape(-1, 2)[np.asarray(t.led_in_frame, bool)] if len(t.led_in_frame) else np.zeros((0, 2))
            out.append(Detection(box, (float(cu), float(cv_)), 1.0, "vehicle", leds, tuple(on), float(sum(on))))
        n_fa = rng.poisson(p.false_alarms_per_mpx * W * H / 1e6) if p.false_alarms_per_mpx > 0 else 0
        for _ in range(n_fa):
            cu, cv_ = ou + rng.uniform(0, W) - 0.5, ov + rng.uniform(0, H) - 0.5
            s = rng.uniform(3.0, 15.0)
            out.append(Detection((cu - s / 2, cv_ - s / 2, cu + s / 2, cv_ + s / 2), (cu, cv_), float(rng.uniform(0.3, 1.0)),
                                 "vehicle", np.zeros((0, 2)), None, float(rng.integers(1, 5))))
        return out
