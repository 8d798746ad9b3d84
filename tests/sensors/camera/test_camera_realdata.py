"""Frames over real imagery (TESTBENCH_DATA): NAIP North Dakota 2018 (5 m) and McMillan (0.81 m)
through MapSource.read_local windows, at several altitudes and attitudes, and at a map edge."""

from __future__ import annotations

import math

import numpy as np
import pytest
import rasterio
from conftest import mount
from pyproj import Transformer

from testbench.core.camera_geometry import PinholeCamera
from testbench.core.interfaces import GeodeticOrigin
from testbench.core.rotations import euler_to_dcm
from testbench.sensors.camera import RenderOptions, render
from testbench.world.imagery import MapSource

pytestmark = pytest.mark.realdata

NAIP_2018 = ("naip_nd", "m_4709963_se_14_1_20180716.tif")
MCMILLAN = ("naip_mcmillan", "mcmillan_naip2016_utm10n.tif")


def _centre_origin(path) -> GeodeticOrigin:
    with rasterio.open(path) as ds:
        x, y = (ds.bounds.left + ds.bounds.right) / 2, (ds.bounds.bottom + ds.bounds.top) / 2
        lon, lat = Transformer.from_crs(ds.crs, "EPSG:4326", always_xy=True).transform(x, y)
    return GeodeticOrigin(math.radians(lat), math.radians(lon), 0.0)


def _window(src: MapSource, centre_ne, half_m: float, gsd_m: float):
    n, e = centre_ne
    return src.read_local(n - half_m, n + half_m, e - half_m, e + half_m, gsd_m)


@pytest.mark.parametrize("which, alt_m, gsd_m, pitch_deg, rpy_deg", [
    (NAIP_2018, 800.0, 2.5, -90.0, (2.0, -1.0, 30.0)),
    (NAIP_2018, 400.0, 2.5, -60.0, (0.0, 3.0, -120.0)),
    (MCMILLAN, 150.0, 0.5, -90.0, (-3.0, 2.0, 75.0)),
    (MCMILLAN, 80.0, 0.5, -45.0, (1.0, 0.0, 200.0)),
])
def test_frames_over_real_imagery(realdata, which, alt_m, gsd_m, pitch_deg, rpy_deg):
    path = realdata.joinpath(*which)
    cam = PinholeCamera.from_hfov(320, 180, 90.0, (-0.05, 0.01, 0.0, 0.0, 0.0))
    pos = np.array([30.0, -40.0, -alt_m])
    with MapSource(path, _centre_origin(path)) as src:
        win = _window(src, pos[:2], 4.0 * alt_m, gsd_m)
        f = render(cam, mount(pitch_deg), pos, euler_to_dcm(np.radians(rpy_deg)), win,
                   rng=np.random.default_rng(1), want_ground_points=True, options=RenderOptions(noise_std=2.0))
    assert f.image.shape == (180, 320, 3) and f.image.dtype == np.uint8
    ground = ~f.sky
    # (oblique frames reach the window's corners: a sliver beyond it is no-data)
    assert ground.mean() > 0.5 and f.valid[ground].mean() > 0.97
    assert f.offmap_fraction == pytest.approx((ground & ~f.valid).mean())
    g = f.image[f.valid].astype(float)
    assert g.std() > 8.0  # real texture, not a flat colour
    # Valid ground points fall inside the window that was read (up to about one pixel of the
    # coarse pyramid level used far away, whose blurred alpha reaches past the data edge).
    pts = f.ground_points_ned_m[f.valid]
    assert np.allclose(pts[:, 2], 0.0)
    assert np.abs(pts[:, :2] - pos[:2]).max() < 4.0 * alt_m + 10.0


@pytest.mark.parametrize("which, alt_m, gsd_m", [(NAIP_2018, 800.0, 5.0), (MCMILLAN, 200.0, 1.0)])
def test_map_edge_is_no_data(realdata, which, alt_m, gsd_m):
    """A nadir frame over the map's east edge: the part beyond it is masked, black and counted;
    the counted share matches the window's own no-data mask at the pixels' ground points."""
    path = realdata.joinpath(*which)
    cam = PinholeCamera.from_hfov(320, 180, 90.0)
    with MapSource(path, _centre_origin(path)) as src:
        fp = src.footprint
        pos = np.array([0.5 * (fp.north_min_m + fp.north_max_m), fp.east_max_m - 0.3 * alt_m, -alt_m])
        win = _window(src, pos[:2], 2.0 * alt_m, gsd_m)
        f = render(cam, mount(-90.0), pos, np.eye(3), win, want_ground_points=True,
                   options=RenderOptions(haze_visibility_m=None))
    assert not f.sky.any()
    assert 0.2 < f.offmap_fraction < 0.5
    assert f.offmap_fraction == pytest.approx(1.0 - f.valid.mean())
    assert not f.image[~f.valid].any()
    # The window's nearest-pixel validity at each ground point agrees away from the edge pixels.
    pts = f.ground_points_ned_m
    row, col = win.ne_to_rowcol(pts[..., 0], pts[..., 1])
    r = np.clip(np.rint(row).astype(int), 0, win.shape[0] - 1)
    c = np.clip(np.rint(col).astype(int), 0, win.shape[1] - 1)
    agree = win.valid[r, c] == f.valid
    assert agree.mean() > 0.98
    # Image columns left of the edge (image right = east at zero yaw) are on the map.
    assert f.valid[:, : cam.width_px // 4].all() and not f.valid[:, -cam.width_px // 8:].any()
