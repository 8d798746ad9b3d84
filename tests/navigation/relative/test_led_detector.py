"""The LED blob detector on synthetic frames: what it finds, where, in which order, and what it
leaves out."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from testbench.navigation.relative.detectors import LedDetector


def _led(img: np.ndarray, u: float, v: float, colour=(255, 40, 40), r: int = 2) -> None:
    """A lit LED as the renderer draws one: a saturated glow around a near-white core."""
    glow = tuple(int(0.6 * c + 0.4 * 255) for c in colour)
    core = tuple(int(0.35 * c + 0.65 * 255) for c in colour)
    cv2.circle(img, (int(round(u)), int(round(v))), 2 * r, glow, -1, cv2.LINE_AA)
    cv2.circle(img, (int(round(u)), int(round(v))), r, core, -1, cv2.LINE_AA)


def _frame(h: int = 600, w: int = 900) -> np.ndarray:
    rng = np.random.default_rng(3)
    return np.clip(rng.normal(90, 12, (h, w, 3)), 0, 255).astype(np.uint8)  # textured dull ground


def test_two_vehicles_are_found_in_raster_order_at_their_led_centroids():
    img = _frame()
    lower = [(700.0, 400.0), (712.0, 400.0)]  # two LEDs of one vehicle (separate blobs, one group)
    upper = [(150.0, 120.0), (162.0, 124.0)]  # drawn second, lies higher in the frame
    for u, v in lower + upper:
        _led(img, u, v)
    dets = LedDetector().detect(img)
    assert len(dets) == 2
    # Top row first, whatever order OpenCV labels the blobs in.
    assert dets[0].centre_px[1] < dets[1].centre_px[1]
    for det, leds in zip(dets, (upper, lower)):
        assert np.hypot(*(np.asarray(det.centre_px) - np.mean(leds, axis=0))) < 1.0
        assert len(det.led_px) == 2
        u0, v0, u1, v1 = det.bbox_px
        assert all(u0 <= u <= u1 and v0 <= v <= v1 for u, v in leds)


def test_nothing_lit_gives_nothing():
    assert LedDetector().detect(_frame()) == []
    # Bright but unsaturated (sky, a white roof) is not an LED.
    img = _frame()
    img[100:140, 200:260] = 250
    assert LedDetector().detect(img) == []


def test_a_saturated_patch_larger_than_an_led_is_not_one():
    img = _frame()
    img[200:240, 300:340] = (255, 60, 60)  # 1600 px of bright red: a painted surface, not a blob
    _led(img, 600.0, 300.0)
    dets = LedDetector().detect(img)
    assert len(dets) == 1 and abs(dets[0].centre_px[0] - 600.0) < 1.0


def test_the_data_hue_level_counts_only_the_data_leds():
    """With data_hue_deg (red data LEDs, a green anchor), led_level is 0.05 + the red LEDs'
    brightness: clear of zero with only the anchor lit."""
    anchor_only, with_data = _frame(), _frame()
    _led(anchor_only, 400.0, 300.0, colour=(40, 255, 40))
    _led(with_data, 400.0, 300.0, colour=(40, 255, 40))
    _led(with_data, 408.0, 300.0, colour=(255, 40, 40))
    det = LedDetector(LedDetector.Params(data_hue_deg=0.0))
    (a,), (b,) = det.detect(anchor_only), det.detect(with_data)
    assert a.led_level < 0.1 < 1.0 < b.led_level


def test_the_data_leds_centroid_is_reported_apart_from_the_anchor():
    """With data_hue_deg the detection also gives the centroid of its data LEDs alone (the red
    ones), which a merged blob's chip-resolved bearing uses; None with only the anchor lit; it
    moves with the detection into full-frame pixels."""
    img = _frame()
    _led(img, 400.0, 296.0, colour=(40, 255, 40))  # the anchor, above
    data = [(394.0, 304.0), (406.0, 304.0)]
    for u, v in data:
        _led(img, u, v, colour=(255, 40, 40))
    (det,) = LedDetector(LedDetector.Params(data_hue_deg=0.0)).detect(img)
    assert np.hypot(*(np.asarray(det.data_centre_px) - np.mean(data, axis=0))) < 0.3
    assert abs(det.centre_px[1] - 304.0) > 1.0  # the whole group's centroid is pulled up by the anchor
    moved = det.shifted(100.0, 50.0)
    assert moved.data_centre_px == pytest.approx((det.data_centre_px[0] + 100.0, det.data_centre_px[1] + 50.0))
    anchor_only = _frame()
    _led(anchor_only, 400.0, 296.0, colour=(40, 255, 40))
    (a,) = LedDetector(LedDetector.Params(data_hue_deg=0.0)).detect(anchor_only)
    assert a.data_centre_px is None
    (plain,) = LedDetector().detect(img)
    assert plain.data_centre_px is None  # no data hue configured: no such centroid


def test_a_group_with_two_anchors_is_two_vehicles():
    """Two vehicles 10 px apart (closer than group_px): one detection between them without
    anchor_hue_deg; with it, one detection at each vehicle's LEDs, each with its own blobs."""
    img = _frame()
    near = [(400.0, 300.0, (40, 255, 40)), (396.0, 304.0, (255, 40, 40)), (404.0, 304.0, (255, 40, 40))]
    far = [(411.0, 301.0, (40, 255, 40)), (413.0, 303.0, (255, 40, 40))]
    for u, v, c in near + far:
        _led(img, u, v, colour=c, r=1)
    merged = LedDetector(LedDetector.Params(data_hue_deg=0.0)).detect(img)
    assert len(merged) == 1
    split = LedDetector(LedDetector.Params(data_hue_deg=0.0, anchor_hue_deg=120.0)).detect(img)
    assert len(split) == 2
    by_u = sorted(split, key=lambda d: d.centre_px[0])
    for det, leds in zip(by_u, (near, far)):
        centroid = np.mean([(u, v) for u, v, _ in leds], axis=0)
        assert np.hypot(*(np.asarray(det.centre_px) - centroid)) < 1.5
    # One vehicle alone (one anchor) stays one detection.
    one = _frame()
    for u, v, c in near:
        _led(one, u, v, colour=c, r=1)
    assert len(LedDetector(LedDetector.Params(data_hue_deg=0.0, anchor_hue_deg=120.0)).detect(one)) == 1


def test_a_group_with_two_anchors_reports_its_parts_and_stays_one_detection():
    """anchor_split "parts": the two vehicles 10 px apart stay one detection (the merged one's
    centre and blink level, for tracking and decoding) that reports each vehicle's LED centroid
    as a part, also after the detection is moved to full-frame pixels; one vehicle has none."""
    img = _frame()
    near = [(400.0, 300.0, (40, 255, 40)), (396.0, 304.0, (255, 40, 40)), (404.0, 304.0, (255, 40, 40))]
    far = [(411.0, 301.0, (40, 255, 40)), (413.0, 303.0, (255, 40, 40))]
    for u, v, c in near + far:
        _led(img, u, v, colour=c, r=1)
    (merged,) = LedDetector(LedDetector.Params(data_hue_deg=0.0)).detect(img)
    parts_det = LedDetector(LedDetector.Params(data_hue_deg=0.0, anchor_hue_deg=120.0, anchor_split="parts"))
    (det,) = parts_det.detect(img)
    assert det.centre_px == pytest.approx(merged.centre_px) and det.led_level == pytest.approx(merged.led_level)
    assert len(merged.parts_px) == 0 and det.parts_px.shape == (2, 2)
    by_u = det.parts_px[np.argsort(det.parts_px[:, 0])]
    for part, leds in zip(by_u, (near, far)):
        assert np.hypot(*(part - np.mean([(u, v) for u, v, _ in leds], axis=0))) < 1.5
    moved = det.shifted(100.0, -50.0)
    assert moved.parts_px == pytest.approx(det.parts_px + [100.0, -50.0])
    one = _frame()
    for u, v, c in near:
        _led(one, u, v, colour=c, r=1)
    (alone,) = parts_det.detect(one)
    assert len(alone.parts_px) == 0
