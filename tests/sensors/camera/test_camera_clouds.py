"""Clouds in the camera (sensors/camera/clouds.py): where each ray meets the sheet, what it
shows there, and what it hides."""

from __future__ import annotations

import numpy as np
from conftest import mount, raster, textured

from testbench.core.camera_geometry import PinholeCamera, camera_pose_ned
from testbench.core.rotations import euler_to_dcm
from testbench.sensors.camera import RenderOptions, VehicleAppearance, render
from testbench.sensors.camera.clouds import TOP_RGB
from testbench.sensors.camera.lens import undistort_pixels
from testbench.world.clouds import CloudLayer

NO_HAZE = RenderOptions(haze_visibility_m=None)
CAM = PinholeCamera.from_hfov(480, 360, 90.0, (-0.12, 0.03, 0.0, 0.0, 0.0))
POS = np.array([0.0, 0.0, -800.0])  # 800 m above flat ground at the origin's altitude


def _clouds(coverage, t_s=0.0, base_m=500.0, seed=4, cell_m=150.0):
    return CloudLayer(base_m, coverage, (), cell_m, 1.0, (0.0, 0.0), np.random.default_rng(seed)).at(t_s)


def _ground():
    return raster(textured(512, seed=1), 4.0)


def test_a_clear_sky_leaves_the_frame_as_it_was():
    bare = render(CAM, mount(-90.0), POS, np.eye(3), _ground(), options=NO_HAZE)
    clear = render(CAM, mount(-90.0), POS, np.eye(3), _ground(), options=NO_HAZE, clouds=_clouds(0.0))
    assert np.array_equal(bare.image, clear.image) and clear.cloud_fraction == 0.0


def test_an_overcast_sheet_shows_nothing_but_cloud_tops():
    f = render(CAM, mount(-90.0), POS, np.eye(3), _ground(), options=NO_HAZE, clouds=_clouds(1.0))
    assert f.cloud_fraction == 1.0
    assert np.abs(f.image.astype(float) - TOP_RGB).max() <= 1.0
    assert f.valid.all()  # the camera cannot tell: nothing marks the pixels as cloud


def test_each_ray_takes_the_cloud_where_it_meets_the_sheet():
    """Over black ground, an oblique and rolled camera with a distorting lens: the alpha read
    back from each pixel is the density at the point where that pixel's ray crosses the sheet
    (the renderer samples every 8 px, so away from the clouds' edges)."""
    black = raster(np.zeros((600, 600, 3), np.uint8), 8.0)
    R_nb = euler_to_dcm(np.radians([8.0, -5.0, 30.0]))
    view = _clouds(0.45, cell_m=400.0)
    f = render(CAM, mount(-60.0), POS, R_nb, black, options=NO_HAZE, clouds=view)
    C, R_nc = camera_pose_ned(POS, R_nb, mount(-60.0))
    v, u = np.mgrid[5:CAM.height_px:11, 5:CAM.width_px:11]
    x, y = undistort_pixels(CAM, u.astype(float), v.astype(float))
    d = np.stack([x, y, np.ones_like(x)], axis=-1) @ R_nc.T
    t = (view.down_m - C[2]) / d[..., 2]
    north, east = C[0] + t * d[..., 0], C[1] + t * d[..., 1]
    density = view.density(north, east)
    seen = f.image[v, u, 1].astype(float) / (TOP_RGB[1] * 0.8)  # alpha x shade; fringes 0.8
    # Firm: clear or opaque over 25 m around (the sampling's 8 px span up to 17 m of the sheet).
    around = [view.density(north + dn, east + de) for dn, de in ((25, 0), (-25, 0), (0, 25), (0, -25))]
    firm = np.all([a == density for a in around], axis=0) & ((density == 0.0) | (density == 1.0))
    assert firm.sum() > 200 and 0.2 < density[firm].mean() < 0.8
    assert np.all((seen[firm] > 0.5) == (density[firm] == 1.0))
    assert abs(f.cloud_fraction - float(np.mean(density >= 0.5))) < 0.05


def test_from_below_the_sheet_hides_the_sky_not_the_ground():
    level = mount(0.0)  # looking north, level, 300 m up: the sheet 500 m up fills the upper half
    low = np.array([0.0, 0.0, -300.0])
    bare = render(CAM, level, low, np.eye(3), _ground(), options=NO_HAZE)
    f = render(CAM, level, low, np.eye(3), _ground(), options=NO_HAZE, clouds=_clouds(1.0))
    assert np.array_equal(f.image[bare.valid], bare.image[bare.valid])
    top = f.image[: CAM.height_px // 4].reshape(-1, 3).mean(axis=0)
    assert np.all(top < TOP_RGB - 50) and not np.array_equal(f.image[bare.sky], bare.image[bare.sky])
    assert f.cloud_fraction == 0.0  # the share of the ground hidden: none of it


def _quad(pos):
    return VehicleAppearance("q1", np.array(pos, float), np.eye(3), shape="quad", size_m=4.0,
                             colour_rgb=(200, 60, 40), led_positions_b_m=((0.0, 0.0, -0.1),),
                             led_colours=((255, 0, 0),), led_on=(True,), led_radius_m=0.5)


def test_a_vehicle_beyond_the_cloud_is_hidden_one_before_it_is_not():
    below, above = _quad((0.0, 0.0, -200.0)), _quad((0.0, 0.0, -650.0))  # the sheet at 500 m up
    f = render(CAM, mount(-90.0), POS, np.eye(3), _ground(), vehicles=(below, above), options=NO_HAZE,
               clouds=_clouds(1.0))
    assert [t.visible for t in f.vehicles] == [False, True]
    clear = render(CAM, mount(-90.0), POS, np.eye(3), _ground(), vehicles=(below, above), options=NO_HAZE,
                   clouds=_clouds(0.0))
    assert [t.visible for t in clear.vehicles] == [True, True]


def test_a_clouded_frame_does_not_depend_on_where_buffers_land():
    """The blend and the samplings are OpenCV's, some of whose vector loops round their head and
    tail apart by the buffer's alignment (tests/integration/test_determinism.py): the same
    frame, rendered with the heap shifted between calls, must come out bit for bit the same."""
    cam = PinholeCamera.from_hfov(333, 251, 100.0)
    view = CloudLayer(500.0, 0.5, (), 150.0, 0.9, (0.0, 0.0), np.random.default_rng(2),
                      sun_ned=(0.4, -0.3, -0.87), shadow_light=0.35).at(3.0)  # and their shadows
    rng = np.random.default_rng(0)
    results, held = set(), []
    for _ in range(40):
        held.append([np.empty(int(rng.integers(1, 4096)) * 16, np.uint8) for _ in range(int(rng.integers(1, 8)))])
        if len(held) > 12:
            held.pop(int(rng.integers(0, len(held))))
        f = render(cam, mount(-70.0), POS, np.eye(3), _ground(), options=NO_HAZE, clouds=view)
        results.add(f.image.tobytes())
    assert len(results) == 1 and f.cloud_fraction > 0.1 and f.shadow_fraction > 0.05


def test_the_clouds_shadows_darken_the_ground_where_the_sun_is_cut():
    """Over uniform grey ground, a nadir camera: each ground pixel is darkened by the light its
    ground point gets (world.clouds.CloudView.ground_light) through the frames' gamma, where
    that point's ray to the sun crosses a cloud, and the ground under a clear sun is as it was."""
    grey = raster(np.full((600, 600, 3), 160, np.uint8), 8.0)
    layer = CloudLayer(500.0, 0.35, (), 700.0, 1.0, (0.0, 0.0), np.random.default_rng(4),
                       sun_ned=(0.3, 0.4, -0.87), shadow_light=0.3)
    view = layer.at(0.0)
    f = render(CAM, mount(-90.0), POS, np.eye(3), grey, options=NO_HAZE, clouds=view)
    C, R_nc = camera_pose_ned(POS, np.eye(3), mount(-90.0))
    v, u = np.mgrid[5:CAM.height_px:11, 5:CAM.width_px:11]
    x, y = undistort_pixels(CAM, u.astype(float), v.astype(float))
    d = np.stack([x, y, np.ones_like(x)], axis=-1) @ R_nc.T
    t = (0.0 - C[2]) / d[..., 2]  # to the ground
    g_n, g_e = C[0] + t * d[..., 0], C[1] + t * d[..., 1]
    light = view.ground_light(g_n, g_e, np.zeros_like(g_n))
    t_sheet = (view.down_m - C[2]) / d[..., 2]
    s_n, s_e = C[0] + t_sheet * d[..., 0], C[1] + t_sheet * d[..., 1]
    in_cloud = np.max([view.density(s_n + dn, s_e + de) for dn, de in ((0, 0), (15, 15), (-15, -15), (15, -15), (-15, 15))],
                      axis=0)  # the sheet 300 m from the camera: 8 px span 10 m of it
    # Firm: clear sheet in front, and the same light 60 m around (the 8 px sampling spans 27 m
    # of ground under the camera, twice that at the frame's edges).
    around = [view.ground_light(g_n + dn, g_e + de, np.zeros_like(g_n))
              for dn, de in ((60, 0), (-60, 0), (0, 60), (0, -60), (42, 42), (-42, -42), (42, -42), (-42, 42))]
    firm = (in_cloud == 0.0) & np.all([a == light for a in around], axis=0)
    shaded, lit = firm & (light < 0.31), firm & (light > 0.99)
    assert shaded.sum() > 25 and lit.sum() > 100
    seen = f.image[v, u].astype(float).mean(axis=-1)
    # (all but the odd sample next to an edge the 8 px interpolation still reaches)
    assert np.mean(np.abs(seen[lit] - 160.0) <= 1.0) > 0.97
    assert np.mean(np.abs(seen[shaded] - 160.0 * 0.3 ** (1.0 / 2.2)) <= 1.5) > 0.9
    # The truth share of the ground in view that shows in shadow, as the samples read it.
    assert abs(f.shadow_fraction - float(np.mean((light <= 0.65) & (in_cloud < 0.5)))) < 0.05
    assert f.shadow_fraction > 0.05
    # Without a sun the same clouds cast nothing.
    dark = CloudLayer(500.0, 0.35, (), 700.0, 1.0, (0.0, 0.0), np.random.default_rng(4)).at(0.0)
    g = render(CAM, mount(-90.0), POS, np.eye(3), grey, options=NO_HAZE, clouds=dark).image[v, u].astype(float)
    assert np.allclose(g.mean(axis=-1)[firm], 160.0, atol=1.0)
    assert render(CAM, mount(-90.0), POS, np.eye(3), grey, options=NO_HAZE, clouds=dark).shadow_fraction == 0.0
