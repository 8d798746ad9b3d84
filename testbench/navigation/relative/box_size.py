"""Whether a detection's box is small enough to be a neighbour's (RelnavAid: target_extent_m).

No neighbour is nearer than the shortest recent UWB range, so none images larger than
f x extent / (range x cos^2 theta) pixels: a pinhole stretches an object theta off the optical
axis by 1 / cos theta across and 1 / cos^2 theta along the radius (a 120 deg lens: 4x at its
edge; barrel distortion only shrinks it). Only for detectors whose box is the vehicle's outline
(Detector.box_shows_extent): an LED detector's box is the LEDs' glow, whatever the range.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from testbench.navigation.relative.geometry import undistort_normalized
from testbench.navigation.relative.types import Detection


def largest_box_px(camera: Any, centres_px, nearest_range_m: float, extent_m: float, factor: float,
                   slack_px: float) -> np.ndarray:
    """(n,) the largest box side (px) a vehicle of extent_m (m) at no less than nearest_range_m
    (m) may show at each full-frame pixel centres_px (n, 2): factor x f x extent / (range
    cos^2 theta) + slack_px, f the larger focal length (px)."""
    m_xy = undistort_normalized(camera, centres_px)
    cos2 = 1.0 / (1.0 + np.einsum("ij,ij->i", m_xy, m_xy))
    return factor * max(camera.fx, camera.fy) * extent_m / (nearest_range_m * cos2) + slack_px


def small_enough(detections: Sequence[Detection], camera: Any, nearest_range_m: float, extent_m: float,
                 factor: float, slack_px: float) -> list[Detection]:
    """The detections whose larger box side is within largest_box_px, in their order."""
    if not detections:
        return []
    limit_px = largest_box_px(camera, [d.centre_px for d in detections], nearest_range_m, extent_m, factor, slack_px)
    return [d for d, lim in zip(detections, limit_px) if max(d.width_px, d.height_px) <= lim]
