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


def test_boresight_error_renders_with_the_true_mount_and_tells_navigation_the_calibrated_one():
    """A nadir camera whose true mounting is pitched 2 deg off the calibrated one renders what a
    camera mounted at -88 deg renders (the Z-Y-X error about body y composes with the mounting's
    pitch), while its frames and `.mount` carry the calibrated -90 deg."""
    truth = make_truth(0.0, pos_ned_m=(5.0, 3.0, -100.0))
    misaligned = _sensor(noise_std=0.0, mount_error_deg=(0.0, 2.0, 0.0))
    tilted = _sensor(noise_std=0.0, mount_pitch_deg=-88.0)
    w1, w2 = TinyWorld(), TinyWorld()
    f1 = misaligned.measure(truth, w1, np.random.default_rng(0))
    f2 = tilted.measure(truth, w2, np.random.default_rng(0))
    (b1, g1), = w1.asked
    (b2, g2), = w2.asked
    assert np.allclose(b1, b2, rtol=0, atol=1e-9) and g1 == pytest.approx(g2)
    # The same pose to the last bits of R_bc: at most a DN here and there from the resampling.
    assert np.abs(f1.image.astype(int) - f2.image.astype(int)).mean() < 0.01
    assert np.allclose(f1.mount.R_bc, _sensor().mount.R_bc) and f1.mount is misaligned.mount
    assert np.allclose(misaligned.true_mount.R_bc, tilted.mount.R_bc)
    # The footprint moved forward (north at zero heading), as a 2 deg forward tilt moves it.
    nominal_world = TinyWorld()
    _sensor(noise_std=0.0).measure(truth, nominal_world, np.random.default_rng(0))
    ((n0, n1, _, _), _), = nominal_world.asked
    assert (b1[0] + b1[1]) / 2 - (n0 + n1) / 2 > 0.9 * 100.0 * np.tan(np.radians(2.0))


def test_random_boresight_error_is_drawn_once_from_the_seed():
    """mount_error_sigma_deg: one draw per axis (draw_constant_errors, before the run), the
    same for the same stream, another for another; the calibrated mount is untouched, and
    without a sigma nothing is drawn."""

    def drawn(seed, sigma=0.1):
        cam = _sensor(noise_std=0.0, mount_error_sigma_deg=sigma)
        assert np.array_equal(cam.true_mount.R_bc, cam.mount.R_bc)  # not drawn yet
        rng = np.random.default_rng(seed)
        cam.draw_constant_errors(rng)
        assert np.allclose(cam.mount.R_bc, _sensor().mount.R_bc)
        return cam, rng

    (a, _), (b, _), (c, _) = drawn(1), drawn(1), drawn(2)
    assert np.array_equal(a.true_mount.R_bc, b.true_mount.R_bc) and not np.allclose(a.true_mount.R_bc, c.true_mount.R_bc)
    nominal = _sensor().mount.R_bc
    angle_deg = np.degrees(np.arccos(np.clip((np.trace(nominal.T @ a.true_mount.R_bc) - 1.0) / 2.0, -1.0, 1.0)))
    assert 0.0 < angle_deg < 0.6  # a 0.1 deg sigma per axis: about 0.16 deg in all
    assert angle_deg == pytest.approx(np.linalg.norm(a.boresight_error_deg), rel=1e-3)
    none, rng = drawn(1, sigma=0.0)
    assert np.array_equal(none.true_mount.R_bc, none.mount.R_bc)
    assert rng.standard_normal() == np.random.default_rng(1).standard_normal()  # the stream untouched


def test_a_frame_stamped_late_shows_the_pose_of_its_exposure():
    """time_offset_s (stamp minus exposure): flying north at 25 m/s, a frame stamped 0.2 s after
    its exposure looks down from 5 m further south; its stamp stays the tick's."""
    world = TinyWorld()
    cam = _sensor(noise_std=0.0, time_offset_s=0.2)
    truth = make_truth(1.0, pos_ned_m=(20.0, -10.0, -100.0), vel_ned_mps=(25.0, 0.0, 0.0))
    frame = cam.measure(truth, world, np.random.default_rng(0))
    assert frame.t_s == 1.0
    ((n0, n1, e0, e1), _), = world.asked
    assert (n0 + n1) / 2 == pytest.approx(15.0, abs=1e-6) and (e0 + e1) / 2 == pytest.approx(-10.0, abs=1e-6)


def test_the_exposure_pose_follows_a_turn_to_second_order():
    """A level turn of radius 110 m at 25 m/s (a 30 deg bank's): the pose 0.1 s before the tick,
    extrapolated from the tick's velocity, acceleration and body rate, within a millimetre and a
    microradian of the circle's."""
    import dataclasses

    from testbench.core.rotations import euler_to_dcm, quat_to_dcm
    from testbench.sensors.camera.sensor import exposure_pose

    speed, radius, dt = 25.0, 110.0, 0.1
    rate = speed / radius

    def on_circle(t):
        a = rate * t  # heading; the centre east of the start
        pos = np.array([radius * np.sin(a), radius * (1 - np.cos(a)), -100.0])
        return pos, np.array([speed * np.cos(a), speed * np.sin(a), 0.0]), a

    pos, vel, heading = on_circle(2.0)
    truth = make_truth(2.0, pos_ned_m=pos, vel_ned_mps=vel, rpy_rad=(0.0, 0.0, heading), omega_eb_b_rps=(0.0, 0.0, rate))
    R_bn = quat_to_dcm(truth.q_nb_wxyz).T
    acc_n = np.array([-np.sin(heading), np.cos(heading), 0.0]) * speed * rate  # towards the centre
    from testbench.core.units import STANDARD_GRAVITY_MPS2

    truth = dataclasses.replace(truth, f_b_mps2=R_bn @ (acc_n - np.array([0.0, 0.0, STANDARD_GRAVITY_MPS2])))
    p_exp, R_exp = exposure_pose(truth, dt)
    p_true, _, h_true = on_circle(2.0 - dt)
    assert np.linalg.norm(p_exp - p_true) < 1e-3
    np.testing.assert_allclose(R_exp, euler_to_dcm((0.0, 0.0, h_true)), atol=1e-6)


def test_the_time_offset_is_drawn_once_per_run_from_its_stream():
    cam = _sensor(time_offset_s=0.01, time_offset_sigma_s=0.02)
    assert cam.time_offset_s == 0.01
    cam.draw_constant_errors(np.random.default_rng(3))
    again = _sensor(time_offset_s=0.01, time_offset_sigma_s=0.02)
    again.draw_constant_errors(np.random.default_rng(3))
    assert cam.time_offset_s == again.time_offset_s != 0.01
    still = _sensor(time_offset_s=0.01)
    still.draw_constant_errors(np.random.default_rng(3))
    assert still.time_offset_s == 0.01
