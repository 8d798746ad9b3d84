"""Real imagery: frames rendered from one NAIP year, matched against another year (North Dakota,
800 m), and McMillan at 150 m (one year only: same raster with photometric changes, labelled)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import rasterio
from pyproj import Transformer

from testbench.core.camera_geometry import CameraMount, PinholeCamera, mount_rotation
from testbench.core.interfaces import GeodeticOrigin
from testbench.core.rotations import euler_to_dcm
from testbench.navigation.ismn import IsmnPipeline, NccMatcher
from testbench.navigation.ismn.synth import photometric_change, render_plane_frame
from testbench.world.imagery import MapSource

pytestmark = pytest.mark.realdata


def _centre_origin(path) -> GeodeticOrigin:
    with rasterio.open(path) as ds:
        x, y = (ds.bounds.left + ds.bounds.right) / 2, (ds.bounds.bottom + ds.bounds.top) / 2
        lon, lat = Transformer.from_crs(ds.crs, "EPSG:4326", always_xy=True).transform(x, y)
    return GeodeticOrigin(math.radians(lat), math.radians(lon), 0.0)


def _run(render_src, map_src, camera, mount, poses, make_estimate, render_gsd, rng, photometric=False,
         sigma_pos=10.0):
    pipe = IsmnPipeline(camera, mount, map_src, None, NccMatcher())
    errs = []
    for truth, rpy in poses:
        R_nb = euler_to_dcm(np.radians(rpy))
        pad = 3.0 * -truth[2]
        src = render_src.read_local(truth[0] - pad, truth[0] + pad, truth[1] - pad, truth[1] + pad, render_gsd)
        frame = render_plane_frame(src, camera, truth, R_nb, mount)
        if photometric:
            frame = photometric_change(frame, rng)
        est = make_estimate(truth + np.r_[rng.normal(0, sigma_pos, 2), 0.0], rpy + rng.normal(0, 0.05, 3),
                            sigma_pos_m=1.5 * sigma_pos, sigma_att_deg=0.1)
        fix, diag = pipe.process(frame, 0.0, est)
        errs.append(np.nan if fix is None else float(np.hypot(*(fix.pos_ned_m[:2] - truth[:2]))))
    return np.array(errs)


def test_naip_2018_frames_against_2016_map(realdata, camera, mount, make_estimate):
    """800 m, 640 x 360 camera (about 4.3 m ground sample, the map's is 5 m): fix rate and
    accuracy near the scene centre (the two years' georeferences differ by a few metres)."""
    nd = realdata / "naip_nd"
    origin = _centre_origin(nd / "m_4709963_se_14_1_20160816.tif")
    rng = np.random.default_rng(11)
    poses = [(np.r_[rng.uniform(-300, 300, 2), -800.0], np.r_[rng.uniform(-3, 3, 2), rng.uniform(-30, 30)])
             for _ in range(6)]
    with MapSource(nd / "m_4709963_se_14_1_20180716.tif", origin) as r18, \
            MapSource(nd / "m_4709963_se_14_1_20160816.tif", origin) as r16:
        errs = _run(r18, r16, camera, mount, poses, make_estimate, 2.5, rng)
    ok = np.isfinite(errs)
    print(f"NAIP ND 2018 vs 2016 at 800 m: fix rate {ok.mean():.2f}, mean error {np.nanmean(errs):.2f} m")
    assert ok.mean() >= 0.8
    assert np.nanmean(errs) < 3.0  # issue target for real imagery, smooth flight


def test_mcmillan_150m_same_raster_photometric(realdata, make_estimate):
    """150 m, 640 x 360 camera with 90 deg FOV over the 0.81 m McMillan raster. SAME raster for
    rendering and matching (one year only), with gain/gamma/blur/noise changes."""
    path = realdata / "naip_mcmillan" / "mcmillan_naip2016_utm10n.tif"
    origin = _centre_origin(path)
    cam = PinholeCamera.from_hfov(640, 360, 90.0)
    mount = CameraMount(mount_rotation(0.0, -90.0, 0.0), np.zeros(3))
    rng = np.random.default_rng(5)
    poses = [(np.r_[rng.uniform(-300, 300, 2), -150.0], np.r_[rng.uniform(-3, 3, 2), rng.uniform(-180, 180)])
             for _ in range(5)]
    with MapSource(path, origin) as m:
        errs = _run(m, m, cam, mount, poses, make_estimate, 0.5, rng, photometric=True, sigma_pos=5.0)
    ok = np.isfinite(errs)
    print(f"McMillan same-raster photometric at 150 m: fix rate {ok.mean():.2f}, mean error {np.nanmean(errs):.2f} m")
    assert ok.mean() >= 0.8
    assert np.nanmean(errs) < 1.5
