"""Search window and orthorectification: geometry round trips on a synthetic world."""

from __future__ import annotations

import numpy as np

from testbench.core.camera_geometry import camera_pose_ned
from testbench.core.rotations import euler_to_dcm
from testbench.navigation.ismn.geometry import predict_search_window, rays_to_ground
from testbench.navigation.ismn.ortho import Orthorectifier
from testbench.navigation.ismn.synth import RasterMapSource, distort_frame, render_plane_frame
from testbench.core.camera_geometry import PinholeCamera


def _ortho_vs_map(raster, camera, mount, pos, rpy_deg, frame=None):
    R_nb = euler_to_dcm(np.radians(rpy_deg))
    if frame is None:
        frame = render_plane_frame(raster, camera, pos, R_nb, mount)
    c, R_nc = camera_pose_ned(pos, R_nb, mount)
    orth = Orthorectifier(camera)
    src = RasterMapSource(raster)
    from testbench.navigation.ismn.geometry import footprint_bounds
    fp = footprint_bounds(c, R_nc, camera, 0.0, orth.max_off_nadir_rad)
    win = src.read_local(*fp, raster.gsd_m)
    small, K_s = orth.prepare(frame, 1.0)
    of = orth.rectify(small, K_s, c, R_nc, win.north0_m, win.east0_m, win.gsd_m, win.shape, (0, 0), 0.0)
    m = win.data[..., 0].astype(float)
    v = of.valid & win.valid
    return float(np.corrcoef(m[v], of.image[v].astype(float))[0, 1]), of


def test_ortho_of_oblique_frame_matches_map_window(seasons, camera, mount):
    """An oblique frame (10 deg roll, 8 deg pitch, 35 deg heading) warped back to north-up
    correlates with the map window it was rendered from (same raster): NCC >= 0.8."""
    ncc, of = _ortho_vs_map(seasons[0], camera, mount, np.array([50.0, -30.0, -800.0]), [10.0, 8.0, 35.0])
    assert of.valid.mean() > 0.3
    assert ncc >= 0.8, ncc


def test_ortho_with_lens_distortion(seasons, mount):
    """Distortion is undone before the warp (cached undistortion maps)."""
    cam = PinholeCamera.from_hfov(640, 360, 100.0, dist=(-0.12, 0.03, 0.0, 0.0, 0.0))
    pos, rpy = np.array([0.0, 0.0, -800.0]), [4.0, -3.0, 10.0]
    ideal = render_plane_frame(seasons[0], cam, pos, euler_to_dcm(np.radians(rpy)), mount)
    ncc, _ = _ortho_vs_map(seasons[0], cam, mount, pos, rpy, frame=distort_frame(ideal, cam))
    assert ncc >= 0.8, ncc


def test_optical_axis_footprint_centre_eq5(camera, mount):
    """The window centre is where the optical axis meets the ground: p + h (E_N/E_D, E_E/E_D)."""
    pos = np.array([100.0, 200.0, -800.0])
    rpy = np.radians([5.0, -4.0, 30.0])
    R_nb = euler_to_dcm(rpy)
    c, R_nc = camera_pose_ned(pos, R_nb, mount)
    ne, ok = rays_to_ground(c, R_nc, camera.K, np.array([[camera.cx, camera.cy]]), 0.0, np.radians(80))
    E = R_nc[:, 2]
    h = -c[2]
    np.testing.assert_allclose(ne[0], c[:2] + h * E[:2] / E[2], atol=1e-9)
    assert ok[0]


def test_window_contains_truth_and_scales_with_covariance(camera, mount, make_estimate):
    """Window = footprint + 3 sigma: the true footprint lies inside when the estimate is 2.5 sigma
    off, and the window grows with the filter's position covariance (not a constant)."""
    truth_pos, rpy = np.array([0.0, 0.0, -800.0]), [3.0, 2.0, 15.0]
    sigma = 20.0
    est = make_estimate(truth_pos + np.array([2.5 * sigma * 0.6, -2.5 * sigma * 0.8, 0.0]), rpy, sigma_pos_m=sigma)
    win = predict_search_window(est, camera, mount, 0.0, 4.0)
    true_win = predict_search_window(make_estimate(truth_pos, rpy, sigma_pos_m=0.0, sigma_att_deg=0.0), camera, mount, 0.0, 4.0)
    tf, b = true_win.footprint_ne_m, win.bounds_ne_m
    assert b[0] <= tf[0] and b[1] >= tf[1] and b[2] <= tf[2] and b[3] >= tf[3]
    assert b[0] <= true_win.centre_ne_m[0] <= b[1] and b[2] <= true_win.centre_ne_m[1] <= b[3]
    wide = predict_search_window(make_estimate(truth_pos, rpy, sigma_pos_m=100.0), camera, mount, 0.0, 4.0)
    assert win.margin_m >= 3 * sigma + 10.0 and wide.margin_m >= 3 * 100.0 + 10.0 > win.margin_m


def _oblique_ortho(raster, camera, mount, height_fn=None):
    """(lazy OrthoFrame, its whole image and mask warped at once) of an oblique frame (the
    footprint's edge and the off-nadir limit both cut the grid)."""
    from testbench.navigation.ismn.geometry import footprint_bounds

    pos, R_nb = np.array([50.0, -30.0, -800.0]), euler_to_dcm(np.radians([12.0, 8.0, 35.0]))
    frame = render_plane_frame(raster, camera, pos, R_nb, mount)
    c, R_nc = camera_pose_ned(pos, R_nb, mount)
    orth = Orthorectifier(camera, np.radians(55.0))
    fp = footprint_bounds(c, R_nc, camera, 0.0, np.radians(80.0))
    win = RasterMapSource(raster).read_local(*fp, raster.gsd_m)
    small, K_s = orth.prepare(frame, 1.0)
    args = (small, K_s, c, R_nc, win.north0_m, win.east0_m, win.gsd_m, win.shape, (0, 0), 0.0, height_fn)
    whole = orth.rectify(*args)
    return orth.rectify(*args), whole.image, whole.valid


def _check_lazy_ortho(of, image, valid):
    from testbench.navigation.ismn.area import pyramid

    assert valid.any() and not valid.all()  # the test needs both kinds of pixels
    H, W = of.shape
    pyr = pyramid(image, valid, 3)
    rng = np.random.default_rng(1)
    for level in (0, 1, 2):
        for _ in range(40):
            h, w = 48 >> level, 64 >> level
            y0, x0 = int(rng.integers(0, (H >> level) - h)), int(rng.integers(0, (W >> level) - w))
            img, v = of.crop(level, x0, y0, x0 + w, y0 + h)
            ref_img, ref_v = pyr[level][0][y0:y0 + h, x0:x0 + w], pyr[level][1][y0:y0 + h, x0:x0 + w]
            # The same warp of a region: at most one grey level of rounding apart, same mask.
            assert np.abs(img.astype(int) - ref_img).max() <= 1
            np.testing.assert_array_equal(v, ref_v)
            if level == 0:
                assert of.valid_share(x0, y0, w, h) == ref_v.mean()
    # The coarse level is warped from the reduced frame: close to the reduced image (5.5 grey
    # levels on average in this oblique view; 12 warped at the level itself), and valid only
    # where the reduced image is.
    c_img, c_valid = of.coarse(3)
    assert c_img.shape == pyr[3][0].shape
    assert not (c_valid & ~pyr[3][1]).any() and c_valid.sum() >= 0.9 * pyr[3][1].sum()
    both = c_valid & pyr[3][1]
    assert np.abs(c_img[both].astype(float) - pyr[3][0][both]).mean() < 7.0


def test_lazy_ortho_regions_equal_the_whole_warp(seasons, camera, mount):
    """Regions, reduced regions and valid shares of the lazily warped ortho frame are those of
    the whole frame warped at once (plane case); the directly warped coarse level is close."""
    _check_lazy_ortho(*_oblique_ortho(seasons[0], camera, mount))


def test_lazy_ortho_over_relief(seasons, camera, mount):
    """The same over relief (per-pixel ground heights, cv2.remap)."""
    _check_lazy_ortho(*_oblique_ortho(seasons[0], camera, mount, lambda n, e: -(0.03 * np.asarray(e) + 10.0)))


def test_surely_valid_never_claims_an_invalid_pixel(seasons, camera, mount):
    """The corner test that spares the warp of a candidate tile says "all valid" only when it is."""
    of, _, valid = _oblique_ortho(seasons[0], camera, mount)
    H, W = of.shape
    rng = np.random.default_rng(2)
    sure = 0
    for _ in range(400):
        y0, x0 = int(rng.integers(0, H - 64)), int(rng.integers(0, W - 64))
        if of._surely_valid(x0, y0, 64, 64):
            sure += 1
            assert valid[y0:y0 + 64, x0:x0 + 64].all()
    assert sure > 50  # and it does say so for most interior tiles
