"""Scene matching with a camera off its intrinsic calibration: the pose solve's sensitivity to
the intrinsics (PoseSolution.intrinsics_sensitivity), and a solve with the intrinsics corrected."""

from __future__ import annotations

import numpy as np

from testbench.core.camera_geometry import PinholeCamera, camera_pose_ned
from testbench.core.rotations import euler_to_dcm
from testbench.navigation.ismn.pose import solve_camera_pose


def _seen(camera: PinholeCamera, c, R_nc, X):
    xc = (X - c) @ R_nc
    return (camera.K @ xc.T)[:2].T / xc[:, 2:3]


def test_the_fix_moves_with_the_intrinsics_as_its_sensitivity_says(camera, mount):
    """Correspondences seen by a camera whose principal point is (2, -1) px off and focal length
    0.3 % long, solved with the calibrated K: the centre errs by S (2, -1, 0.003) to within 2 %
    of it (the solve is near-linear there), about height / focal (4.3 m) per px of principal
    point with this 640 px, 120 deg camera 800 m up; solved with the true intrinsics, not at all."""
    rng = np.random.default_rng(4)
    R_nb = euler_to_dcm(np.radians([3.0, -2.0, 35.0]))
    c, R_nc = camera_pose_ned(np.array([0.0, 0.0, -800.0]), R_nb, mount)
    X = np.c_[rng.uniform(-900, 900, (60, 2)) + c[:2], rng.uniform(-20, 20, 60)]
    err = np.array([2.0, -1.0, 0.003])
    true_cam = PinholeCamera(camera.width_px, camera.height_px, camera.fx * (1 + err[2]), camera.fy * (1 + err[2]),
                             camera.cx + err[0], camera.cy + err[1])
    uv = _seen(true_cam, c, R_nc, X)
    keep = (uv[:, 0] > 0) & (uv[:, 0] < camera.width_px) & (uv[:, 1] > 0) & (uv[:, 1] < camera.height_px)
    X, uv = X[keep], uv[keep]
    sol = solve_camera_pose(X, uv, camera.K, c + [5.0, -3.0, 1.0], R_nc, 1.0)
    S = sol.intrinsics_sensitivity
    moved = sol.centre_ned_m - c
    np.testing.assert_allclose(moved, S @ err, atol=0.02 * np.linalg.norm(S @ err))
    assert abs(np.hypot(*S[:2, 0]) / (800.0 / camera.fx) - 1.0) < 0.2  # a shift of about height / focal per px
    exact = solve_camera_pose(X, uv, true_cam.K, c + [5.0, -3.0, 1.0], R_nc, 1.0)
    np.testing.assert_allclose(exact.centre_ned_m, c, atol=1e-3)
