"""Matchers: sub-pixel offset recovery, a wrong match gets a low quality, registration."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from testbench.core.registry import available, build
from testbench.navigation.ismn.area import NccMatcher, PhaseMatcher, subpixel_peak
from testbench.navigation.ismn.types import MatchPrior
from testbench.navigation.ismn.synth import procedural_seasons


def test_matchers_registered():
    assert {"ncc", "phase", "orb", "sift"} <= set(available("matcher"))
    m = build("matcher", "ncc", {"tiles_x": 4}, where="test", ctx=None)
    assert isinstance(m, NccMatcher) and m.p.tiles_x == 4


def test_subpixel_peak_of_a_parabola():
    y, x = np.mgrid[0:9, 0:9]
    res = -((x - 4.3) ** 2) - 0.5 * (y - 3.8) ** 2
    assert subpixel_peak(res.astype(np.float32), 4, 4) == pytest.approx((4.3, 3.8), abs=1e-6)


def _shifted_crop(img, x0, y0, w, h, dx, dy):
    """Crop of img whose pixel (0, 0) sits at map pixel (x0 + dx, y0 + dy), bilinear."""
    A = np.array([[1.0, 0.0, x0 + dx], [0.0, 1.0, y0 + dy]])
    return cv2.warpAffine(img, A, (w, h), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP)


@pytest.mark.parametrize("cls", [NccMatcher, PhaseMatcher])
def test_known_offset_recovered_to_subpixel(seasons, cls):
    """The ortho frame is the map shifted by (6.3, -4.6) px from its predicted place, and from
    another season: the offset comes back to better than 0.25 px."""
    summer, winter = seasons
    m = winter.data[:600, :700, 0]
    x0, y0, dx, dy = 60, 70, 6.3, -4.6
    o = _shifted_crop(summer.data[:600, :700, 0], x0, y0, 560, 440, dx, dy)
    res = cls().match(o, m, MatchPrior((x0, y0), 20.0))
    assert res is not None
    np.testing.assert_allclose(res.offset_px, [dx, dy], atol=0.25)
    assert res.quality > 0.5
    assert res.ortho_px is not None and len(res.ortho_px) >= 6
    np.testing.assert_allclose(np.median(res.map_px - res.ortho_px, axis=0), [x0 + dx, y0 + dy], atol=0.25)


def test_wrong_map_gets_low_quality(seasons):
    """Matching against a map of somewhere else: no distinct peak, no consistent tiles."""
    other, _ = procedural_seasons(np.random.default_rng(99), 700, 4.0)
    o = seasons[0].data[70:510, 60:620, 0]
    res = NccMatcher().match(o, other.data[:600, :700, 0], MatchPrior((60, 70), 20.0))
    assert res is None or res.quality < 0.15
    good = NccMatcher().match(o, seasons[1].data[:600, :700, 0], MatchPrior((60, 70), 20.0))
    assert good.quality > 0.5


@pytest.mark.parametrize("name", ["orb", "sift"])
def test_feature_matchers_same_season(seasons, name):
    """Feature matchers recover a shift on the same season (inliers give the quality)."""
    m = seasons[0].data[:600, :700, 0]
    o = _shifted_crop(m, 60, 70, 560, 440, 5.0, -3.0)
    res = build("matcher", name, None, where="test", ctx=None).match(o, m, MatchPrior((60, 70), 20.0))
    assert res is not None and res.quality > 0.3
    np.testing.assert_allclose(res.offset_px, [5.0, -3.0], atol=0.5)


def test_heading_uncertainty_widens_the_tile_search(seasons):
    """The ortho frame rotated 2 deg against the map (a heading error) and shifted: with the
    prior's heading sigma (2 deg) the tiles search far enough and the affine fit takes the
    rotation, so the correspondences follow it to half a pixel; the matcher told the heading is
    exact finds a handful of agreeing tiles at best."""
    summer, winter = seasons
    m = winter.data[:600, :700, 0]
    x0, y0, w, h = 60, 70, 560, 440
    ang = np.radians(2.0)
    c, s = np.cos(ang), np.sin(ang)
    cx, cy = w / 2.0, h / 2.0
    # ortho px (x, y) sits at map px R (x - c) + c + (x0 + 4, y0 - 3): rotation about the centre.
    A = np.array([[c, -s, x0 + 4.0 + cx - c * cx + s * cy], [s, c, y0 - 3.0 + cy - s * cx - c * cy]])
    o = cv2.warpAffine(summer.data[:600, :700, 0], A, (w, h), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP)
    told = NccMatcher().match(o, m, MatchPrior((x0, y0), 20.0, heading_sigma_rad=ang))
    assert told is not None and told.ortho_px is not None and len(told.ortho_px) >= 20 and told.quality > 0.8
    pred = told.ortho_px @ A[:, :2].T + A[:, 2]
    assert np.abs(told.map_px - pred).max() < 0.5
    blind = NccMatcher().match(o, m, MatchPrior((x0, y0), 20.0))
    n_blind = 0 if blind is None or blind.ortho_px is None else len(blind.ortho_px)
    assert n_blind <= 8 and (blind is None or blind.quality < 0.5)


def test_a_tile_displaced_beyond_its_search_is_dropped_not_clipped(seasons):
    """A tile whose true offset lies outside its search box peaks on the box's edge: that is no
    measurement, and the tile is dropped (kept, it would report the edge as its offset). The
    same tiles with a search wide enough recover the offset."""
    from testbench.navigation.ismn.area import as_u8, pyramid
    from testbench.navigation.ismn.tiles import refine_tiles
    from testbench.navigation.ismn.types import OrthoFrame

    m = as_u8(seasons[1].data[:600, :700, 0])
    o = as_u8(_shifted_crop(seasons[0].data[:600, :700, 0], 60, 70, 400, 300, 9.0, -7.0))
    pyr_o = OrthoFrame.from_image(o)
    pyr_m = pyramid(m, np.ones(m.shape, bool), 0)
    tiles = [(x, y) for x in (40, 160, 280) for y in (40, 160)]
    wide = refine_tiles(pyr_o, pyr_m, (60, 70), (0.0, 0.0), 12.0, tiles, 64, "gradmag", 0.15)
    assert len(wide.ortho_px) >= 5
    np.testing.assert_allclose(wide.map_px - wide.ortho_px - [60, 70], np.tile([9.0, -7.0], (len(wide.ortho_px), 1)), atol=0.5)
    # Searched to 8 px: the 9 px offset is one pixel beyond; the edge column still scores an NCC
    # of about 0.5 (that is what the tiles reported at 8.0 px before they were dropped).
    narrow = refine_tiles(pyr_o, pyr_m, (60, 70), (0.0, 0.0), 7.0, tiles, 64, "gradmag", 0.15)
    assert len(narrow.ortho_px) == 0
