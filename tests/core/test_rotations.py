"""Rotation helpers: conventions and round trips."""

import numpy as np
from scipy.spatial.transform import Rotation

from testbench.core import rotations as r

RNG = np.random.default_rng(3)
RPY = np.column_stack([RNG.uniform(-np.pi, np.pi, 300), RNG.uniform(-1.5, 1.5, 300), RNG.uniform(-np.pi, np.pi, 300)])


def test_euler_dcm_matches_scipy_zyx():
    ours = r.euler_to_dcm(RPY)
    ref = Rotation.from_euler("ZYX", RPY[:, ::-1]).as_matrix()  # intrinsic yaw, pitch, roll
    np.testing.assert_allclose(ours, ref, atol=1e-12)


def test_round_trips():
    np.testing.assert_allclose(r.dcm_to_euler(r.euler_to_dcm(RPY)), RPY, atol=1e-10)
    q = r.euler_to_quat(RPY)
    np.testing.assert_allclose(r.quat_to_dcm(q), r.euler_to_dcm(RPY), atol=1e-12)
    np.testing.assert_allclose(r.dcm_to_quat(r.quat_to_dcm(q)), q, atol=1e-10)
    v = RNG.normal(size=(300, 3))
    np.testing.assert_allclose(r.quat_to_rotvec(r.rotvec_to_quat(v * 0.5)), v * 0.5, atol=1e-10)


def test_quaternion_product_composes_rotations():
    q1, q2 = r.euler_to_quat(RPY[:10]), r.euler_to_quat(RPY[10:20])
    np.testing.assert_allclose(r.quat_to_dcm(r.quat_multiply(q1, q2)), r.quat_to_dcm(q1) @ r.quat_to_dcm(q2), atol=1e-12)


def test_body_to_nav_sense():
    # yaw 90 deg: the body nose (x) points east in NED
    R_nb = r.euler_to_dcm(np.array([0.0, 0.0, np.pi / 2]))
    np.testing.assert_allclose(R_nb @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    # pitch up 30 deg: the nose points up (negative down)
    R_nb = r.euler_to_dcm(np.array([0.0, np.radians(30), 0.0]))
    assert (R_nb @ [1, 0, 0])[2] < 0


def test_skew_is_cross_product():
    a, b = RNG.normal(size=3), RNG.normal(size=3)
    np.testing.assert_allclose(r.skew(a) @ b, np.cross(a, b), atol=1e-15)


def test_heading_sensitivity_matches_finite_differences():
    """d yaw / d phi for R' = Exp(phi) R, at a pitched and rolled attitude."""
    from testbench.core.rotations import dcm_to_euler, euler_to_dcm, heading_sensitivity, quat_to_dcm, rotvec_to_quat

    R = euler_to_dcm(np.radians([20.0, -35.0, 130.0]))
    h = heading_sensitivity(R)
    for axis in range(3):
        d = np.zeros(3)
        d[axis] = 1e-6
        fd = (dcm_to_euler(quat_to_dcm(rotvec_to_quat(d)) @ R)[2] - dcm_to_euler(quat_to_dcm(rotvec_to_quat(-d)) @ R)[2]) / 2e-6
        assert abs(fd - h[axis]) < 1e-6
    np.testing.assert_allclose(heading_sensitivity(np.eye(3)), [0.0, 0.0, 1.0])
