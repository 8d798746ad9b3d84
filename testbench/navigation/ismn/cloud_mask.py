"""Which pixels of a camera frame are cloud, from the pixels alone (`pipeline.cloud_mask`).

A cloud top seen from above is bright in every channel and nearly grey; the ground rarely is
(over the project's worlds, pixels with their darkest channel at 175 or more and their
channels within 30 of each other: 0.02 % of the procedural farmland, 0.1-0.34 % of the three
North Dakota NAIP years, 0.47 % of McMillan's dry hills, mostly roads and roofs, which are
narrow). The mask takes those pixels, drops the patches narrower than `min_size_px` (a
morphological opening: roads, roofs, a bright car) and grows the rest by `margin_px`, since a
cloud's thin fringe veils the ground without being bright itself: its edge would otherwise
stand in the frame as an edge the map does not have, and the matcher's gradient image is made
of edges. The scene matcher then treats the mask as no-data, as it does the ground beyond the
frame's border.

Without colour (a grey frame) the brightness alone decides. Snow, salt flats and white roofs
are cloud to this test: it costs their tiles, never a false edge.
"""

from __future__ import annotations

import cv2
import numpy as np
import pydantic

from testbench.core.registry import ParamsModel


class CloudMaskParams(ParamsModel):
    """The cloud test (0-255 digital numbers; full-frame pixels)."""

    min_brightness: int = pydantic.Field(175, ge=0, le=255, description="a cloud pixel's darkest channel is at least this")
    max_spread: int = pydantic.Field(30, ge=0, le=255, description="and its channels lie within this of each other (clouds are grey-white)")
    min_size_px: int = pydantic.Field(15, ge=1, description="bright patches narrower than this are ground (roads, roofs)")
    margin_px: int = pydantic.Field(10, ge=0, description="grown around each cloud: its fringe veils the ground")
    max_share: float = pydantic.Field(0.9, gt=0, le=1, description="no match tried when clouds hide more of the frame than this")


def cloud_mask(frame: np.ndarray, p: CloudMaskParams) -> np.ndarray:
    """(H, W) bool, True where `frame` ((H, W, 3) RGB or (H, W) grey uint8) shows cloud.

    Frames 640 px wide or more are tested at half resolution (clouds are tens of pixels
    across at least), and the mask brought back to the frame's pixels."""
    img = np.asarray(frame)
    H, W = img.shape[:2]
    f = 2 if W >= 640 else 1
    if f > 1:
        img = cv2.resize(img, (W // f, H // f), interpolation=cv2.INTER_AREA)
    if img.ndim == 3:
        r, g, b = cv2.split(np.ascontiguousarray(img[..., :3]))
        lo = cv2.min(cv2.min(r, g), b)
        spread = cv2.subtract(cv2.max(cv2.max(r, g), b), lo)
        cand = (lo >= p.min_brightness) & (spread <= p.max_spread)
    else:
        cand = img >= p.min_brightness
    m = cand.view(np.uint8)
    k_open = max(1, round(p.min_size_px / f)) | 1
    if k_open > 1:
        m = cv2.morphologyEx(m, cv2.MORPH_OPEN, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k_open, k_open)))
    k_grow = 2 * round(p.margin_px / f) + 1
    if k_grow > 1 and m.any():
        m = cv2.dilate(m, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k_grow, k_grow)))
    if f > 1:
        m = cv2.resize(m, (W, H), interpolation=cv2.INTER_NEAREST)
    return m.view(bool)
