"""A camera off its intrinsic calibration (CameraParams.focal_error_rel, principal_point_error_px
and their per-run sigmas): the true intrinsics render, navigation is given the calibrated ones."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import textured
from test_camera_rolling_shutter import OneMapWorld, _centroid_row, _dot_map, _sensor

from testbench.sensors.fakes import make_truth


def test_a_principal_point_error_shifts_the_frame_and_navigation_keeps_the_calibration():
    world = OneMapWorld(textured(512), 2.0)
    truth = make_truth(1.0, pos_ned_m=(0.0, 0.0, -100.0))
    calibrated = _sensor().measure(truth, world, np.random.default_rng(0))
    cam = _sensor(principal_point_error_px=(5.0, -3.0))
    off = cam.measure(truth, world, np.random.default_rng(0))
    assert off.camera == calibrated.camera == cam.camera  # what navigation is given
    assert cam.true_camera.cx == cam.camera.cx + 5.0 and cam.true_camera.cy == cam.camera.cy - 3.0
    # The true principal point 5 px right, 3 px up: the ground shows 5 px right and 3 px up.
    a = off.image[:-3, 5:].astype(int)
    b = calibrated.image[3:, :-5].astype(int)
    assert np.abs(a - b).mean() < 0.05


def test_a_focal_length_error_scales_the_view_about_the_principal_point():
    world = OneMapWorld(_dot_map(40.0, 0.0), 0.25)
    truth = make_truth(1.0, pos_ned_m=(0.0, 0.0, -100.0))
    cam = _sensor(focal_error_rel=0.02)
    frame = cam.measure(truth, world, np.random.default_rng(0))
    true_row = cam.camera.cy - cam.camera.fy * 1.02 * 40.0 / 100.0  # image top is north at zero yaw
    assert _centroid_row(frame.image) == pytest.approx(true_row, abs=0.15)
    assert abs(true_row - (cam.camera.cy - cam.camera.fy * 40.0 / 100.0)) > 0.6  # the test sees the effect


def test_the_intrinsics_error_is_drawn_once_per_run_from_its_stream():
    cam = _sensor(focal_error_rel=0.001, focal_error_sigma_rel=0.002, principal_point_error_sigma_px=1.0)
    assert cam.intrinsics_error == (0.001, 0.0, 0.0)
    cam.draw_constant_errors(np.random.default_rng(3))
    again = _sensor(focal_error_rel=0.001, focal_error_sigma_rel=0.002, principal_point_error_sigma_px=1.0)
    again.draw_constant_errors(np.random.default_rng(3))
    assert cam.intrinsics_error == again.intrinsics_error and cam.intrinsics_error[0] != 0.001
    assert cam.true_camera.fx == pytest.approx(cam.camera.fx * (1 + cam.intrinsics_error[0]))
    assert all(x != 0.0 for x in cam.intrinsics_error[1:])
    still = _sensor(principal_point_error_px=(0.5, 0.0))
    still.draw_constant_errors(np.random.default_rng(3))
    assert still.intrinsics_error == (0.0, 0.5, 0.0)
