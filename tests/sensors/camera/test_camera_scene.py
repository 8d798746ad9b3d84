"""Renderer scenes: relief (peak position, occlusion), off-map no-data, other vehicles with LEDs,
regions of interest, seeded noise and anti-aliasing."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import mount, raster, textured

from testbench.core.camera_geometry import PinholeCamera, camera_pose_ned
from testbench.core.rotations import euler_to_dcm
from testbench.sensors.camera import RenderOptions, VehicleAppearance, project_points, render
from testbench.world.raster import LocalRaster

NO_HAZE = RenderOptions(haze_visibility_m=None)
PEAK_NE, PEAK_H, PEAK_SIGMA = np.array([40.0, -30.0]), 80.0, 22.0
BEHIND_NE = np.array([150.0, -30.0])


@pytest.fixture(scope="module")
def hill():
    """A Gaussian hill (DEM at 2 m) and a 0.5 m map with a red disc on its top and a blue
    patch on the flat ground behind it (north of it)."""
    dem_gsd, map_gsd = 2.0, 0.5
    dem = raster(np.zeros((300, 300), np.float32), dem_gsd, (50.0, -30.0))
    rows, cols = np.mgrid[0:300, 0:300]
    n, e = dem.rowcol_to_ne(rows, cols)
    h = PEAK_H * np.exp(-((n - PEAK_NE[0]) ** 2 + (e - PEAK_NE[1]) ** 2) / (2 * PEAK_SIGMA**2))
    dem = LocalRaster(h.astype(np.float32), dem.valid, dem.north0_m, dem.east0_m, dem_gsd)
    data = np.repeat(textured(1200, seed=4)[..., :1] // 2 + 60, 3, axis=2)  # grey: markers stand out
    img = raster(data, map_gsd, (50.0, -30.0))
    rows, cols = np.mgrid[0:1200, 0:1200]
    n, e = img.rowcol_to_ne(rows, cols)
    data[np.hypot(n - PEAK_NE[0], e - PEAK_NE[1]) < 5.0] = (240, 20, 20)
    data[(np.abs(n - BEHIND_NE[0]) < 20.0) & (np.abs(e - BEHIND_NE[1]) < 10.0)] = (20, 20, 240)
    return img, dem


def _red(image: np.ndarray) -> np.ndarray:
    i = image.astype(int)
    return i[..., 0] - (i[..., 1] + i[..., 2]) // 2 > 70


def _centroid(mask: np.ndarray) -> np.ndarray:
    v, u = np.nonzero(mask)
    return np.array([u.mean(), v.mean()])


def test_peak_appears_where_projected(hill):
    img, dem = hill
    cam = PinholeCamera.from_hfov(320, 240, 60.0)
    pos, R_nb, m = np.array([-120.0, -10.0, -160.0]), euler_to_dcm(np.radians([0.0, 0.0, -5.0])), mount(-45.0)
    f = render(cam, m, pos, R_nb, img, dem, want_ground_points=True, options=NO_HAZE)
    top = np.r_[PEAK_NE, -PEAK_H]
    uv, z = project_points(cam, *camera_pose_ned(pos, R_nb, m), top[None])
    red = _red(f.image)
    assert red.sum() > 20
    # The disc drapes over the summit: seen obliquely its near half shows more than its far
    # half, so its centroid sits a little below the top; left-right it is symmetric.
    assert red[int(round(uv[0, 1])), int(round(uv[0, 0]))]
    cu, cv_ = _centroid(red)
    assert abs(cu - uv[0, 0]) < 1.0 and 0.0 < cv_ - uv[0, 1] < 6.0
    # The ground point at the projected pixel is the hill top (its height, its place).
    p = f.ground_points_ned_m[int(round(uv[0, 1])), int(round(uv[0, 0]))]
    assert -p[2] == pytest.approx(PEAK_H, abs=0.5)
    assert np.hypot(*(p[:2] - PEAK_NE)) < 2.0
    # Every pixel's ground point lies on its ray: exact at the ray-cast pixels, interpolated
    # inside smooth cells (a fraction of a pixel, more only along the hill's silhouette).
    pts = f.ground_points_ned_m
    v, u = np.nonzero(np.isfinite(pts).all(axis=-1))
    back, _ = project_points(cam, *camera_pose_ned(pos, R_nb, m), pts[v, u])
    err = np.hypot(back[:, 0] - u, back[:, 1] - v)
    assert np.median(err) < 0.1 and np.percentile(err, 99) < 1.5
    # Over flat ground (no DEM) the disc appears elsewhere: the relief is what moved it.
    flat = render(cam, m, pos, R_nb, img, options=NO_HAZE)
    red_flat = _red(flat.image)
    assert np.hypot(*(_centroid(red_flat) - uv[0])) > 10.0


def test_hill_hides_what_is_behind_it(hill):
    """Grazing view from 20 m: the blue patch 110 m behind the 80 m hill is hidden; without
    the DEM it is seen where projected."""
    img, dem = hill
    cam = PinholeCamera.from_hfov(320, 240, 60.0)
    pos, R_nb, m = np.array([-150.0, -30.0, -20.0]), np.eye(3), mount(-2.0)
    C, R_nc = camera_pose_ned(pos, R_nb, m)
    uv, z = project_points(cam, C, R_nc, np.r_[BEHIND_NE, 0.0][None])
    u, v = (int(round(x)) for x in uv[0])
    assert z[0] > 0 and 5 < u < cam.width_px - 5 and 5 < v < cam.height_px - 5
    win = (slice(v - 4, v + 5), slice(u - 8, u + 9))

    def blue(frame):
        i = frame.image.astype(int)  # (the sky is blue too, but not this saturated)
        return i[..., 2] - (i[..., 0] + i[..., 1]) // 2 > 100

    flat = render(cam, m, pos, R_nb, img, options=NO_HAZE)
    assert blue(flat)[win].sum() >= 5
    f = render(cam, m, pos, R_nb, img, dem, want_ground_points=True, options=NO_HAZE)
    assert not blue(f).any()
    # What is seen there instead is the hill, nearer than the patch.
    p = f.ground_points_ned_m[v, u]
    assert -p[2] > 5.0 and p[0] < BEHIND_NE[0] - 40.0


def test_off_map_is_masked_black_and_counted(nadir):
    """Nadir, image right = east: the map covers east < 0 only, so the right half is no-data."""
    img = raster(textured(200)[:, :100].copy(), 1.0, (0.0, -50.0))
    cam = PinholeCamera.from_hfov(160, 120, 60.0)  # cx = 79.5
    f = render(cam, nadir, np.array([0.0, 0.0, -50.0]), np.eye(3), img, options=NO_HAZE)
    assert f.offmap_fraction == pytest.approx(0.5, abs=1.5 / cam.width_px)
    assert f.valid[:, :79].all() and not f.valid[:, 81:].any()
    assert not f.sky.any()
    assert not f.image[~f.valid].any() and (f.image[f.valid] > 0).any()


def test_off_map_share_looking_forward():
    """Forward view with sky: offmap_fraction is the share of pixels whose ground point lies
    beyond the map's north edge (sky is not off-map)."""
    img = raster(textured(256), 1.0, (72.0, 0.0))  # north edge at 200 m
    cam = PinholeCamera.from_hfov(200, 150, 70.0)
    f = render(cam, mount(-15.0), np.array([0.0, 5.0, -40.0]), np.eye(3), img, want_ground_points=True)
    assert 0.1 < f.sky.mean() < 0.6
    beyond = ~f.sky & (f.ground_points_ned_m[..., 0] > 200.0)
    assert 0.05 < beyond.mean() < 0.5
    assert abs(f.offmap_fraction - beyond.mean()) < 0.01
    assert not f.image[beyond & ~f.valid].any()


def _quad(led_on, pos=(6.0, 4.0, -60.0)):
    # On top of the body (FRD: z up is negative), seen by a camera above.
    leds = ((0.12, 0.1, -0.1), (0.12, -0.1, -0.1), (-0.12, 0.1, -0.1), (-0.12, -0.1, -0.1))
    return VehicleAppearance("q1", np.array(pos), euler_to_dcm(np.radians([0.0, 0.0, 30.0])), shape="quad",
                             size_m=1.2, colour_rgb=(200, 60, 40), led_positions_b_m=leds,
                             led_colours=((255, 0, 0), (0, 255, 0), (0, 0, 255), (255, 255, 255)),
                             led_on=tuple(led_on), led_radius_m=0.05)


def test_vehicle_truth_leds_and_regions(nadir):
    img = raster(textured(256), 1.0)
    cam = PinholeCamera.from_hfov(320, 240, 70.0)
    pos, R = np.array([0.0, 0.0, -100.0]), np.eye(3)
    on = render(cam, nadir, pos, R, img, vehicles=[_quad([True] * 4)], options=NO_HAZE)
    off = render(cam, nadir, pos, R, img, vehicles=[_quad([False] * 4)], options=NO_HAZE)
    (t,) = on.vehicles
    assert t.visible and all(t.led_in_frame)
    u0, v0, u1, v1 = t.bbox_px
    assert u0 < t.centre_px[0] < u1 and v0 < t.centre_px[1] < v1
    assert t.range_m == pytest.approx(np.linalg.norm(np.array([6.0, 4.0, 40.0])))
    diff = np.abs(on.image.astype(int) - off.image.astype(int)).max(axis=-1)
    for lu, lv in t.led_px:
        assert diff[int(round(lv)), int(round(lu))] > 60
    # Nothing changes away from the LEDs.
    vv, uu = np.mgrid[0:cam.height_px, 0:cam.width_px]
    near = np.zeros_like(diff, bool)
    for lu, lv in t.led_px:
        near |= np.hypot(uu - lu, vv - lv) < 8
    assert not diff[~near].any()
    # A region of interest is the same pixels as the crop of the full frame.
    roi = (int(u0) - 20, int(v0) - 15, int(u1) + 25, int(v1) + 10)
    part = render(cam, nadir, pos, R, img, vehicles=[_quad([True] * 4)], roi=roi, options=NO_HAZE)
    assert part.roi == roi
    crop = on.image[roi[1]:roi[3], roi[0]:roi[2]]
    assert part.image.shape == crop.shape
    d = np.abs(part.image.astype(int) - crop.astype(int))
    assert d.max() <= 2 and d.mean() < 0.02
    assert np.array_equal(part.valid, on.valid[roi[1]:roi[3], roi[0]:roi[2]])
    assert np.allclose(part.vehicles[0].bbox_px, t.bbox_px)
    # The same with the vehicles as one tuple, as a camera passes a frame's regions (the
    # projection is made once for the frame and reused): the same pixels and truths, and a
    # vehicle moved in a new tuple is drawn where it now is.
    frame_vehicles = (_quad([True] * 4),)
    whole = render(cam, nadir, pos, R, img, vehicles=frame_vehicles, options=NO_HAZE)
    part2 = render(cam, nadir, pos, R, img, vehicles=frame_vehicles, roi=roi, options=NO_HAZE)
    assert np.array_equal(whole.image, on.image) and np.array_equal(part2.image, part.image)
    a, b = part2.vehicles[0], whole.vehicles[0]
    assert a.bbox_px == b.bbox_px and np.array_equal(a.centre_px, b.centre_px) and np.array_equal(a.led_px, b.led_px)
    moved = render(cam, nadir, pos, R, img, vehicles=(_quad([True] * 4, pos=(16.0, 4.0, -60.0)),), options=NO_HAZE)
    assert np.hypot(*(moved.vehicles[0].centre_px - t.centre_px)) > 20  # 10 m north at 40 m: ~57 px


def test_vehicle_behind_the_camera_or_hill_is_not_drawn(hill):
    img, dem = hill
    cam = PinholeCamera.from_hfov(320, 240, 60.0)
    pos, m = np.array([-150.0, -30.0, -20.0]), mount(-2.0)
    hidden = _quad([True] * 4, pos=(BEHIND_NE[0], BEHIND_NE[1], -3.0))  # behind the hill
    behind = _quad([True] * 4, pos=(-200.0, -30.0, -20.0))                # behind the camera
    base = render(cam, m, pos, np.eye(3), img, dem, options=NO_HAZE)
    f = render(cam, m, pos, np.eye(3), img, dem, vehicles=[hidden, behind], options=NO_HAZE)
    assert not any(t.visible for t in f.vehicles)
    assert np.array_equal(f.image, base.image)


def test_noise_is_seeded(nadir):
    img = raster(textured(256), 1.0)
    cam = PinholeCamera.from_hfov(160, 120, 60.0)
    args = (cam, nadir, np.array([0.0, 0.0, -80.0]), np.eye(3), img)
    opts = RenderOptions(noise_std=3.0, haze_visibility_m=None)
    a = render(*args, rng=np.random.default_rng(7), options=opts).image
    b = render(*args, rng=np.random.default_rng(7), options=opts).image
    c = render(*args, rng=np.random.default_rng(8), options=opts).image
    clean = render(*args, options=opts).image  # no generator: no noise
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    n = a.astype(float) - clean
    assert abs(n.mean()) < 0.1 and n.std() == pytest.approx(3.0, rel=0.05)
    # Consecutive frames from one generator get different noise.
    rng = np.random.default_rng(7)
    f1, f2 = (render(*args, rng=rng, options=opts).image for _ in range(2))
    assert np.corrcoef((f1.astype(float) - clean).ravel(), (f2.astype(float) - clean).ravel())[0, 1] < 0.05


def test_noise_bands_are_independent_draws():
    """Rows are noised in bands, each a window of a small fixed field at its own seeded offset:
    every band has the configured statistics, and neighbouring bands are not copies."""
    from testbench.sensors.camera.effects import _NOISE_BAND_PX, add_noise

    h = 3 * _NOISE_BAND_PX
    img = add_noise(np.full((h, 400, 3), 100, np.uint8), 0.0, 3.0, np.random.default_rng(3))
    n = img.astype(float) - 100.0
    bands = [n[i * _NOISE_BAND_PX:(i + 1) * _NOISE_BAND_PX].ravel() for i in range(3)]
    for b in bands:
        assert abs(b.mean()) < 0.1 and b.std() == pytest.approx(3.0, rel=0.05)
    assert abs(np.corrcoef(bands[0], bands[1])[0, 1]) < 0.05
    assert abs(np.corrcoef(bands[1], bands[2])[0, 1]) < 0.05


@pytest.mark.parametrize("pitch_deg", [-90.0, -50.0])
def test_fine_checkerboard_from_far_is_flat_grey(pitch_deg):
    """1-map-pixel checkerboard seen with ~8 map pixels per image pixel: the mip level chosen
    averages it to mid grey (low variance); forcing level 0 (lod_bias -10) aliases (moire)."""
    n = 2048
    rows, cols = np.mgrid[0:n, 0:n]
    board = np.where((rows + cols) % 2 == 0, 235, 20).astype(np.uint8)
    img = raster(np.repeat(board[..., None], 3, axis=2), 0.5)
    cam = PinholeCamera.from_hfov(200, 150, 60.0)
    args = (cam, mount(pitch_deg), np.array([0.0, 0.0, -700.0 if pitch_deg == -90.0 else -400.0]), np.eye(3), img)
    f = render(*args, options=NO_HAZE)
    g = f.image[f.valid][:, 1].astype(float)
    assert g.size > 0.5 * f.valid.size
    assert g.mean() == pytest.approx(127.5, abs=3.0) and g.std() < 3.0
    aliased = render(*args, options=RenderOptions(haze_visibility_m=None, lod_bias=-10.0))
    assert aliased.image[aliased.valid][:, 1].astype(float).std() > 20.0


def _anchor_quad(pos, lit=True):
    """The swarm quad's LED layout: a top anchor 0.20 m above the hub, four arm LEDs (off)."""
    leds = ((0.0, 0.0, -0.20), (0.165, 0.165, -0.03), (0.165, -0.165, -0.03), (-0.165, -0.165, -0.03), (-0.165, 0.165, -0.03))
    return VehicleAppearance("q1", np.array(pos, float), np.eye(3), shape="quad", size_m=0.5, colour_rgb=(40, 40, 45),
                             led_positions_b_m=leds, led_colours=((40, 255, 40),) + ((255, 40, 40),) * 4,
                             led_on=(lit, False, False, False, False), led_radius_m=0.03)


def _green_centroid(image, near_uv, radius_px=8):
    """Centroid (u, v) of the saturated green pixels within radius_px of near_uv, or None."""
    import cv2

    hsv = cv2.cvtColor(image, cv2.COLOR_RGB2HSV)
    green = (np.abs(hsv[..., 0].astype(int) * 2 - 120) < 30) & (hsv[..., 1] > 90) & (hsv[..., 2] > 200)
    vv, uu = np.mgrid[0:image.shape[0], 0:image.shape[1]]
    sel = green & (np.hypot(uu - near_uv[0], vv - near_uv[1]) < radius_px)
    return None if not sel.any() else np.array([uu[sel].mean(), vv[sel].mean()])


@pytest.mark.parametrize("range_m", [60.0, 150.0])
def test_a_lit_leds_glow_is_not_cut_by_its_own_hub(range_m):
    """Seen from level, the top anchor's glow is centred on the anchor: the glow is light spread
    by the optics, and a nearer face of the hub does not hide the half of it below the anchor
    (drawn as a disc in depth order it did: the centroid sat 2.4 px above the anchor)."""
    img = raster(textured(256), 1.0)
    cam = PinholeCamera.from_hfov(1920, 1080, 120.0)
    pos = np.array([0.0, 0.0, -60.0])
    f = render(cam, mount(0.0), pos, np.eye(3), img, vehicles=[_anchor_quad(pos + [range_m, 0.0, 0.0])], options=NO_HAZE)
    anchor_uv = f.vehicles[0].led_px[0]
    c = _green_centroid(f.image, anchor_uv)
    assert c is not None
    assert np.hypot(*(c - anchor_uv)) < 0.35  # px


def test_a_lit_led_behind_its_hub_is_not_drawn(nadir):
    """Seen from straight below, the top anchor is behind the hub: no glow at all."""
    img = raster(textured(256), 1.0)
    cam = PinholeCamera.from_hfov(640, 480, 60.0)
    pos = np.array([0.0, 0.0, -40.0])
    above = mount(90.0)  # looking straight up
    lit = render(cam, above, pos, np.eye(3), img, vehicles=[_anchor_quad(pos + [0.0, 0.0, -15.0])], options=NO_HAZE)
    dark = render(cam, above, pos, np.eye(3), img, vehicles=[_anchor_quad(pos + [0.0, 0.0, -15.0], lit=False)], options=NO_HAZE)
    assert lit.vehicles[0].visible
    assert _green_centroid(lit.image, lit.vehicles[0].led_px[0]) is None
    # At most the edge of its core shows past the hub, nothing of a glow.
    changed = np.abs(lit.image.astype(int) - dark.image.astype(int)).max(axis=-1) > 0
    assert changed.sum() <= 4
