"""Obstacles in the camera: drawn over the ground, out of the valid mask, hiding vehicles."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import mount, raster, textured

from testbench.core.camera_geometry import PinholeCamera, camera_pose_ned
from testbench.core.obstacles import Obstacle
from testbench.core.rotations import euler_to_dcm
from testbench.sensors.camera import RenderOptions, VehicleAppearance, project_points, render

NO_HAZE = RenderOptions(haze_visibility_m=None)
CAM = PinholeCamera.from_hfov(320, 240, 90.0)
LEVEL = mount(0.0)  # looking north, level
POS = np.array([0.0, 0.0, -30.0])  # 30 m above flat ground
# A building 60-80 m north, 20 m wide, 50 m tall: it stands across the line of sight ahead.
TOWER = Obstacle((60.0, -10.0, -50.0), (80.0, 10.0, 0.0), "tower")


def _quad(pos):
    return VehicleAppearance("q1", np.array(pos, float), np.eye(3), shape="quad", size_m=1.2,
                             colour_rgb=(200, 60, 40), led_positions_b_m=((0.0, 0.0, -0.1),),
                             led_colours=((255, 0, 0),), led_on=(True,), led_radius_m=0.2)


@pytest.fixture(scope="module")
def ground():
    return raster(textured(512, seed=2), 1.0, (150.0, 0.0))


def test_obstacle_covers_its_projection_and_leaves_the_valid_mask(ground):
    bare = render(CAM, LEVEL, POS, np.eye(3), ground, options=NO_HAZE)
    f = render(CAM, LEVEL, POS, np.eye(3), ground, options=NO_HAZE, obstacles=(TOWER,))
    # The south wall (60 m ahead): its centre and two points near its corners.
    C, R_nc = camera_pose_ned(POS, np.eye(3), LEVEL)
    uv, _ = project_points(CAM, C, R_nc, np.array([[60.0, 0.0, -25.0], [60.0, -9.0, -2.0], [60.0, 9.0, -48.0]]))
    for u, v in np.round(uv).astype(int):
        px = f.image[v, u].astype(int)
        assert np.ptp(px) < 15 and 60 < px.mean() < 200  # flat grey wall
        assert not f.valid[v, u] and not f.sky[v, u]
    covered = (bare.valid | bare.sky) & ~(f.valid | f.sky)  # ground or sky before, the wall now
    assert covered.sum() > 500 and not (f.valid & ~bare.valid).any() and not (f.sky & ~bare.sky).any()
    # Away from the wall the frame is the bare one.
    wall = np.zeros_like(covered)
    lo, hi = np.floor(uv.min(axis=0)).astype(int) - 40, np.ceil(uv.max(axis=0)).astype(int) + 40
    wall[max(lo[1], 0):hi[1], max(lo[0], 0):hi[0]] = True
    assert np.array_equal(f.image[~wall], bare.image[~wall])
    # The wall's pixels are not "off the map": over a map that covers the whole view none are.
    assert f.offmap_fraction <= bare.offmap_fraction
    big = raster(np.full((4000, 4000, 3), 90, np.uint8), 1.0)
    short = RenderOptions(haze_visibility_m=None, far_m=1500.0)  # the map's edge beyond the far plane
    assert render(CAM, LEVEL, POS, np.eye(3), big, options=short, obstacles=(TOWER,)).offmap_fraction == 0.0


def test_obstacle_hides_the_vehicle_behind_it_not_the_one_in_front(ground):
    behind, front = _quad((100.0, 0.0, -30.0)), _quad((40.0, 0.0, -30.0))
    f = render(CAM, LEVEL, POS, np.eye(3), ground, vehicles=(behind, front), options=NO_HAZE, obstacles=(TOWER,))
    assert [t.visible for t in f.vehicles] == [False, True]
    open_view = render(CAM, LEVEL, POS, np.eye(3), ground, vehicles=(behind,), options=NO_HAZE)
    assert open_view.vehicles[0].visible
    # The one in front is drawn over the wall: its LED core is bright there.
    u, v = np.round(f.vehicles[1].led_px[0]).astype(int)
    assert f.image[v, u].astype(int).max() > 230


def test_a_wall_next_to_the_camera_fills_the_view(ground):
    """The camera 2 m from the wall: the wall reaches behind and beside the camera (clipped at
    the near plane and just outside the view), and covers the frame."""
    pos = np.array([58.0, 0.0, -20.0])
    f = render(CAM, LEVEL, pos, np.eye(3), ground, options=NO_HAZE, obstacles=(TOWER,))
    assert (~f.valid & ~f.sky).mean() > 0.98


def test_regions_match_the_full_frame(ground):
    """A region of interest draws the wall on the same pixels as the full frame."""
    roi = (100, 60, 220, 180)
    whole = render(CAM, LEVEL, POS, np.eye(3), ground, options=NO_HAZE, obstacles=(TOWER,))
    part = render(CAM, LEVEL, POS, np.eye(3), ground, roi=roi, options=NO_HAZE, obstacles=(TOWER,))
    window = np.s_[roi[1]:roi[3], roi[0]:roi[2]]
    wall = ~(whole.valid | whole.sky)[window] & (ground_or_sky := render(CAM, LEVEL, POS, np.eye(3), ground,
                                                                          options=NO_HAZE)).valid[window]
    assert wall.sum() > 1000 and np.array_equal(~(part.valid | part.sky) & ground_or_sky.valid[window], wall)
    assert np.abs(part.image[wall].astype(int) - whole.image[window][wall].astype(int)).max() <= 2


def test_yawed_camera_sees_the_east_wall():
    """Seen from the north-east above the roof, the roof and two walls show, each its own
    shade of the one grey (the sun from the south-east lights them differently)."""
    img = raster(np.full((400, 400, 3), 90, np.uint8), 1.0, (70.0, 0.0))
    pos = np.array([120.0, 60.0, -90.0])
    R_nb = euler_to_dcm(np.radians([0.0, 0.0, -140.0]))  # facing south-west, towards the box
    f = render(CAM, mount(-35.0), pos, R_nb, img, options=NO_HAZE, obstacles=(TOWER,))
    covered = ~f.valid & ~f.sky
    shades = {tuple(px) for px in f.image[covered].reshape(-1, 3)[::7]}
    assert covered.sum() > 300 and len(shades) >= 3


def test_a_wall_seen_through_a_wide_distorting_lens(ground):
    """Through a barrel lens: a wall filling the view still fills it, and one ahead covers
    its outline as the lens projects it, and nothing beside it."""
    from dataclasses import replace

    cam = replace(PinholeCamera.from_hfov(320, 240, 100.0), dist=(-0.05, 0.0, 0.0, 0.0, 0.0))
    near = render(cam, LEVEL, np.array([58.0, 0.0, -20.0]), np.eye(3), ground, options=NO_HAZE, obstacles=(TOWER,))
    assert (~near.valid & ~near.sky).mean() > 0.98
    f = render(cam, LEVEL, POS, np.eye(3), ground, options=NO_HAZE, obstacles=(TOWER,))
    bare = render(cam, LEVEL, POS, np.eye(3), ground, options=NO_HAZE)
    covered = (bare.valid | bare.sky) & ~(f.valid | f.sky)
    C, R_nc = camera_pose_ned(POS, np.eye(3), LEVEL)
    inside = np.array([[60.0, e, -d] for e in (-8.0, 0.0, 8.0) for d in (2.0, 25.0, 48.0)])
    uv, _ = project_points(cam, C, R_nc, inside)
    for u, v in np.round(uv).astype(int):
        assert covered[v, u]
    outside = np.array([[60.0, e, -d] for e in (-14.0, 14.0) for d in (5.0, 25.0)] + [[60.0, 0.0, -56.0]])
    uv, _ = project_points(cam, C, R_nc, outside)
    for u, v in np.round(uv).astype(int):
        assert not covered[v, u]


def test_a_wall_beside_the_view_does_not_fold_back_into_it(ground):
    """The wall's near edge 2 m to the left of a barrel-lens camera 2 m from it: the wall fills
    the left of the frame, and its corners beyond the view (cut before the lens maps them) do
    not fold back into the right."""
    from dataclasses import replace

    cam = replace(PinholeCamera.from_hfov(320, 240, 100.0), dist=(-0.05, 0.0, 0.0, 0.0, 0.0))
    f = render(cam, LEVEL, np.array([58.0, 12.0, -20.0]), np.eye(3), ground, options=NO_HAZE, obstacles=(TOWER,))
    covered = ~(f.valid | f.sky)
    assert covered[:, :100].mean() > 0.95
    assert covered[:, 200:].mean() < 0.05


def test_a_ridge_hides_the_foot_of_a_tower_behind_it():
    """Over relief the terrain in front of a box hides what it covers: from 40 m up, a 35 m
    ridge 40 m ahead hides a tower 80 m ahead below about 30 m; its top shows."""
    north = 150.0 - np.arange(300)[:, None] - 0.5  # row centres, north m (the raster runs south)
    dem_h = 35.0 * np.exp(-((north - 40.0) ** 2) / (2 * 6.0**2)) * np.ones((1, 300))
    dem = raster(dem_h.astype(np.float32), 1.0, (0.0, 0.0))
    img = raster(textured(300, seed=5), 1.0, (0.0, 0.0))
    tower = Obstacle((80.0, -10.0, -70.0), (90.0, 10.0, 0.0), "tower")
    pos = np.array([0.0, 0.0, -40.0])
    C, R_nc = camera_pose_ned(pos, np.eye(3), LEVEL)
    (top, foot), _ = project_points(CAM, C, R_nc, np.array([[80.0, 0.0, -60.0], [80.0, 0.0, -15.0]]))
    (ut, vt), (uf, vf) = np.round(top).astype(int), np.round(foot).astype(int)
    f = render(CAM, LEVEL, pos, np.eye(3), img, dem, options=NO_HAZE, obstacles=(tower,))
    assert not (f.valid | f.sky)[vt, ut]
    assert f.valid[vf, uf]  # the ridge, not the tower
    # Without the ridge the foot is the tower's.
    flat = raster(np.zeros((300, 300), np.float32), 1.0, (0.0, 0.0))
    g = render(CAM, LEVEL, pos, np.eye(3), img, flat, options=NO_HAZE, obstacles=(tower,))
    assert not (g.valid | g.sky)[vf, uf]
