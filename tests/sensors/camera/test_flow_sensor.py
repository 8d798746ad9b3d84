"""The optical-flow sensor: the image-shift fit (known sub-pixel shifts, its covariance against
the spread it shows under pixel noise, weak texture) and the sensor over a textured map (the
flow of a translation and of a rotation, as the navigator's model has them)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from conftest import raster, textured
from test_camera_sensor import TinyWorld

from testbench.core.interfaces import BuildContext
from testbench.core.messages import OpticalFlowSample
from testbench.core.rotations import euler_to_dcm
from testbench.sensors.fakes import ORIGIN, make_truth
from testbench.sensors.image_shift import image_shift
from testbench.sensors.optical_flow import OpticalFlowSensor


def _shifted(img: np.ndarray, du: float, dv: float) -> np.ndarray:
    """img with its content moved by (du, dv) px (bilinear)."""
    M = np.float32([[1, 0, du], [0, 1, dv]])
    return cv2.warpAffine(img, M, img.shape[::-1], flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)


def _grey(n=96, seed=0) -> np.ndarray:
    return cv2.cvtColor(textured(n, seed), cv2.COLOR_RGB2GRAY).astype(np.float32)


@pytest.mark.parametrize("du, dv", [(0.0, 0.0), (0.37, -0.12), (-1.8, 2.6), (5.3, -4.1)])
def test_a_known_shift_is_recovered_to_a_hundredth_of_a_pixel(du, dv):
    img = _grey()
    s = image_shift(img, _shifted(img, du, dv))
    assert s is not None
    np.testing.assert_allclose(s.shift_px, [du, dv], atol=0.01)


def test_the_claimed_covariance_follows_the_spread_under_pixel_noise():
    img = _grey(64, seed=3)
    rng = np.random.default_rng(1)
    moved = _shifted(img, 0.4, 0.2)
    err, nees = [], []
    for _ in range(300):
        a = img + rng.normal(0, 2.0, img.shape).astype(np.float32)
        b = moved + rng.normal(0, 2.0, img.shape).astype(np.float32)
        s = image_shift(a, b)
        e = s.shift_px - [0.4, 0.2]
        err.append(e)
        nees.append(e @ np.linalg.solve(s.cov_px2, e))
    # Pixel noise alone is white: the fit's claim is what it errs by (2 dof; the bilinear shift's
    # own smoothing of the second image leaves a little more).
    assert 1.5 < np.mean(nees) < 3.0
    assert np.abs(np.mean(err, axis=0)).max() < 0.005


def test_texture_in_one_direction_claims_wide_along_it():
    # Stripes along the image's columns: a shift along them changes nothing (the aperture problem).
    u = np.arange(64, dtype=np.float32)
    stripes = np.tile(120 + 40 * np.sin(2 * np.pi * u / 9.0), (64, 1)).astype(np.float32)
    rng = np.random.default_rng(0)
    a = stripes + rng.normal(0, 1.0, stripes.shape).astype(np.float32)
    b = _shifted(stripes, 0.5, 0.0) + rng.normal(0, 1.0, stripes.shape).astype(np.float32)
    s = image_shift(a, b)
    # Across the stripes the squared gradient is (40 * 2 pi / 9)^2 / 2 = 390 DN^2/px^2 per
    # pixel; along them only the noise's.
    assert s is None or (s.cov_px2[1, 1] > 100 * s.cov_px2[0, 0] and s.texture_dn2 < 1.0)


def test_a_flat_image_gives_no_shift():
    flat = np.full((64, 64), 100.0, np.float32)
    assert image_shift(flat, flat.copy()) is None


class FlowWorld(TinyWorld):
    def __init__(self):
        super().__init__()
        self.map = raster(textured(1024, seed=5), 0.5)

    def terrain_height_m(self, north_m, east_m):
        return np.zeros_like(np.asarray(north_m, float))


def _sensor(**kw) -> OpticalFlowSensor:
    params = OpticalFlowSensor.Params(**{"rate_hz": 20.0, "noise_std": 0.0, **kw})
    return OpticalFlowSensor(params, ctx=BuildContext("uav0", ("uav0",), ORIGIN, physics_rate_hz=100.0))


def _flow_between(sensor, truth0, truth1) -> OpticalFlowSample:
    world = FlowWorld()
    rng = np.random.default_rng(0)
    assert sensor.measure(truth0, world, rng) is None  # the first frame has nothing to compare with
    m = sensor.measure(truth1, world, rng)
    assert isinstance(m, OpticalFlowSample)
    return m


def test_a_translation_moves_the_ground_against_it_over_the_height():
    # Level, heading 30 deg, 50 m above flat ground; 0.3 m north and 0.1 m east in 0.05 s.
    rpy = (0.0, 0.0, np.radians(30.0))
    s = _sensor()
    d_ned = np.array([0.3, 0.1, 0.0])
    m = _flow_between(s, make_truth(1.0, (0.0, 0.0, -50.0), rpy_rad=rpy),
                      make_truth(1.05, tuple(np.array([0.0, 0.0, -50.0]) + d_ned), rpy_rad=rpy))
    assert m.dt_s == pytest.approx(0.05)
    R_nc = euler_to_dcm(np.array(rpy)) @ s.mount.R_bc
    d_c = R_nc.T @ d_ned  # the camera's move in its own frame; depth along its axis is 50 m
    np.testing.assert_allclose(m.flow_c_rad, -d_c[:2] / 50.0, atol=2e-4)
    np.testing.assert_allclose(m.R_bc, s.mount.R_bc)


@pytest.mark.parametrize("hfov_deg", [10.0, 45.0])
def test_a_rotation_moves_the_ground_as_the_sensor_says_it_reads_one(hfov_deg):
    # A roll of 4 mrad, a pitch of -3 mrad and a yaw of 2 mrad between frames, hovering 50 m up.
    s = _sensor(hfov_deg=hfov_deg)
    d_rpy = np.array([4e-3, -3e-3, 2e-3])
    m = _flow_between(s, make_truth(1.0, (0.0, 0.0, -50.0)), make_truth(1.05, (0.0, 0.0, -50.0), rpy_rad=tuple(d_rpy)))
    # Small rotation about body axes d_rpy: in the camera frame dalpha_c = R_cb d_rpy. The
    # ground at the image centre moves by (-dalpha_c,y, +dalpha_c,x); over the frame a little
    # more (off-centre pixels move by 1 + x^2 times that), as the sample's rotation_c reads it.
    da_c = s.mount.R_bc.T @ d_rpy
    centre = np.array([-da_c[1], da_c[0]])
    # First order: within 1-3 % of the rotation's flow (the navigator's rotation_sigma_fraction).
    np.testing.assert_allclose(m.flow_c_rad, m.rotation_c @ da_c, atol=0.04 * np.abs(centre).max())
    if hfov_deg < 20:  # a narrow view is nearly its centre
        np.testing.assert_allclose(m.flow_c_rad, centre, rtol=0.02)
    else:  # over 45 deg, 1 + tan(22.5 deg)^2 / 3 = 1.057 on average
        assert np.all(np.abs(m.flow_c_rad) > np.abs(centre) * 1.03)


def test_a_view_off_the_map_gives_no_flow_until_two_frames_see_only_map(caplog):
    # FlowWorld's map ends 256 m north; 50 m up the view spans +-20.7 m. At 240 m north 11 % of
    # it is no-data, whose edge stays put while the ground moves: the fit read +57 % there.
    s = _sensor()
    world, rng = FlowWorld(), np.random.default_rng(0)
    d = np.array([0.3, 0.1, 0.0])
    pos = [np.array([n, 0.0, -50.0]) for n in (0.0, 240.0, 240.3, 0.0, 0.3, 0.6)]
    pos[4], pos[5] = pos[3] + d, pos[3] + 2 * d
    out = [s.measure(make_truth(1.0 + 0.05 * i, tuple(p)), world, rng) for i, p in enumerate(pos)]
    # frame 1 looks off the map: no sample from it, nor from the pair it would start (frame 2);
    # frame 3 starts a new pair (jumped back over the map: nothing to compare with), 4 and 5 measure.
    assert [o is None for o in out] == [True, True, True, True, False, False]
    assert "off the map" in caplog.text and caplog.text.count("off the map") == 1
    d_c = s.mount.R_bc.T @ d  # level, heading north: body = NED
    np.testing.assert_allclose(out[4].flow_c_rad, -d_c[:2] / 50.0, atol=2e-4)


def test_a_tilted_cameras_reading_is_the_one_its_moments_predict():
    # 20 deg of pitch, 50 m up: the ground is nearer on one side of the image, where it moves
    # faster, and the texture weighs the sides unevenly. The fit's reading of the quadratic
    # fields (moments_c) predicts what it reads of the translation; the centre's flow alone,
    # -(t_x, t_y) n_z / D, does not.
    from testbench.navigation.ins.measurements import flow_bilinear

    world, rng = FlowWorld(), np.random.default_rng(0)
    rpy = (0.0, np.radians(-20.0), 0.0)
    R_nc = euler_to_dcm(np.array(rpy)) @ _sensor().mount.R_bc
    n_c = R_nc.T @ [0.0, 0.0, 1.0]
    centre_err, moments_err = [], []
    for _ in range(16):
        s = _sensor()
        n0, e0 = rng.uniform(-150, 150, 2)
        course = rng.uniform(0, 2 * np.pi)
        d = 0.3 * np.array([np.cos(course), np.sin(course), 0.0])
        s.measure(make_truth(1.0, (n0, e0, -50.0), rpy_rad=rpy), world, rng)
        m = s.measure(make_truth(1.05, (n0 + d[0], e0 + d[1], -50.0), rpy_rad=rpy), world, rng)
        assert m.moments_c.shape == (2, 8)
        t_c = R_nc.T @ d
        centre = flow_bilinear(None) @ n_c @ t_c / 50.0
        predicted = flow_bilinear(m.moments_c) @ n_c @ t_c / 50.0
        centre_err.append(np.linalg.norm(m.flow_c_rad - centre) / np.linalg.norm(centre))
        moments_err.append(np.linalg.norm(m.flow_c_rad - predicted) / np.linalg.norm(centre))
    assert np.median(moments_err) < 0.015
    assert np.median(moments_err) < 0.7 * np.median(centre_err)
    assert np.max(moments_err) < 0.7 * np.max(centre_err)
