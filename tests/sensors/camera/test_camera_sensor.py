"""CameraSensor in a tiny fake world (the CameraWorld protocol): frame size, footprint windows
consistent with the pose, region requests, frame caching per tick."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import raster, textured

from testbench.core.interfaces import BuildContext
from testbench.sensors.camera import CameraFrame, CameraSensor
from testbench.sensors.fakes import ORIGIN, make_truth


class TinyWorld:
    """CameraWorld over one in-memory map; records the windows the camera asks for."""

    def __init__(self, requests=None):
        self.t_s = 0.0
        self.self_id = "uav0"
        self.map = raster(textured(512), 2.0)
        self.asked: list[tuple[tuple[float, float, float, float], float]] = []
        self._requests = requests

    def imagery_for(self, bounds_ne_m, gsd_m):
        self.asked.append((tuple(bounds_ne_m), gsd_m))
        return self.map

    def elevation_for(self, bounds_ne_m):
        return None

    def appearances(self, t_s):
        return ()

    def render_requests(self, camera_name):
        return self._requests


def _sensor(**kw) -> CameraSensor:
    params = CameraSensor.Params(**{"width_px": 160, "height_px": 90, "hfov_deg": 90.0, "rate_hz": 5.0, **kw})
    return CameraSensor(params, ctx=BuildContext("uav0", ("uav0",), ORIGIN, physics_rate_hz=100.0))


def test_nadir_frame_size_and_footprint():
    world = TinyWorld()
    cam = _sensor(noise_std=0.0)
    truth = make_truth(1.0, pos_ned_m=(20.0, -10.0, -100.0))
    frame = cam.measure(truth, world, np.random.default_rng(0))
    assert isinstance(frame, CameraFrame)
    assert frame.image.shape == (90, 160, 3) and frame.offmap_fraction == 0.0
    assert len(frame.regions) == 1 and frame.regions[0].roi is None
    ((n0, n1, e0, e1), gsd), = world.asked
    # Level nadir view at 100 m, 90 deg horizontal FOV: east half-width 100 m (image right is
    # east at zero yaw), north half-height 100 * (44.5 / 79.5) m; centred on the vehicle.
    half_e = 100.0 * (cam.camera.width_px - 1) / 2 / cam.camera.fx
    half_n = 100.0 * (cam.camera.height_px - 1) / 2 / cam.camera.fy
    assert (n0 + n1) / 2 == pytest.approx(20.0) and (e0 + e1) / 2 == pytest.approx(-10.0)
    assert (e1 - e0) / 2 == pytest.approx(half_e, rel=1e-6) and (n1 - n0) / 2 == pytest.approx(half_n, rel=1e-6)
    # The window's ground sample is the nadir pixel footprint (h / f).
    assert gsd == pytest.approx(100.0 / cam.camera.fx)
    # The same tick gives the same frame without rendering again.
    assert cam.measure(truth, world, np.random.default_rng(1)) is frame and len(world.asked) == 1


def test_footprint_follows_heading_and_tilt():
    world = TinyWorld()
    cam = _sensor(mount_pitch_deg=-60.0)  # tilted forward 30 deg off nadir
    # Heading east: the view reaches further east than west of the vehicle.
    truth = make_truth(0.0, pos_ned_m=(0.0, 0.0, -100.0), rpy_rad=(0.0, 0.0, np.pi / 2))
    frame = cam.measure(truth, world, np.random.default_rng(0))
    ((n0, n1, e0, e1), _), = world.asked
    # Image rows are lines across the track on flat ground: the top row lies 30 deg + half the
    # vertical field ahead, the bottom row 30 deg - half of it (just ahead of the vehicle).
    half_v = np.arctan((cam.camera.height_px - 1) / 2 / cam.camera.fy)
    assert e1 == pytest.approx(100.0 * np.tan(np.radians(30.0) + half_v), rel=1e-6)
    assert e0 == pytest.approx(100.0 * np.tan(np.radians(30.0) - half_v), rel=1e-6)
    assert n0 == pytest.approx(-n1)
    assert frame.image.shape == (90, 160, 3)


def test_region_requests():
    world = TinyWorld(requests=[(10, 20, 42, 52)])
    cam = _sensor()
    frame = cam.measure(make_truth(0.0, pos_ned_m=(0.0, 0.0, -80.0)), world, np.random.default_rng(0))
    assert frame.image is None and len(frame.regions) == 1
    assert frame.regions[0].roi == (10, 20, 42, 52) and frame.regions[0].image.shape == (32, 32, 3)
    assert _sensor().measure(make_truth(0.0), TinyWorld(requests=[]), np.random.default_rng(0)) is None


def test_frame_carries_camera_model_and_mount():
    cam = _sensor()
    frame = cam.measure(make_truth(0.0), TinyWorld(), np.random.default_rng(0))
    assert frame.camera == cam.camera
    assert np.allclose(frame.mount.R_bc, cam.mount.R_bc)
