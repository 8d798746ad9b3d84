"""Camera pose from map correspondences (PnP), so that an attitude error does not become a
position error.

Model: a map point X_n (NED, at its terrain height) is seen at the undistorted pixel
u = pi(K R_cn (X_n - c_n)). Unknowns: the camera centre c_n and a small rotation delta of the
camera frame, R_nc = R_nc0 Exp(delta). Solved by Gauss-Newton with
- per-point image covariance from the map-point uncertainty: Sigma_i = J_g sigma_g^2 J_g^T,
  J_g = d u / d (north, east) (a matcher error is an error on the ground, not in the image);
- optionally a prior on the attitude from the INS (cov_att_rad2, NED small angles psi with
  R_nc = Exp(psi) R_nc0): with a good INS attitude the solve leans on it, with a poor one the
  image geometry frees it (MAP estimate);
- one round of outlier rejection (Mahalanobis chi-square, 2 dof, 99.9 %).
A solve that leans on the INS attitude is not independent of the INS: an attitude error of the
filter moves the camera centre the solve returns. The solution says by how much (the sensitivity
of the centre to the prior's mean, M) and what is left once the attitude is known (the
covariance from the image alone), so that a filter can fuse the fix as
fix = c_true - M phi + n, cov(n) = cov_centre_given_att (phi: the filter's attitude error),
instead of as an independent measurement that it would count twice (Bar-Shalom et al. 2001,
sec. 10.4: a measurement correlated with the state).
method "opencv" uses cv2.solvePnP (SOLVEPNP_ITERATIVE seeded with the estimate) instead and only
the covariance from the same Jacobian.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from testbench.core.rotations import dcm_to_euler, heading_sensitivity, quat_to_rotvec, dcm_to_quat, rotvec_to_quat, quat_to_dcm, skew

CHI2_2DOF_999 = 13.8155


@dataclass(frozen=True)
class PoseSolution:
    """centre_ned_m (3,), R_nc (3, 3) camera->NED, cov_centre_m2 (3, 3), cov_att_rad2 (3, 3) (NED
    small angles), inliers (N,) bool, rms_px: post-fit image residual RMS of the inliers.

    With an attitude prior: att_sensitivity_m_per_rad (3, 3), M = d centre / d (prior mean), the
    prior's mean moved by a small NED rotation (rad); cov_centre_given_att_m2 (3, 3), the centre's
    covariance from the image alone (what is left when the prior's error is known). Identity:
    cov_centre_m2 = cov_centre_given_att_m2 + M prior_cov M^T. Without a prior: M = 0 and the two
    covariances are the same."""

    centre_ned_m: np.ndarray
    R_nc: np.ndarray
    cov_centre_m2: np.ndarray
    cov_att_rad2: np.ndarray
    inliers: np.ndarray
    rms_px: float
    att_sensitivity_m_per_rad: np.ndarray
    cov_centre_given_att_m2: np.ndarray
    att_img_ned_rad: np.ndarray | None = None
    """(3,) the camera attitude the image alone gives, as the NED small rotation psi from the
    seed attitude R_nc0 (R_nc_img = Exp(psi) R_nc0): with a prior, one Gauss-Newton step of the
    image's own normal equations from the MAP solution; without, the solution itself. None
    when the image alone does not fix the attitude (singular normal equations)."""
    cov_att_img_rad2: np.ndarray | None = None
    """(3, 3) its covariance (NED small angles), from the image alone: independent of the
    prior, so a filter may fuse it as a measurement of its own attitude."""
    centre_img_ned_m: np.ndarray | None = None
    """(3,) the camera centre of the same image-only solution (NED m); None with att_img_ned_rad."""
    cov_pose_img: np.ndarray | None = None
    """(6, 6) the covariance of the image-only pose [centre (NED m), psi (NED rad)], the
    position-attitude cross terms included (a tilt and a shift of the camera move the points
    near the image centre alike): what a filter fuses when it takes the image's pose as one
    measurement instead of the MAP centre (ismn pose_from_image)."""
    intrinsics_sensitivity: np.ndarray | None = None
    """(3, 3) d centre / d (du, dv, e): how the centre moves (NED m) with an error of the
    intrinsics in K (the true camera has its principal point at (cx + du, cy + dv) px and its
    focal lengths (1 + e) times K's), which moves each observed pixel by
    d uv_i = (du, dv) + e (uv_i - (cx, cy)): A^-1 sum_i J_i^T W_i d uv_i per column, of the
    solve's own normal equations (the prior's included). Over flat ground the principal point's
    columns are a translation of about height / focal per px, so no single image tells a
    principal point error from a shift of the camera; the focal length's is mostly the height."""


def _exp(rotvec):
    return quat_to_dcm(rotvec_to_quat(np.asarray(rotvec, float)))


def _log(R):
    return quat_to_rotvec(dcm_to_quat(R))


def _prior_jacobian(R_nc):
    """d psi / d [dc_n, delta_c] (3, 6): the NED attitude deviation psi (R_nc = Exp(psi) R_nc0)
    moves with the camera-frame increment delta as R_nc, not with the centre."""
    Jpsi = np.zeros((3, 6))
    Jpsi[:, 3:] = R_nc
    return Jpsi


@dataclass(frozen=True)
class PointPoses:
    """Where each point's own camera pose lies from the solve's (a rolling shutter: each image row
    exposed at its own time): point i is seen from the centre c + dc_ned_m[i] with the attitude
    dR_ned[i] @ R_nc, (c, R_nc) the pose solved for. dc_ned_m (N, 3) NED m; dR_ned (N, 3, 3)
    small NED rotations."""

    dc_ned_m: np.ndarray
    dR_ned: np.ndarray

    def take(self, sel) -> "PointPoses":
        return PointPoses(self.dc_ned_m[sel], self.dR_ned[sel])


def _project(K, R_nc, c, X, poses: PointPoses | None = None):
    """(uv (N, 2), x_c (N, 3), R_cn per point (N, 3, 3) or (3, 3)) of NED points X (N, 3)."""
    if poses is None:
        xc = (X - c) @ R_nc  # rows: R_cn (X - c)
        R_cn = R_nc.T
    else:  # x_c = (dR R_nc)^T (X - c - dc)
        R_cn = np.swapaxes(poses.dR_ned @ R_nc, 1, 2)
        xc = np.einsum("nij,nj->ni", R_cn, X - c - poses.dc_ned_m)
    uv = np.c_[K[0, 0] * xc[:, 0] / xc[:, 2] + K[0, 2], K[1, 1] * xc[:, 1] / xc[:, 2] + K[1, 2]]
    return uv, xc, R_cn


def _linearise(K, R_nc, c, X, uv_obs, sigma_ground_m, sigma_img_px, poses: PointPoses | None = None):
    """Residuals, Jacobians (N, 2, 6) for [dc_n, delta_c], per-point information (N, 2, 2)."""
    uv, xc, R_cn = _project(K, R_nc, c, X, poses)
    r = uv_obs - uv
    z = xc[:, 2]
    Jp = np.zeros((len(X), 2, 3))
    Jp[:, 0, 0] = K[0, 0] / z
    Jp[:, 0, 2] = -K[0, 0] * xc[:, 0] / z**2
    Jp[:, 1, 1] = K[1, 1] / z
    Jp[:, 1, 2] = -K[1, 1] * xc[:, 1] / z**2
    J = np.empty((len(X), 2, 6))
    J[:, :, :3] = -Jp @ R_cn  # d x_c / d c_n = -R_cn (each point's own, with a rolling shutter)
    # (dR) R_nc Exp(delta): x_c -> x_c - delta x x_c = x_c + [x_c]x delta
    J[:, :, 3:] = Jp @ skew(xc)
    Jg = Jp @ R_cn[..., :2]  # d uv / d (north, east) of the map point
    S = sigma_ground_m**2 * (Jg @ Jg.transpose(0, 2, 1)) + sigma_img_px**2 * np.eye(2)
    return r, J, _inv_sym2(S)


def _intrinsics_sensitivity(cov: np.ndarray, J: np.ndarray, W: np.ndarray, uv_px: np.ndarray, K: np.ndarray) -> np.ndarray:
    """(3, 3) PoseSolution.intrinsics_sensitivity from the solution's covariance cov (6, 6) and
    the inliers' Jacobians J (N, 2, 6), weights W (N, 2, 2) and pixels uv_px (N, 2)."""
    JtW = J.transpose(0, 2, 1) @ W  # (N, 6, 2)
    centred = uv_px - np.array([K[0, 2], K[1, 2]])
    G = np.c_[JtW.sum(axis=0), np.einsum("nij,nj->i", JtW, centred)]  # (6, 3): du, dv, e
    return (cov @ G)[:3]


def _take(poses: PointPoses | None, sel) -> PointPoses | None:
    return None if poses is None else poses.take(sel)


def _inv_sym2(S: np.ndarray) -> np.ndarray:
    """Inverses of symmetric positive-definite 2 x 2 matrices S (N, 2, 2), in closed form
    (numpy's batched LAPACK inverse costs ~25 us for 50 of them, most of it call overhead)."""
    a, b, d = S[:, 0, 0], S[:, 0, 1], S[:, 1, 1]
    inv = np.empty_like(S)
    det = a * d - b * b
    inv[:, 0, 0] = d / det
    inv[:, 1, 1] = a / det
    inv[:, 0, 1] = inv[:, 1, 0] = -b / det
    return inv


def _normal_equations(J: np.ndarray, W: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(J^T W J (6, 6), J^T W r (6,)) summed over the points: J (N, 2, 6), W (N, 2, 2), r (N, 2).
    One (6, 2N) x (2N, 6) product (a three-operand einsum took ~110 us for 50 points)."""
    JtW = (J.transpose(0, 2, 1) @ W).transpose(1, 0, 2).reshape(6, -1)  # (6, 2N)
    return JtW @ J.reshape(-1, 6), JtW @ r.reshape(-1)


SEED_SHIFT_FRACTION = 0.25
"""A match that places the ground farther from the estimate than this fraction of the camera's
height above it moves the pose solve's seed by that offset (seed_centre). Gauss-Newton from the
estimate diverges once the offset is a few heights (a cold start 4-6 km off at 800 m: solves
landing thousands of km away); below a quarter of the height it converges from either seed to
the same pose, so tracking runs keep the estimate's seed and their records bit for bit."""


def seed_centre(centre_ned_m: np.ndarray, height_m: float, d_north_m: np.ndarray, d_east_m: np.ndarray) -> np.ndarray:
    """(3,) the camera centre (NED, m) solve_camera_pose starts from: the estimate's centre_ned_m,
    moved by the match's horizontal offset when that exceeds SEED_SHIFT_FRACTION of height_m (m
    above ground). The offset is the median over the correspondences of d_north_m, d_east_m (N,):
    where the map places each point minus where the estimate put it."""
    d = np.array([np.median(d_north_m), np.median(d_east_m)])
    if not np.all(np.isfinite(d)) or float(np.hypot(*d)) <= SEED_SHIFT_FRACTION * height_m:
        return centre_ned_m
    return np.asarray(centre_ned_m, float) + np.r_[d, 0.0]


def solve_camera_pose(
    X_ned_m: np.ndarray,
    uv_px: np.ndarray,
    K: np.ndarray,
    centre0_ned_m: np.ndarray,
    R_nc0: np.ndarray,
    sigma_ground_m: float,
    att_prior_cov_rad2: np.ndarray | None = None,
    *,
    sigma_img_px: float = 0.5,
    method: str = "map",
    iterations: int = 8,
    point_poses: PointPoses | None = None,
) -> PoseSolution | None:
    """Camera centre and attitude from N >= 4 correspondences X_ned_m (N, 3) <-> uv_px (N, 2)
    (full-resolution undistorted pixels), seeded with the estimated pose (centre0, R_nc0).
    point_poses: each point's own pose relative to the one solved for (a rolling shutter's
    rows; None: one pose for all, a global shutter)."""
    X = np.asarray(X_ned_m, float)
    uv = np.asarray(uv_px, float)
    if len(X) < 4:
        return None
    c = np.asarray(centre0_ned_m, float).copy()
    R = np.asarray(R_nc0, float).copy()
    inl = np.ones(len(X), bool)
    P_prior_inv = None
    if att_prior_cov_rad2 is not None and method == "map":
        P_prior_inv = np.linalg.inv(np.asarray(att_prior_cov_rad2, float) + 1e-12 * np.eye(3))
    if method == "opencv":
        ref = X.mean(axis=0)
        R_cn = R.T
        rvec0, _ = cv2.Rodrigues(R_cn)
        tvec0 = R_cn @ (ref - c)
        ok, rvec, tvec = cv2.solvePnP(X - ref, uv, K, None, rvec0, tvec0.reshape(3, 1), True, cv2.SOLVEPNP_ITERATIVE)
        if not ok:
            return None
        R_cn = cv2.Rodrigues(rvec)[0]
        R, c = R_cn.T, ref - R_cn.T @ tvec.ravel()
        iterations = 0
    for rnd in range(2):
        for _ in range(iterations):
            r, J, W = _linearise(K, R, c, X[inl], uv[inl], sigma_ground_m, sigma_img_px, _take(point_poses, inl))
            A, b = _normal_equations(J, W, r)
            if P_prior_inv is not None:
                psi = _log(R @ R_nc0.T)  # NED attitude deviation from the INS
                Jpsi = _prior_jacobian(R)
                A += Jpsi.T @ P_prior_inv @ Jpsi
                b += Jpsi.T @ P_prior_inv @ (-psi)
            try:
                dx = np.linalg.solve(A + 1e-9 * np.eye(6), b)
            except np.linalg.LinAlgError:
                return None
            c = c + dx[:3]
            R = R @ _exp(dx[3:])
            if np.linalg.norm(dx[:3]) < 1e-4 and np.linalg.norm(dx[3:]) < 1e-8:
                break
        r, J, W = _linearise(K, R, c, X, uv, sigma_ground_m, sigma_img_px, point_poses)
        d2 = np.einsum("nk,nkl,nl->n", r, W, r)
        new_inl = d2 < CHI2_2DOF_999
        if rnd == 1 or new_inl.sum() < 4 or (new_inl == inl).all():
            break
        inl = new_inl
        if method == "opencv":
            iterations = 8  # refine the inlier set with Gauss-Newton
    r, J, W = _linearise(K, R, c, X[inl], uv[inl], sigma_ground_m, sigma_img_px, _take(point_poses, inl))
    A_img, b_img = _normal_equations(J, W, r)  # information of the image alone
    A = A_img.copy()
    Jpsi = _prior_jacobian(R)
    if P_prior_inv is not None:
        A += Jpsi.T @ P_prior_inv @ Jpsi
    try:
        cov = np.linalg.inv(A + 1e-12 * np.eye(6))
    except np.linalg.LinAlgError:
        return None
    cov_att = R @ cov[3:, 3:] @ R.T
    if P_prior_inv is not None:
        # Moving the prior's mean by mu (NED rad) moves the solution by A^-1 Jpsi^T P^-1 mu; the
        # image's own noise reaches the solution as A^-1 A_img A^-1.
        M = (cov @ Jpsi.T @ P_prior_inv)[:3]
        cov_img = (cov @ A_img @ cov)[:3, :3]
    else:
        M, cov_img = np.zeros((3, 3)), cov[:3, :3]
    img = _image_only_pose(A_img, b_img, c, R, np.asarray(R_nc0, float), cov, P_prior_inv is not None)
    rms = float(np.sqrt(np.mean(np.sum(r**2, axis=1)))) if len(r) else float("nan")
    return PoseSolution(c, R, 0.5 * (cov[:3, :3] + cov[:3, :3].T), cov_att, inl, rms,
                        M, 0.5 * (cov_img + cov_img.T), *img,
                        intrinsics_sensitivity=_intrinsics_sensitivity(cov, J, W, uv[inl], K))


def image_heading(att_img_ned_rad: np.ndarray, cov_att_img_rad2: np.ndarray, R_nb_seed: np.ndarray) -> tuple[float, float]:
    """(heading rad, 1-sigma rad) of the body whose attitude is Exp(psi) R_nb_seed, psi the
    image-only attitude (PoseSolution.att_img_ned_rad, taken about the seed attitude of the
    solve) with covariance cov_att_img_rad2 (3, 3)."""
    R_nb = _exp(np.asarray(att_img_ned_rad, float)) @ np.asarray(R_nb_seed, float)
    h = heading_sensitivity(R_nb)
    return float(dcm_to_euler(R_nb)[2]), float(np.sqrt(max(h @ np.asarray(cov_att_img_rad2, float) @ h, 0.0)))


def _image_only_pose(A_img, b_img, c, R, R_nc0, cov, had_prior: bool):
    """(psi (3,), cov_psi (3, 3), centre (3,), cov_pose (6, 6)) of the pose the image alone gives
    (PoseSolution.att_img_ned_rad, cov_att_img_rad2, centre_img_ned_m, cov_pose_img), all None
    when its normal equations are singular. c, R: the solution; cov (6, 6): its covariance in
    the solve's [dc_n, delta_c] (camera-frame rotation) parameters."""
    if had_prior:
        # The MAP solution balances the image's pull against the prior's; the image's own
        # optimum is one Gauss-Newton step of its normal equations away (the problem is
        # near-linear there).
        try:
            cov = np.linalg.inv(A_img)
        except np.linalg.LinAlgError:
            return None, None, None, None
        step = cov @ b_img
        if not (np.all(np.isfinite(step)) and np.all(np.isfinite(cov))):
            return None, None, None, None
        c, R_img = c + step[:3], R @ _exp(step[3:])
    else:
        R_img = R
    # delta_c (R_nc Exp(delta)) is psi = R delta in NED (Exp(psi) R_nc).
    cov_att = R @ cov[3:, 3:] @ R.T
    cov_pose = np.empty((6, 6))
    cov_pose[:3, :3] = cov[:3, :3]
    cov_pose[:3, 3:] = cov[:3, 3:] @ R.T
    cov_pose[3:, :3] = cov_pose[:3, 3:].T
    cov_pose[3:, 3:] = cov_att
    cov_pose = 0.5 * (cov_pose + cov_pose.T)
    return _log(R_img @ R_nc0.T), 0.5 * (cov_att + cov_att.T), c.copy(), cov_pose
