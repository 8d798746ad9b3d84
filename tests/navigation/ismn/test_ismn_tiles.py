"""Tile consensus (outliers rejected, affine and projective distortion followed) and the map-window cache."""

from __future__ import annotations

import numpy as np
import pytest

from testbench.navigation.ismn.mapcache import MapWindowCache, quantise_gsd
from testbench.navigation.ismn.synth import RasterMapSource
from testbench.navigation.ismn.tiles import TileMatches, tile_consensus
from testbench.world.raster import LocalRaster


def _tiles(rng, n=24, n_bad=8, A=None):
    o = rng.uniform(0, 1800, (n, 2))
    A = np.array([[1.0, 0.0, 12.3], [0.0, 1.0, -7.6]]) if A is None else A
    m = o @ A[:, :2].T + A[:, 2] + rng.normal(0, 0.2, (n, 2))
    bad = rng.choice(n, n_bad, replace=False)
    m[bad] += rng.uniform(-40, 40, (n_bad, 2))  # false peaks land anywhere in the search box
    ncc = rng.uniform(0.3, 0.8, n)
    return TileMatches(o, m, ncc, np.full(n, 0.05)), bad


def test_consensus_rejects_outliers_and_recovers_the_shift():
    rng = np.random.default_rng(1)
    t, bad = _tiles(rng)
    con = tile_consensus(t)
    assert con is not None
    good = np.ones(len(t.ncc), bool)
    good[bad] = False
    far = np.hypot(*(t.map_px[bad] - t.ortho_px[bad] - [12.3, -7.6]).T) > 3.0
    assert not con.inliers[bad[far]].any()  # every outlier farther than the gate is out
    assert con.inliers[good].mean() > 0.9
    d = (t.map_px - t.ortho_px)[con.inliers]
    np.testing.assert_allclose(np.median(d, axis=0), [12.3, -7.6], atol=0.15)
    # Per-correspondence variance from the residuals: about the 0.2 px noise we added.
    assert 0.01 < con.var_px2 < 0.1


def test_consensus_follows_a_small_affine_distortion():
    """An attitude error leaves a small scale/rotation in the ortho view: 1e-3 over 1800 px is
    1.8 px across the frame, more than the inlier gate of a pure shift would allow."""
    rng = np.random.default_rng(2)
    A = np.array([[1.001, 0.0008, 5.0], [-0.0008, 1.001, 3.0]])
    t, bad = _tiles(rng, n=30, n_bad=6, A=A)
    for projective in (False, True):
        con = tile_consensus(t, consensus_px=3.0, inlier_px=1.0, projective=projective)
        good = np.ones(len(t.ncc), bool)
        good[bad] = False
        assert con.kind == ("homography" if projective else "affine") and con.inliers[good].mean() > 0.9
        # An affine is a homography with a last row [0, 0, 1]: the projective fit finds it.
        np.testing.assert_allclose(con.H[:2, :2], A[:, :2], atol=2e-4)
        np.testing.assert_allclose(con.H[:2, 2], A[:, 2], atol=0.3)
        np.testing.assert_allclose(con.H[2, :2], 0.0, atol=2e-6)


def _tilted_view_homography(tilt_rad, height_px=800.0, centre=(900.0, 900.0)):
    """Ortho px -> map px of a nadir view built with its attitude off by tilt_rad about the
    image's x axis, over flat ground height_px below (pixels as ground units): the plane
    homography K R K^-1 of a pure rotation, with K = [[f, 0, cx], [0, f, cy], [0, 0, 1]]."""
    f = height_px
    K = np.array([[f, 0.0, centre[0]], [0.0, f, centre[1]], [0.0, 0.0, 1.0]])
    c, s = np.cos(tilt_rad), np.sin(tilt_rad)
    R = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    H = K @ R @ np.linalg.inv(K)
    return H / H[2, 2]


def test_consensus_keeps_the_outer_tiles_of_a_tilted_view():
    """A 5 mrad tilt error over a wide view moves the outer tiles by up to 2.3x the central ones
    (1 / cos^2 off nadir), which no affine follows: with an affine the inlier gate dropped the
    outer tiles whose noise did not happen to flatten that pattern, and the survivors
    under-read it. The homography (projective=True) keeps them and reads the pattern without
    bias."""
    rng = np.random.default_rng(4)
    H = _tilted_view_homography(5e-3)
    o = np.stack(np.meshgrid(np.linspace(0, 1800, 8), np.linspace(0, 1800, 6)), -1).reshape(-1, 2)
    q = np.c_[o, np.ones(len(o))] @ H.T
    m_true = q[:, :2] / q[:, 2:]
    m = m_true + rng.normal(0, 0.3, o.shape)
    t = TileMatches(o, m, np.full(len(o), 0.6), np.full(len(o), 0.05))
    spread = np.ptp(m_true[:, 1] - o[:, 1])
    assert spread > 4.0  # the pattern: several pixels between centre and edge
    affine = tile_consensus(t, consensus_px=3.0 + spread, inlier_px=1.5)
    assert affine.kind == "affine" and affine.inliers.mean() < 0.6  # what the affine gate does
    con = tile_consensus(t, consensus_px=3.0 + spread, inlier_px=1.5, projective=True)
    assert con.kind == "homography" and con.inliers.all()
    # The fitted map reproduces the true one within the noise's reach, at the outer tiles too.
    q = np.c_[o, np.ones(len(o))] @ con.H.T
    assert np.abs(q[:, :2] / q[:, 2:] - m_true).max() < 0.5


def test_consensus_needs_agreement():
    rng = np.random.default_rng(3)
    o = rng.uniform(0, 1000, (6, 2))
    t = TileMatches(o, o + rng.uniform(-60, 60, (6, 2)), np.full(6, 0.5), np.zeros(6))
    con = tile_consensus(t, consensus_px=1.0)
    assert con is None or con.inliers.sum() <= 2


def test_quantise_gsd():
    assert quantise_gsd(1.5, 1.5) == 1.5
    assert quantise_gsd(1.2, 1.5) == 1.2  # finer than native: unchanged
    g = quantise_gsd(1.6, 1.5)
    assert 1.6 <= g < 1.6 * 2 ** 0.125 + 1e-9
    assert quantise_gsd(1.61, 1.5) == g  # nearby requests share one sample


def test_map_cache_crop_equals_direct_read():
    rng = np.random.default_rng(4)
    data = rng.integers(0, 255, (400, 500, 3), dtype=np.uint8)
    src = RasterMapSource(LocalRaster(data, np.ones((400, 500), bool), 300.0, -250.0, 1.5))
    cache = MapWindowCache(src, grow=0.5)
    for n0, e0 in [(-60.0, -90.0), (-51.0, -75.0), (-45.0, -80.0)]:
        r = cache.read(n0, n0 + 120.0, e0, e0 + 150.0, 1.5)
        assert r.north0_m >= n0 + 120.0 - 1e-9 and r.north0_m - r.shape[0] * 1.5 <= n0 + 1e-9
        assert r.east0_m <= e0 + 1e-9 and r.east0_m + r.shape[1] * 1.5 >= e0 + 150.0 - 1e-9
        direct = src.read_local(r.north0_m - r.shape[0] * 1.5, r.north0_m, r.east0_m, r.east0_m + r.shape[1] * 1.5, 1.5)
        grey = (direct.data.astype(float) @ [0.299, 0.587, 0.114])
        assert np.abs(r.data.astype(float) - grey).max() <= 1.0
    assert len(cache._cache) == 1  # one read served all three


@pytest.mark.parametrize("grow", [0.0, 0.5])
def test_map_cache_covers_request(grow):
    data = np.full((200, 200, 3), 100, np.uint8)
    src = RasterMapSource(LocalRaster(data, np.ones((200, 200), bool), 150.0, -150.0, 1.5))
    r = MapWindowCache(src, grow=grow).read(-10.3, 20.7, 5.1, 33.3, 1.5)
    assert r.north0_m >= 20.7 - 1e-9 and r.north0_m - r.shape[0] * 1.5 <= -10.3 + 1e-9


def test_pyramid_levels_equal_chained_halving():
    """A level made in one pass from level 0 equals two exact halvings (INTER_AREA), and a
    reduced pixel is valid only when all the pixels it covers are."""
    import cv2

    from testbench.navigation.ismn.area import pyramid

    rng = np.random.default_rng(5)
    img = rng.integers(0, 255, (203, 317), dtype=np.uint8)
    valid = np.ones(img.shape, bool)
    valid[10, 20] = False
    pyr = pyramid(img, valid, 2)
    g1 = cv2.resize(img[:202, :316], None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
    g2 = cv2.resize(g1[:100, :158], None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
    assert len(pyr) == 3 and pyr[2][0].shape == g2.shape
    assert np.abs(pyr[2][0].astype(int) - g2).max() <= 1
    v2 = pyr[2][1]
    assert not v2[10 // 4, 20 // 4] and v2.sum() == v2.size - 1


def test_map_cache_serves_the_levels_of_its_crops():
    """A window's reduced levels cut from the cached read's pyramid are the window's own (crops
    start on multiples of ALIGN_PX); its coarse feature image differs only by the context the
    read gives its local normalisation."""
    from testbench.navigation.ismn.area import pyramid
    from testbench.navigation.ismn.features import robust_image
    from testbench.navigation.ismn.mapcache import ALIGN_PX

    rng = np.random.default_rng(3)
    data = rng.integers(0, 255, (401, 523, 3), dtype=np.uint8)
    valid = np.ones((401, 523), bool)
    valid[5:9, 300:320] = False
    src = RasterMapSource(LocalRaster(data, valid, 300.0, -250.0, 1.5))
    cache = MapWindowCache(src)
    for n0, e0 in [(-60.3, -90.1), (-51.0, -75.7), (150.0, -240.0)]:
        w = cache.read(n0, n0 + 140.3, e0, e0 + 170.2, 1.5)
        assert w.north0_m >= n0 + 140.3 - 1e-9 and w.east0_m <= e0 + 1e-9  # still covers the request
        own = pyramid(w.data, w.valid, 3)
        for level in (1, 2, 3):
            img, v = cache.pyramid_level(w, level)
            np.testing.assert_array_equal(img, own[level][0])
            np.testing.assert_array_equal(v, own[level][1])
        f, f_own = cache.features(w, "gradmag", 1), robust_image(*own[1])[0]
        assert f.shape == f_own.shape and np.abs(f - f_own)[12:-12, 12:-12].max() < 0.05
    assert cache.pyramid_level(w, int(np.log2(ALIGN_PX)) + 1) is None
