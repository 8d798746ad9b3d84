"""Renderer geometry against OpenCV: projection, pixel -> ground round trip, metres per pixel,
the horizon row, and marker centroids in the rendered image (lens distortion included)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from conftest import mount, raster, textured

from testbench.core.camera_geometry import PinholeCamera, camera_pose_ned
from testbench.core.rotations import euler_to_dcm
from testbench.sensors.camera import RenderOptions, project_points, render

DIST = (-0.18, 0.04, 0.0008, -0.0006, -0.003)
NO_HAZE = RenderOptions(haze_visibility_m=None)


def _pose(rpy_deg):
    return euler_to_dcm(np.radians(rpy_deg))


@pytest.mark.parametrize("dist", [(0.0,) * 5, DIST])
@pytest.mark.parametrize("pitch_deg, rpy_deg", [(-90.0, (2.0, -3.0, 25.0)), (-50.0, (4.0, 1.0, -70.0))])
def test_ground_points_reproject_onto_their_pixels(dist, pitch_deg, rpy_deg):
    """Each pixel's ground point, projected by cv2.projectPoints (same K, distortion, pose),
    lands on that pixel's centre (< 0.05 px); lens.project_points agrees with OpenCV."""
    cam = PinholeCamera.from_hfov(160, 120, 80.0, dist)
    img = raster(textured(256), 2.0)
    pos, R_nb, m = np.array([5.0, -3.0, -120.0]), _pose(rpy_deg), mount(pitch_deg)
    f = render(cam, m, pos, R_nb, img, want_ground_points=True, options=NO_HAZE)
    pts = f.ground_points_ned_m
    ok = np.isfinite(pts).all(axis=-1)
    assert ok.mean() > 0.5
    v, u = np.nonzero(ok)
    C, R_nc = camera_pose_ned(pos, R_nb, m)
    uv, z = project_points(cam, C, R_nc, pts[v, u])
    assert (z > 0).all()
    err = np.hypot(uv[:, 0] - u, uv[:, 1] - v)
    assert err.max() < 0.05
    # The same with OpenCV called directly (world -> camera: R_cn = R_nc^T, t = -R_cn C).
    R_cn = R_nc.T
    uv_cv, _ = cv2.projectPoints(pts[v, u].reshape(-1, 1, 3), cv2.Rodrigues(R_cn)[0], -R_cn @ C, cam.K,
                                 np.asarray(dist, float))
    assert np.abs(uv_cv.reshape(-1, 2) - uv).max() < 1e-9


def test_rendered_markers_sit_on_their_projections():
    """Bright 3 x 3-pixel markers at known NE points on a dark map: with lens distortion and an
    oblique view, each marker's intensity centroid lies within 0.15 px of its projection."""
    gsd = 0.25
    data = np.full((800, 800, 3), 20, np.uint8)
    g = np.arange(40, 760, 48)
    rc = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2) + np.random.default_rng(3).integers(-5, 6, (g.size**2, 2))
    for r, c in rc:
        data[r - 1:r + 2, c - 1:c + 2] = 230
    img = raster(data, gsd)
    north, east = img.rowcol_to_ne(rc[:, 0].astype(float), rc[:, 1].astype(float))
    P = np.c_[north, east, np.zeros(len(rc))]
    cam = PinholeCamera.from_hfov(320, 240, 70.0, DIST)
    pos, R_nb, m = np.array([0.0, 0.0, -60.0]), _pose((3.0, -2.0, 15.0)), mount(-75.0)
    f = render(cam, m, pos, R_nb, img, options=NO_HAZE)
    uv, z = project_points(cam, *camera_pose_ned(pos, R_nb, m), P)
    grey = f.image[..., 1].astype(float) - 20.0
    checked = 0
    for i, ((u, v), zz) in enumerate(zip(uv, z)):
        u0, v0 = int(round(u)), int(round(v))
        if zz <= 0 or not (8 <= u0 < cam.width_px - 8 and 8 <= v0 < cam.height_px - 8):
            continue
        assert np.sort(np.hypot(*(uv - uv[i]).T))[1] > 14  # one marker per window
        win = np.clip(grey[v0 - 6:v0 + 7, u0 - 6:u0 + 7], 0, None)
        vv, uu = np.mgrid[v0 - 6:v0 + 7, u0 - 6:u0 + 7]
        cu, cv_ = (win * uu).sum() / win.sum(), (win * vv).sum() / win.sum()
        assert np.hypot(cu - u, cv_ - v) < 0.15, (u, v, cu, cv_)
        checked += 1
    assert checked >= 20


def test_nadir_round_trip_to_map_coordinates(nadir):
    """A map whose red/green encode its column/row (2 DN per map pixel): the colour of every
    rendered pixel gives back the map coordinates of its ground point (< 0.5 map pixel)."""
    n, gsd = 120, 1.0
    rows, cols = np.mgrid[0:n, 0:n]
    data = np.stack([2 * cols, 2 * rows, np.full_like(cols, 128)], axis=-1).astype(np.uint8)
    img = raster(data, gsd)
    cam = PinholeCamera.from_hfov(200, 150, 60.0)
    f = render(cam, nadir, np.array([3.0, -2.0, -70.0]), _pose((1.0, 2.0, 33.0)), img,
               want_ground_points=True, options=NO_HAZE)
    pts = f.ground_points_ned_m
    assert f.valid.all() and np.isfinite(pts).all()
    row, col = img.ne_to_rowcol(pts[..., 0], pts[..., 1])
    assert np.abs(f.image[..., 0] / 2.0 - col).max() < 0.5
    assert np.abs(f.image[..., 1] / 2.0 - row).max() < 0.5


def _period_px(signal: np.ndarray) -> float:
    """Dominant period (px) of a 1-D signal, from its spectrum's peak (parabolic refinement)."""
    s = signal - signal.mean()
    n = 8 * len(s)
    spec = np.abs(np.fft.rfft(s * np.hanning(len(s)), n))
    k = int(np.argmax(spec[4:])) + 4
    a, b, c = np.log(spec[k - 1:k + 2])
    k += 0.5 * (a - c) / (a - 2 * b + c)
    return n / k


def test_checkerboard_metres_per_pixel(nadir):
    """Level camera at height h straight down: a pixel covers h / f metres, so 4 m squares
    repeat every 2 * 4 * f / h pixels along image rows and columns."""
    sq_m, gsd, n = 4.0, 0.5, 1200
    rows, cols = np.mgrid[0:n, 0:n]
    board = (((rows * gsd) // sq_m + (cols * gsd) // sq_m) % 2 * 200 + 30).astype(np.uint8)
    img = raster(np.repeat(board[..., None], 3, axis=2), gsd)
    cam = PinholeCamera.from_hfov(400, 300, 60.0)
    h = 150.0
    f = render(cam, nadir, np.array([0.3, 0.7, -h]), np.eye(3), img, options=NO_HAZE)
    g = f.image[..., 1].astype(float)
    expected = 2 * sq_m * cam.fx / h
    assert _period_px(g.mean(axis=0)) == pytest.approx(expected, rel=0.01)
    assert _period_px(g.mean(axis=1)) == pytest.approx(expected, rel=0.01)


@pytest.mark.parametrize("pitch_deg", [0.0, 5.0, 12.0])
def test_horizon_row_for_pitch(pitch_deg):
    """Forward camera, vehicle pitched up by p at 100 m over flat ground: the first ground row
    is v = cy + fy tan(p) (the horizon moves down the image as the nose goes up), up to the
    dip of the far plane, here 100 m / 1e6 m (0.01 px)."""
    cam = PinholeCamera.from_hfov(320, 240, 90.0)
    img = raster(textured(128), 20.0)
    f = render(cam, mount(0.0), np.array([0.0, 0.0, -100.0]), _pose((0.0, pitch_deg, 40.0)), img,
               options=RenderOptions(far_m=1e6))
    expected = cam.cy + cam.fy * np.tan(np.radians(pitch_deg))
    for u in (0, cam.width_px // 2, cam.width_px - 1):
        first_ground = int(np.argmin(f.sky[:, u]))
        assert f.sky[:first_ground, u].all() and not f.sky[first_ground:, u].any()
        # Pixel centres: rows < expected are sky, rows > expected are ground.
        assert first_ground - 1 < expected + 0.02 and first_ground > expected - 0.02
    # The sky is drawn with the sky colours, not the map.
    assert (f.image[f.sky][:, 2] > f.image[f.sky][:, 0]).all()


def test_dem_max_maps_bound_the_terrain_exactly():
    """The ray caster's empty-space maps (built level by level from shifted maxima) equal a
    direct square dilation of radius 2^j + 1, edges replicated."""
    from testbench.sensors.camera.pyramid import DemSampler
    from testbench.world.raster import LocalRaster

    rng = np.random.default_rng(3)
    h = (rng.random((150, 230)) * 100.0).astype(np.float32)
    sampler = DemSampler(LocalRaster(h, np.ones_like(h, bool), 0.0, 0.0, 4.0))
    assert len(sampler.max_maps) == 8  # radii 2 ... 129 while 2^j <= 230
    for j, got in enumerate(sampler.max_maps):
        r = (1 << j) + 1
        want = cv2.dilate(h, np.ones((2 * r + 1, 2 * r + 1), np.uint8), borderType=cv2.BORDER_REPLICATE)
        np.testing.assert_array_equal(got, want, err_msg=f"level {j}")
