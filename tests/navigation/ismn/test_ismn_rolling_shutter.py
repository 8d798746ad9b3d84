"""Scene matching with a rolling-shutter camera: each correspondence seen from the pose of its
own row's time (IsmnParams.readout_s, pose.PointPoses)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from testbench.core.camera_geometry import camera_pose_ned, row_delay_s
from testbench.core.rotations import euler_to_dcm, quat_to_dcm, rotvec_to_quat
from testbench.navigation.ismn import IsmnParams, IsmnPipeline, NccMatcher
from testbench.navigation.ismn.pose import PointPoses, solve_camera_pose
from testbench.navigation.ismn.synth import RasterMapSource, render_plane_frame

# A 30 deg bank turn at 25 m/s (0.23 rad/s of yaw) and a 30 ms readout, 800 m up.
YAW_RATE_RPS, SPEED_MPS, READOUT_S = 0.226, 25.0, 0.03


def _rolling_observations(camera, c, R_nc, X, vel_c, omega_n, readout_s):
    """Pixels (N, 2) where a rolling shutter sees NED points X (N, 3): each point on the row
    whose own pose (the middle row's moved by vel_c dt, turned by omega_n dt) sees it there."""
    uv = None
    dt = np.zeros(len(X))
    for _ in range(30):
        Ri = np.stack([quat_to_dcm(rotvec_to_quat(omega_n * t)) for t in dt]) @ R_nc
        xc = np.einsum("nji,nj->ni", Ri, X - c - dt[:, None] * vel_c)
        uv = (camera.K @ xc.T)[:2].T / xc[:, 2:3]
        dt = row_delay_s(uv[:, 1], camera.height_px, readout_s)
    return uv, dt


def test_the_pose_solve_with_each_rows_pose_recovers_the_middle_rows_pose(camera, mount):
    rng = np.random.default_rng(5)
    R_nb = euler_to_dcm(np.radians([30.0, 1.0, 40.0]))
    c, R_nc = camera_pose_ned(np.array([10.0, -20.0, -800.0]), R_nb, mount)
    X = np.c_[rng.uniform(-700, 700, (60, 2)) + c[:2], rng.uniform(-5, 5, 60)]
    vel = SPEED_MPS * np.array([np.cos(np.radians(40.0)), np.sin(np.radians(40.0)), 0.0])
    omega_n = np.array([0.0, 0.0, YAW_RATE_RPS])
    uv, dt = _rolling_observations(camera, c, R_nc, X, vel, omega_n, READOUT_S)
    keep = (uv[:, 0] > 0) & (uv[:, 0] < camera.width_px) & (uv[:, 1] > 0) & (uv[:, 1] < camera.height_px)
    X, uv, dt = X[keep], uv[keep], dt[keep]
    assert len(X) >= 20
    poses = PointPoses(dt[:, None] * vel, np.stack([quat_to_dcm(rotvec_to_quat(omega_n * t)) for t in dt]))
    seed_c, seed_R = c + [8.0, -5.0, 2.0], R_nc @ euler_to_dcm(np.radians([0.2, -0.1, 0.1]))
    sol = solve_camera_pose(X, uv, camera.K, seed_c, seed_R, 1.0, point_poses=poses)
    np.testing.assert_allclose(sol.centre_ned_m, c, atol=1e-3)
    np.testing.assert_allclose(sol.R_nc, R_nc, atol=1e-7)
    assert sol.inliers.all()
    naive = solve_camera_pose(X, uv, camera.K, seed_c, seed_R, 1.0)  # the same rows taken for one pose
    assert np.linalg.norm(naive.centre_ned_m[:2] - c[:2]) > 0.3


def test_the_row_wise_projection_is_where_each_row_sees_the_ground(camera, mount):
    """RowMotion.project (the ortho view's warp) against the brute-force rolling observation."""
    from testbench.navigation.ismn.rolling import RowMotion

    rng = np.random.default_rng(2)
    c, R_nc = camera_pose_ned(np.array([0.0, 0.0, -800.0]), euler_to_dcm(np.radians([20.0, 3.0, 70.0])), mount)
    X = np.c_[rng.uniform(-600, 600, (50, 2)), np.zeros(50)]
    vel, omega_n = np.array([20.0, 15.0, 0.0]), np.array([0.05, -0.1, 0.4])
    expected, _ = _rolling_observations(camera, c, R_nc, X, vel, omega_n, 0.05)
    got = RowMotion(camera, 0.05, vel, omega_n).project(c, R_nc, X)
    np.testing.assert_allclose(got, expected, atol=1e-3)


def _rolling_frame(world, camera, mount, pos, R_nb, vel, omega_b, readout_s, bands=36):
    """A rolling-shutter frame of a flat synthetic world: each band of rows from the pose of its
    middle row's time (rendered whole at that pose, the band's rows kept)."""
    H = camera.height_px
    edges = np.round(np.linspace(0, H, bands + 1)).astype(int)
    out = None
    for a, b in zip(edges[:-1], edges[1:]):
        t = float(row_delay_s(0.5 * (a + b) - 0.5, H, readout_s))
        R_t = R_nb @ quat_to_dcm(rotvec_to_quat(omega_b * t))
        img = render_plane_frame(world, camera, pos + vel * t, R_t, mount)
        out = np.empty_like(img) if out is None else out
        out[a:b] = img[a:b]
    return out


@pytest.mark.parametrize("readout_s", [0.0, READOUT_S])
def test_a_fix_in_a_turn_is_mended_by_the_rows_poses(seasons, camera, mount, make_estimate, readout_s):
    """In the paper's 30 deg bank turn with a 30 ms readout, the estimate 10 m off: the pipeline
    that models the readout fixes the middle row's pose as well as a global shutter's frame is
    fixed (0.22 m against 0.33 m when this was written); solving the same frame for one pose
    errs by 1.9 m."""
    truth = np.array([40.0, -30.0, -800.0])
    rpy = np.radians([0.0, 0.0, 25.0])
    R_nb = euler_to_dcm(rpy)
    vel = SPEED_MPS * np.array([np.cos(rpy[2]), np.sin(rpy[2]), 0.0])
    omega_b = np.array([0.0, 0.0, YAW_RATE_RPS])
    frame = _rolling_frame(seasons[0], camera, mount, truth, R_nb, vel, omega_b, readout_s)
    est = make_estimate(truth + [6.0, -8.0, 1.0], np.degrees(rpy), sigma_pos_m=10.0)
    est = dataclasses.replace(est, vel_ned_mps=vel, omega_b_rps=omega_b)

    def error(model_readout_s, row_wise_ortho=False):
        params = IsmnParams(readout_s=model_readout_s, rolling_shutter_ortho=row_wise_ortho)
        fix, diag = IsmnPipeline(camera, mount, RasterMapSource(seasons[1]), None, NccMatcher(), params).process(frame, 0.0, est)
        assert fix is not None, diag.reason
        return float(np.hypot(*(fix.pos_ned_m - truth)[:2])), diag.n_inliers

    modelled, n_tiles = error(readout_s)
    assert modelled < 0.8
    if readout_s > 0.0:
        ignored, _ = error(0.0)
        assert ignored > modelled + 1.0, (modelled, ignored)
        row_wise, n_row_wise = error(readout_s, row_wise_ortho=True)  # the ortho view warped row by row too
        assert row_wise < 0.8 and n_row_wise >= n_tiles
