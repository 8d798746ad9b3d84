"""Running any detector on full frames or on regions around predicted tracks.

A region (roi) is (u0, v0, u1, v1) in full-frame pixels, u1/v1 exclusive, as the renderer's
`roi` argument. `detect_regions` crops each region, runs the detector, maps the detections back
to full-frame pixels and drops duplicates found in overlapping regions.
"""

from __future__ import annotations

from typing import Any, Iterable, Sequence

import numpy as np

from testbench.navigation.relative.geometry import project_relative
from testbench.navigation.relative.types import Detection

Roi = tuple[int, int, int, int]


def box_iou(a, b) -> float:
    """Intersection over union of two (u0, v0, u1, v1) boxes."""
    iw = min(a[2], b[2]) - max(a[0], b[0])
    ih = min(a[3], b[3]) - max(a[1], b[1])
    if iw <= 0 or ih <= 0:
        return 0.0
    inter = iw * ih
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return float(inter / union) if union > 0 else 0.0


def roi_around(box, margin_px: float, width_px: int, height_px: int, min_size_px: int = 32) -> Roi | None:
    """Integer region around `box` grown by `margin_px` on each side (and to at least
    min_size_px square), clipped to the frame; None when it misses the frame."""
    u0, v0, u1, v1 = box
    cu, cv = 0.5 * (u0 + u1), 0.5 * (v0 + v1)
    hw = max(0.5 * (u1 - u0) + margin_px, 0.5 * min_size_px)
    hh = max(0.5 * (v1 - v0) + margin_px, 0.5 * min_size_px)
    r = (int(np.floor(cu - hw)), int(np.floor(cv - hh)), int(np.ceil(cu + hw)) + 1, int(np.ceil(cv + hh)) + 1)
    r = (max(r[0], 0), max(r[1], 0), min(r[2], width_px), min(r[3], height_px))
    if r[2] <= r[0] or r[3] <= r[1]:
        return None
    return r


def merge_rois(rois: Iterable[Roi]) -> list[Roi]:
    """Union overlapping regions into their bounding regions until none overlap (fewer,
    larger renders; a detection is never cut by a region edge inside a merged area)."""
    out = [tuple(r) for r in rois]
    changed = True
    while changed:
        changed = False
        for i in range(len(out)):
            for j in range(i + 1, len(out)):
                a, b = out[i], out[j]
                if a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]:
                    out[i] = (min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3]))
                    del out[j]
                    changed = True
                    break
            if changed:
                break
    return sorted(out)


def rois_around_tracks(tracks: Iterable[Any], estimates: Iterable[Any], camera: Any, mount: Any,
                       R_nb: np.ndarray | None, t_s: float, margin_px: float, margin_per_miss_px: float,
                       min_size_px: int) -> list[Roi]:
    """Merged regions of one camera at t_s: around each image track's predicted box (margin
    growing by margin_per_miss_px per missed frame) and, with the own attitude R_nb (3, 3,
    body -> NED; None: unknown, tracks only), around each neighbour estimate projected into
    the camera (NeighbourFilter: relative position x[:3] m NED carried by its velocity x[3:]
    to t_s; half-size 3 sigma of its position at its depth), so that a neighbour known from
    another camera or from before is looked for where it should appear."""
    rois = []
    R_nc = None if R_nb is None else R_nb @ mount.R_bc
    for tr in tracks:
        r = roi_around(tr.box_at(t_s, R_nc, camera.K), margin_px + margin_per_miss_px * tr.misses,
                       camera.width_px, camera.height_px, min_size_px)
        if r is not None:
            rois.append(r)
    if R_nb is not None:
        for f in estimates:
            x = f.x[:3] + (t_s - f.t_s) * f.x[3:]
            uv, z = project_relative(camera, mount, R_nb, x[None, :])
            if z[0] <= 0:
                continue
            half = 3.0 * np.sqrt(max(np.trace(f.P[:3, :3]), 1.0)) * camera.fx / max(z[0], 1.0)
            r = roi_around((uv[0, 0], uv[0, 1], uv[0, 0], uv[0, 1]), margin_px + half, camera.width_px,
                           camera.height_px, min_size_px)
            if r is not None:
                rois.append(r)
    return merge_rois(rois)


def crop(image: np.ndarray, roi: Roi, origin_uv: tuple[int, int] = (0, 0)) -> np.ndarray:
    """The part of `image` (whose top-left pixel is full-frame origin_uv) inside `roi`."""
    ou, ov = origin_uv
    return image[max(roi[1] - ov, 0): max(roi[3] - ov, 0), max(roi[0] - ou, 0): max(roi[2] - ou, 0)]


def dedupe(dets: Sequence[Detection], iou_min: float = 0.3, centre_px: float = 2.0) -> list[Detection]:
    """Greedy non-maximum suppression: keep the best-scoring of detections whose boxes overlap
    by >= iou_min or whose centres lie within centre_px."""
    kept: list[Detection] = []
    for d in sorted(dets, key=lambda d: -d.score):
        if all(box_iou(d.bbox_px, k.bbox_px) < iou_min
               and np.hypot(d.centre_px[0] - k.centre_px[0], d.centre_px[1] - k.centre_px[1]) > centre_px for k in kept):
            kept.append(d)
    return kept


def detect_regions(detector: Any, image: np.ndarray, rois: Sequence[Roi] | None, origin_uv=(0, 0),
                   truths: Sequence[Any] = ()) -> list[Detection]:
    """Run `detector` on `image` (top-left at full-frame origin_uv) or on the regions `rois`
    of it; detections in full-frame pixels, duplicates removed.

    Detectors with `detect_region(image, origin_uv, truths)` (the oracle needs the frame's
    truth annotations) are called through it; any other `Detector.detect(image)` (the CNN)
    sees the crop and its results are shifted by the crop's origin."""
    parts = [(image, tuple(origin_uv))] if rois is None else [
        (crop(image, r, origin_uv), (r[0], r[1])) for r in rois]
    dets: list[Detection] = []
    for img, (ou, ov) in parts:
        if img.size == 0:
            continue
        if hasattr(detector, "detect_region"):
            dets.extend(detector.detect_region(img, (ou, ov), truths))
        else:
            dets.extend(d.shifted(ou, ov) for d in detector.detect(img))
    return dedupe(dets) if rois is not None and len(parts) > 1 else dets
