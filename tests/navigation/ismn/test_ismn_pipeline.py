"""Pose solve and the whole pipeline on synthetic two-season worlds."""

from __future__ import annotations

import numpy as np
import pytest

from testbench.core.camera_geometry import camera_pose_ned
from testbench.core.rotations import euler_to_dcm
from testbench.navigation.ismn import IsmnParams, IsmnPipeline, NccMatcher
from testbench.navigation.ismn.pose import SEED_SHIFT_FRACTION, seed_centre, solve_camera_pose
from testbench.navigation.ismn.synth import RasterMapSource, procedural_seasons, render_plane_frame


@pytest.mark.parametrize("method", ["map", "opencv"])
def test_pnp_recovers_pose_from_exact_correspondences(camera, mount, method):
    """Ground points seen by the true camera, seeded with a pose 30 m and 1 deg off."""
    rng = np.random.default_rng(3)
    R_nb = euler_to_dcm(np.radians([4.0, -2.0, 60.0]))
    c, R_nc = camera_pose_ned(np.array([10.0, -20.0, -800.0]), R_nb, mount)
    X = np.c_[rng.uniform(-900, 900, (40, 2)) + c[:2], rng.uniform(-30, 30, 40)]
    xc = (X - c) @ R_nc
    uv = (camera.K @ xc.T)[:2].T / xc[:, 2:3]
    R0 = R_nc @ euler_to_dcm(np.radians([1.0, -0.5, 0.3]))
    sol = solve_camera_pose(X, uv, camera.K, c + [30.0, -20.0, 5.0], R0, 1.0, method=method)
    np.testing.assert_allclose(sol.centre_ned_m, c, atol=1e-3)
    np.testing.assert_allclose(sol.R_nc, R_nc, atol=1e-7)
    assert sol.inliers.all() and np.all(np.linalg.eigvalsh(sol.cov_centre_m2) > 0)


def test_a_cold_start_far_off_seeds_the_solve_with_the_match_offset(camera, mount):
    """An estimate 5 km off at 800 m (a cold start's 3 km prior), banked 30 deg in the turn it
    launched in: the map places the ground 5 km from where the estimate puts it. From the
    estimate's centre Gauss-Newton does not reach the pose; seeded with the match's offset
    (seed_centre) it does. An offset below a quarter of the height leaves the seed as it is."""
    rng = np.random.default_rng(4)
    R_nb = euler_to_dcm(np.radians([30.0, 2.0, 20.0]))
    c, R_nc = camera_pose_ned(np.array([0.0, 0.0, -800.0]), R_nb, mount)
    uv = np.c_[rng.uniform(0, camera.width_px, 40), rng.uniform(0, camera.height_px, 40)]
    rays = (np.c_[uv, np.ones(40)] @ np.linalg.inv(camera.K).T) @ R_nc.T  # NED directions
    X = c + rays * (-c[2] / rays[:, 2:3])  # where each pixel's ray meets the ground (down 0)
    est = c + np.array([3000.0, -4000.0, 0.0])
    predicted = X[:, :2] + (est - c)[:2]  # where the estimate puts each point's ground
    seed = seed_centre(est, 800.0, X[:, 0] - predicted[:, 0], X[:, 1] - predicted[:, 1])
    np.testing.assert_allclose(seed, c, atol=1e-6)
    P = np.diag(np.radians([0.1, 0.1, 0.3]) ** 2)  # the INS attitude as the solve's prior
    far = solve_camera_pose(X, uv, camera.K, est, R_nc, 1.0, P)
    assert far is None or np.hypot(*(far.centre_ned_m - c)[:2]) > 1000.0
    sol = solve_camera_pose(X, uv, camera.K, seed, R_nc, 1.0, P)
    np.testing.assert_allclose(sol.centre_ned_m, c, atol=1e-3)
    near = c + np.array([0.2 * 800.0, 0.0, 0.0])
    assert SEED_SHIFT_FRACTION * 800.0 > 160.0
    np.testing.assert_array_equal(seed_centre(near, 800.0, np.full(40, -160.0), np.zeros(40)), near)


def test_pose_attitude_prior_sensitivity_matches_finite_differences(camera, mount):
    """With the INS attitude as prior, the solve reports M = d centre / d (prior mean) and the
    covariance from the image alone. Noisy correspondences: moving the prior's mean (the INS
    attitude) by a small NED rotation mu moves the centre by M mu; the covariances satisfy
    cov = cov_given_att + M P M^T; without a prior M = 0."""
    from testbench.core.rotations import quat_to_dcm, rotvec_to_quat

    rng = np.random.default_rng(5)
    R_nb = euler_to_dcm(np.radians([2.0, -1.0, 30.0]))
    c, R_nc = camera_pose_ned(np.array([0.0, 0.0, -800.0]), R_nb, mount)
    X = np.c_[rng.uniform(-600, 600, (30, 2)) + c[:2], np.zeros(30)]
    xc = (X - c) @ R_nc
    uv = (camera.K @ xc.T)[:2].T / xc[:, 2:3] + rng.normal(0.0, 2.0, (30, 2))
    P = np.diag(np.radians([0.05, 0.05, 0.2]) ** 2)
    sol = solve_camera_pose(X, uv, camera.K, c, R_nc, 1.5, P)
    M = sol.att_sensitivity_m_per_rad
    assert np.abs(M).max() > 10.0  # the prior matters: metres per rad at 800 m
    for axis in range(3):
        mu = np.zeros(3)
        mu[axis] = 2e-4  # 0.2 m at 1 km/rad: far above the solve's 0.1 mm convergence step
        R_mu = quat_to_dcm(rotvec_to_quat(mu)) @ R_nc  # the prior's mean moved by mu (NED)
        moved = solve_camera_pose(X, uv, camera.K, c, R_mu, 1.5, P, iterations=30)
        fd = (moved.centre_ned_m - sol.centre_ned_m) / 2e-4
        np.testing.assert_allclose(fd, M[:, axis], rtol=0.01, atol=0.01 * np.abs(M).max())
    np.testing.assert_allclose(sol.cov_centre_m2, sol.cov_centre_given_att_m2 + M @ P @ M.T, rtol=1e-5, atol=1e-6)
    free = solve_camera_pose(X, uv, camera.K, c, R_nc, 1.5, None)
    assert np.all(free.att_sensitivity_m_per_rad == 0.0)
    np.testing.assert_allclose(free.cov_centre_given_att_m2, free.cov_centre_m2)


def test_image_only_attitude_does_not_lean_on_the_prior(camera, mount):
    """Noisy correspondences and a prior whose mean is 0.3 deg off in heading and tight (0.05
    deg): the MAP attitude leans toward the prior, the image-only attitude does not. It equals
    the solve without any prior, and its covariance is that solve's; image_heading turns it
    into the body heading with a 1-sigma from that covariance."""
    from testbench.core.rotations import dcm_to_euler, quat_to_dcm, rotvec_to_quat
    from testbench.navigation.ismn.pose import image_heading

    rng = np.random.default_rng(8)
    R_nb = euler_to_dcm(np.radians([2.0, 3.0, 40.0]))
    c, R_nc = camera_pose_ned(np.array([0.0, 0.0, -800.0]), R_nb, mount)
    X = np.c_[rng.uniform(-700, 700, (40, 2)) + c[:2], np.zeros(40)]
    xc = (X - c) @ R_nc
    uv = (camera.K @ xc.T)[:2].T / xc[:, 2:3] + rng.normal(0.0, 0.5, (40, 2))
    off = quat_to_dcm(rotvec_to_quat(np.radians([0.0, 0.0, 0.3])))
    R0 = off @ R_nc  # the INS: 0.3 deg off in heading, claiming 0.05 deg
    P = np.diag(np.radians([0.05, 0.05, 0.05]) ** 2)
    sol = solve_camera_pose(X, uv, camera.K, c, R0, 1.0, P, iterations=20)
    free = solve_camera_pose(X, uv, camera.K, c, R0, 1.0, None, iterations=20)
    yaw = lambda R: float(dcm_to_euler(R @ mount.R_bc.T)[2])  # noqa: E731
    R_img = quat_to_dcm(rotvec_to_quat(sol.att_img_ned_rad)) @ R0
    assert abs(np.degrees(yaw(sol.R_nc) - yaw(R_nc))) > 0.05  # the MAP leans on the prior
    assert abs(np.degrees(yaw(R_img) - yaw(free.R_nc))) < 1e-3  # the image alone does not
    # (linearised at the MAP solution instead of the free one: equal to a few parts in 1000)
    np.testing.assert_allclose(sol.cov_att_img_rad2, free.cov_att_rad2, rtol=0.02, atol=1e-9)
    heading, sigma = image_heading(sol.att_img_ned_rad, sol.cov_att_img_rad2, R0 @ mount.R_bc.T)
    assert abs(heading - yaw(R_img)) < 1e-9
    assert abs(np.degrees(heading - float(dcm_to_euler(R_nb)[2]))) < 4 * np.degrees(sigma)
    assert 0.0 < np.degrees(sigma) < 0.05



def test_image_only_pose_is_the_solve_without_the_prior(camera, mount):
    """The image-only pose (centre and attitude, with their joint covariance) of a MAP solve
    whose prior is 0.4 deg off in tilt equals the solve without any prior: the same centre to
    centimetres where the MAP centre is pulled by metres, and that solve's covariance, whose
    centre-attitude cross terms are not small (a tilt and a shift move the image alike)."""
    from testbench.core.rotations import quat_to_dcm, rotvec_to_quat

    rng = np.random.default_rng(3)
    R_nb = euler_to_dcm(np.radians([1.0, -2.0, 70.0]))
    c, R_nc = camera_pose_ned(np.array([10.0, -20.0, -800.0]), R_nb, mount)
    X = np.c_[rng.uniform(-700, 700, (40, 2)) + c[:2], np.zeros(40)]
    xc = (X - c) @ R_nc
    uv = (camera.K @ xc.T)[:2].T / xc[:, 2:3] + rng.normal(0.0, 0.5, (40, 2))
    R0 = quat_to_dcm(rotvec_to_quat(np.radians([0.4, 0.0, 0.0]))) @ R_nc  # tilted about north
    P = np.diag(np.radians([0.05, 0.05, 0.05]) ** 2)
    sol = solve_camera_pose(X, uv, camera.K, c, R0, 1.0, P, iterations=20)
    free = solve_camera_pose(X, uv, camera.K, c, R0, 1.0, None, iterations=20)
    assert np.linalg.norm(sol.centre_ned_m - free.centre_ned_m) > 1.0  # the MAP leans on the prior
    assert np.linalg.norm(sol.centre_img_ned_m - free.centre_ned_m) < 0.05
    assert np.linalg.norm(free.centre_img_ned_m - free.centre_ned_m) == 0.0
    cov = sol.cov_pose_img
    np.testing.assert_allclose(cov[3:, 3:], sol.cov_att_img_rad2)
    np.testing.assert_allclose(free.cov_pose_img[:3, :3], free.cov_centre_m2)
    np.testing.assert_allclose(free.cov_pose_img[3:, 3:], free.cov_att_rad2)
    # Linearised at the MAP solution instead of the free one (0.4 deg apart): the variances
    # agree to 2 %, the correlations to 0.05.
    sd, sd_free = np.sqrt(np.diag(cov)), np.sqrt(np.diag(free.cov_pose_img))
    np.testing.assert_allclose(sd, sd_free, rtol=0.02)
    assert np.abs((cov - free.cov_pose_img) / np.outer(sd, sd)).max() < 0.05
    assert np.abs(cov[:3, 3:] / np.outer(sd[:3], sd[3:])).max() > 0.5


def _pipeline(seasons, camera, mount, **kw):
    return IsmnPipeline(camera, mount, RasterMapSource(seasons[1]), None, NccMatcher(), IsmnParams(**kw))


def test_pipeline_fix_other_season(seasons, camera, mount, make_estimate):
    """Frame of the summer world, map of the winter world, estimate 25 m off: fix within 2 m,
    and its covariance is consistent with that."""
    truth = np.array([40.0, -30.0, -800.0])
    rpy = [3.0, -2.0, 25.0]
    frame = render_plane_frame(seasons[0], camera, truth, euler_to_dcm(np.radians(rpy)), mount)
    est = make_estimate(truth + [15.0, -20.0, 3.0], rpy, sigma_pos_m=15.0)
    fix, diag = _pipeline(seasons, camera, mount).process(frame, 12.5, est)
    assert fix is not None, diag.reason
    err = fix.pos_ned_m - truth
    assert np.hypot(err[0], err[1]) < 2.0, err
    assert fix.t_s == 12.5 and fix.source == "ismn" and 0.3 < fix.quality <= 1.0
    assert err[:2] @ np.linalg.solve(fix.cov_ned_m2[:2, :2], err[:2]) < 13.8  # chi2(2) 99.9 %
    assert set(diag.latency_ms) >= {"window", "ortho", "match", "pose", "total"}
    assert diag.ortho is not None and diag.map_window is not None and diag.frame_thumb is not None


def test_down_floor_is_its_own(seasons, camera, mount, make_estimate):
    """sigma_floor_down_m sets the floor of the fix's down variance alone: the same frame and
    estimate give the same fix and horizontal covariance, and the down variance differs by the
    difference of the two floors' squares (the floor is added in quadrature)."""
    truth = np.array([40.0, -30.0, -800.0])
    frame = render_plane_frame(seasons[0], camera, truth, euler_to_dcm(np.radians([1.0, -1.0, 10.0])), mount)
    est = make_estimate(truth + [5.0, -4.0, 1.0], [1.0, -1.0, 10.0], sigma_pos_m=8.0)
    same, _ = _pipeline(seasons, camera, mount, sigma_floor_m=0.3).process(frame, 1.0, est)
    low, _ = _pipeline(seasons, camera, mount, sigma_floor_m=0.3, sigma_floor_down_m=0.05).process(frame, 1.0, est)
    assert same is not None and low is not None
    np.testing.assert_array_equal(low.pos_ned_m, same.pos_ned_m)
    np.testing.assert_allclose(low.cov_ned_m2[:2, :2], same.cov_ned_m2[:2, :2], rtol=1e-12)
    np.testing.assert_allclose(same.cov_ned_m2[2, 2] - low.cov_ned_m2[2, 2], 0.3**2 - 0.05**2, rtol=1e-9)
    np.testing.assert_allclose(same.cov_given_att_ned_m2[2, 2] - low.cov_given_att_ned_m2[2, 2], 0.3**2 - 0.05**2, rtol=1e-9)


def test_appearance_term_follows_quality(seasons, camera, mount, make_estimate):
    """appearance_sigma_m adds s(q) = a ((1 - q) / (1 - q_ref))^k in quadrature on every axis,
    q the fix's quality: the same frame gives the same fix, its covariance grows by s(q)^2 I
    (the attitude-conditioned one likewise), and s at the reference quality is a itself. The
    left three eighths of the frame are moved 6 px, so that their tiles disagree with the rest
    (the quality, the agreeing share of the tiles, drops to about 0.6)."""
    truth = np.array([40.0, -30.0, -800.0])
    frame = render_plane_frame(seasons[0], camera, truth, euler_to_dcm(np.radians([1.0, -1.0, 10.0])), mount)
    w = frame.shape[1] * 3 // 8
    frame[:, :w] = np.roll(frame[:, :w], 6, axis=0)
    est = make_estimate(truth + [5.0, -4.0, 1.0], [1.0, -1.0, 10.0], sigma_pos_m=8.0)
    plain, _ = _pipeline(seasons, camera, mount).process(frame, 1.0, est)
    pipe = _pipeline(seasons, camera, mount, appearance_sigma_m=0.4, appearance_ref_quality=0.6, appearance_exponent=3.0)
    fix, _ = pipe.process(frame, 1.0, est)
    assert plain is not None and fix is not None
    np.testing.assert_array_equal(fix.pos_ned_m, plain.pos_ned_m)
    assert 0.3 < fix.quality < 0.9
    s = 0.4 * ((1.0 - fix.quality) / 0.4) ** 3
    np.testing.assert_allclose(fix.cov_ned_m2 - plain.cov_ned_m2, s**2 * np.eye(3), atol=1e-12)
    np.testing.assert_allclose(fix.cov_given_att_ned_m2 - plain.cov_given_att_ned_m2, s**2 * np.eye(3), atol=1e-12)
    assert pipe._appearance_sigma_m(0.6) == pytest.approx(0.4)
    assert pipe._appearance_sigma_m(1.0) == 0.0 and pipe._appearance_sigma_m(0.2) == pytest.approx(3.2)


def test_pose_solve_removes_attitude_error_bias(seasons, camera, mount, make_estimate):
    """A 1 deg roll error at 800 m shifts an image-centre lookup by about 14 m; the PnP fix
    does not inherit it."""
    truth = np.array([0.0, 0.0, -800.0])
    rpy_true = [2.0, 1.0, 0.0]
    frame = render_plane_frame(seasons[0], camera, truth, euler_to_dcm(np.radians(rpy_true)), mount)
    est = make_estimate(truth, [3.0, 1.0, 0.0], sigma_pos_m=10.0, sigma_att_deg=1.0)
    fix, diag = _pipeline(seasons, camera, mount).process(frame, 0.0, est)
    assert fix is not None, diag.reason
    centre_lookup_err = np.hypot(*(truth[:2] + diag.offset_m - truth[:2]))
    assert centre_lookup_err > 10.0  # the naive method is off by the attitude error
    err = np.hypot(*(fix.pos_ned_m[:2] - truth[:2]))
    assert err < 4.0, (err, centre_lookup_err)


def test_wrong_map_gives_no_fix_or_low_quality(seasons, camera, mount, make_estimate):
    other = procedural_seasons(np.random.default_rng(123), 1200, 4.0)[1]
    truth = np.array([0.0, 0.0, -800.0])
    frame = render_plane_frame(seasons[0], camera, truth, np.eye(3), mount)
    pipe = IsmnPipeline(camera, mount, RasterMapSource(other), None, NccMatcher())
    fix, diag = pipe.process(frame, 0.0, make_estimate(truth, [0.0, 0.0, 0.0]))
    assert fix is None or fix.quality < 0.15
    assert fix is None and diag.reason
    # A failed attempt keeps its images for the report too (the thumbnail is made after the
    # latency clock stops, on every path that prepared the frame).
    assert diag.frame_thumb is not None and diag.frame_thumb.shape[1] == IsmnParams().thumb_px


def test_relief_orthorectification_uses_elevation(camera, mount, make_estimate):
    """Over a tilted plane (40 m rise across the footprint) the elevation input keeps the fix
    accurate; the frame is rendered on the same tilted plane."""
    from testbench.world.raster import LocalRaster

    summer, winter = procedural_seasons(np.random.default_rng(5), 1200, 4.0)
    n = summer.shape[0]
    north, east = summer.rowcol_to_ne(*np.mgrid[0:n, 0:n])
    slope = 0.02  # 2 % grade towards the east: up to ~50 m over the footprint
    height = (slope * east).astype(np.float32)
    elev = LocalRaster(height, np.ones((n, n), bool), summer.north0_m, summer.east0_m, summer.gsd_m)
    # Render over the tilted plane: it is a plane, so one homography still renders it exactly.
    truth = np.array([0.0, 0.0, -800.0])
    R_nb = euler_to_dcm(np.radians([5.0, 0.0, 0.0]))
    frame = _render_on_plane(summer, camera, mount, truth, R_nb, slope)
    pipe = IsmnPipeline(camera, mount, RasterMapSource(winter), RasterMapSource(elev), NccMatcher())
    fix, diag = pipe.process(frame, 0.0, make_estimate(truth + [10.0, 10.0, 0.0], [5.0, 0.0, 0.0]))
    assert fix is not None, diag.reason
    assert np.hypot(*(fix.pos_ned_m[:2] - truth[:2])) < 3.0


def _render_on_plane(raster, camera, mount, pos, R_nb, slope):
    """Render raster draped on the plane down = -slope * east (ground points (N, E, -slope E))."""
    import cv2

    c, R_nc = camera_pose_ned(pos, R_nb, mount)
    g = raster.gsd_m
    # ground point of raster px (col, row): N = N0 - (row + .5) g, E = E0 + (col + .5) g, D = -slope E
    e0, n0 = raster.east0_m + 0.5 * g, raster.north0_m - 0.5 * g
    M = np.array([[0.0, -g, n0 - c[0]], [g, 0.0, e0 - c[1]], [-slope * g, 0.0, -slope * e0 - c[2]]])
    H = camera.K @ R_nc.T @ M
    return cv2.warpPerspective(raster.data, H, (camera.width_px, camera.height_px), flags=cv2.INTER_LINEAR)


def test_pipeline_waits_for_the_heading(seasons, camera, mount, make_estimate):
    """max_heading_sigma_deg: a frame taken while the heading sigma is above it gives no fix, a
    reason, and is not counted as an attempt; below it the same frame gives a fix."""
    truth = np.array([0.0, 0.0, -800.0])
    frame = render_plane_frame(seasons[0], camera, truth, np.eye(3), mount)
    pipe = _pipeline(seasons, camera, mount, max_heading_sigma_deg=0.1)
    fix, diag = pipe.process(frame, 0.0, make_estimate(truth, [0.0, 0.0, 0.0], sigma_att_deg=0.5))
    assert fix is None and "heading" in diag.reason and diag.attempted is False
    fix, diag = pipe.process(frame, 0.5, make_estimate(truth, [0.0, 0.0, 0.0], sigma_att_deg=0.05))
    assert fix is not None and diag.attempted, diag.reason


def test_image_pose_shows_the_boresight_and_a_seed_with_it_mends_the_fix(seasons, camera, mount, make_estimate):
    """A camera whose true mounting is turned by b = (0.5, -0.4, 0.3) deg (body axes) from its
    calibration, the estimate at the true pose: the image-only pose (pose_from_image), read
    through the calibrated mounting, is the body attitude turned by C b (measurements.
    image_pose's model), to a few hundredths of a degree; its position is the truth. The MAP fix
    of the calibrated seed errs by metres (its prior leans on the wrong camera attitude); seeded
    with the boresight as the navigator would estimate it (NavEstimate.camera_boresight_b_rad),
    it does not (7.1 m against 0.03 m)."""
    import dataclasses

    from testbench.core.camera_geometry import CameraMount
    from testbench.core.rotations import dcm_to_quat, quat_to_rotvec

    truth = np.array([60.0, 40.0, -800.0])
    rpy = [2.0, -1.5, 35.0]
    R_nb = euler_to_dcm(np.radians(rpy))
    b = np.radians([0.5, -0.4, 0.3])
    true_mount = CameraMount(euler_to_dcm(b) @ mount.R_bc, mount.lever_arm_b_m)
    frame = render_plane_frame(seasons[0], camera, truth, R_nb, true_mount)
    est = make_estimate(truth, rpy, sigma_pos_m=5.0, sigma_att_deg=0.05)
    pipe = _pipeline(seasons, camera, mount, pose_from_image=True)
    fix, diag = pipe.process(frame, 1.0, est)
    assert fix is not None, diag.reason
    seen = quat_to_rotvec(dcm_to_quat(fix.image_R_nb @ R_nb.T))
    expected = R_nb @ b  # the boresight turned into NED
    assert np.degrees(np.abs(seen - expected)).max() < 0.02, np.degrees(seen - expected)
    assert np.linalg.norm(fix.image_pos_ned_m - truth) < 1.0
    cov = fix.image_pose_cov
    assert cov.shape == (6, 6) and np.all(np.linalg.eigvalsh(cov) > 0)
    assert np.degrees(np.sqrt(cov[3, 3])) >= pipe.p.attitude_floor_deg
    map_err = np.hypot(*(fix.pos_ned_m - truth)[:2])
    seeded = dataclasses.replace(est, camera_boresight_b_rad=b, cov_camera_boresight_rad2=np.eye(3) * np.radians(0.01) ** 2)
    fix2, diag2 = pipe.process(frame, 1.0, seeded)
    assert fix2 is not None, diag2.reason
    seeded_err = np.hypot(*(fix2.pos_ned_m - truth)[:2])
    assert map_err > 4.0 and seeded_err < 0.5, (map_err, seeded_err)  # measured 7.1 and 0.03 m
    # The image pose does not depend on the seed's mounting (read through the calibrated one).
    assert np.degrees(np.abs(quat_to_rotvec(dcm_to_quat(fix2.image_R_nb @ fix.image_R_nb.T)))).max() < 0.02
