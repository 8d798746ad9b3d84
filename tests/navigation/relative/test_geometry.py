"""Bearing-range geometry: relative position -> pixel + UWB range -> the same position."""

import numpy as np
import pytest

from testbench.core.camera_geometry import CameraMount, PinholeCamera, mount_rotation
from testbench.core.rotations import euler_to_dcm
from testbench.navigation.relative.geometry import (
    los_camera, project_relative, relative_from_bearing_range, undistort_normalized, uwb_range)

CAM = PinholeCamera.from_hfov(1920, 1080, 120.0, dist=(-0.12, 0.03, 0.001, -0.0005, 0.0))


@pytest.mark.parametrize("mount_yaw_deg", [0.0, 90.0, -90.0])
def test_round_trip_with_distortion_and_lever_arms(mount_yaw_deg):
    rng = np.random.default_rng(1)
    mount = CameraMount(mount_rotation(0.0, 0.0, mount_yaw_deg), np.array([0.12, 0.05 * np.sign(mount_yaw_deg), -0.04]))
    uwb_lever = np.array([-0.05, 0.0, -0.10])
    for _ in range(20):
        R_nb = euler_to_dcm(rng.uniform([-0.3, -0.3, -np.pi], [0.3, 0.3, np.pi]))
        # A neighbour 20-200 m away inside the camera's view (+-50 deg of its axis).
        az, el = rng.uniform(-0.85, 0.85), rng.uniform(-0.4, 0.4)
        d_c = np.array([np.tan(az), np.tan(el), 1.0])
        d_c *= rng.uniform(20, 200) / np.linalg.norm(d_c)
        rel = R_nb @ mount.lever_arm_b_m + R_nb @ mount.R_bc @ d_c
        uv, z = project_relative(CAM, mount, R_nb, rel[None, :])
        assert z[0] > 0 and 0 <= uv[0, 0] < CAM.width_px and 0 <= uv[0, 1] < CAM.height_px
        rho = uwb_range(rel, R_nb, uwb_lever)  # same installation, same attitude: levers cancel
        assert rho == pytest.approx(np.linalg.norm(rel), abs=1e-12)
        back = relative_from_bearing_range(CAM, mount, R_nb, uv, rho)
        np.testing.assert_allclose(back, rel, atol=1e-6 * np.linalg.norm(rel))


def test_undistort_inverts_projection():
    xy = np.array([[0.3, -0.2], [-0.9, 0.45], [0.0, 0.0]])
    import cv2

    pts = np.column_stack([xy, np.ones(3)]).reshape(-1, 1, 3)
    uv, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), CAM.K, np.asarray(CAM.dist))
    np.testing.assert_allclose(undistort_normalized(CAM, uv.reshape(-1, 2)), xy, atol=1e-9)
    los = los_camera(CAM, uv.reshape(-1, 2))
    np.testing.assert_allclose(np.linalg.norm(los, axis=1), 1.0)


def test_uwb_range_lever_arm_with_different_attitudes():
    lever = np.array([0.0, 0.0, -0.2])
    R_self, R_peer = euler_to_dcm([0.0, 0.0, 0.0]), euler_to_dcm([0.5, 0.0, 0.0])
    rel = np.array([10.0, 0.0, 0.0])
    expected = np.linalg.norm(rel + R_peer @ lever - R_self @ lever)
    assert uwb_range(rel, R_self, lever, R_peer) == pytest.approx(expected)
