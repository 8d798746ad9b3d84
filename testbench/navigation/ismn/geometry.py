"""Search-window prediction (DESIGN.md eq. 3-5): where the camera looks and how far to search.

Frames: camera c (OpenCV: x right, y down, z optical axis), body b (FRD), nav n (local NED).
R_nc = R_nb @ R_bc maps camera vectors to NED (core.camera_geometry.camera_pose_ned).
"""

from __future__ import annotations

import numpy as np

from testbench.core.camera_geometry import CameraMount, PinholeCamera, camera_pose_ned
from testbench.core.messages import NavEstimate
from testbench.core.rotations import quat_to_dcm
from testbench.navigation.ismn.types import SearchWindow


def estimate_pose(estimate: NavEstimate) -> tuple[np.ndarray, np.ndarray]:
    """(pos_ned_m (3,), R_nb (3, 3)) of a NavEstimate (attitude from q_nb_wxyz)."""
    return np.asarray(estimate.pos_ned_m, float), quat_to_dcm(np.asarray(estimate.q_nb_wxyz, float))


def rays_to_ground(centre_ned_m, R_nc, K, uv_px, ground_down_m: float, max_off_nadir_rad: float):
    """Intersect camera rays with the horizontal plane down = ground_down_m.

    uv_px (N, 2) undistorted pixel coordinates; returns (ne_m (N, 2), ok (N,) bool), ok False for
    rays that point above max_off_nadir_rad from straight down (towards or above the horizon).
    """
    uv = np.asarray(uv_px, float)
    rays_c = np.linalg.solve(K, np.vstack([uv.T, np.ones(len(uv))]))  # (3, N) camera frame
    rays_n = R_nc @ rays_c  # camera -> NED
    norm = np.linalg.norm(rays_n, axis=0)
    ok = rays_n[2] > np.cos(max_off_nadir_rad) * norm
    height = ground_down_m - centre_ned_m[2]  # > 0 when the camera is above the ground
    s = np.where(ok, height / np.where(ok, rays_n[2], 1.0), np.nan)
    ne = centre_ned_m[:2, None] + s * rays_n[:2]
    return ne.T, ok & (height > 0)


def footprint_bounds(centre_ned_m, R_nc, camera: PinholeCamera, ground_down_m, max_off_nadir_rad, n=9):
    """Bounding box (north_min, north_max, east_min, east_max) of the ground seen through a grid
    of n x n rays over the image (rays beyond max_off_nadir_rad are cut), or None if none hit."""
    us = np.linspace(-0.5, camera.width_px - 0.5, n)
    vs = np.linspace(-0.5, camera.height_px - 0.5, n)
    uu, vv = np.meshgrid(us, vs)
    ne, ok = rays_to_ground(centre_ned_m, R_nc, camera.K, np.c_[uu.ravel(), vv.ravel()],
                            ground_down_m, max_off_nadir_rad)
    if not ok.any():
        return None
    ne = ne[ok]
    return (float(ne[:, 0].min()), float(ne[:, 0].max()), float(ne[:, 1].min()), float(ne[:, 1].max()))


def nadir_gsd_m(camera: PinholeCamera, height_m: float) -> float:
    """Ground sample distance straight below a camera at height_m (m per pixel)."""
    return float(height_m / max(camera.fx, camera.fy))


def predict_search_window(
    estimate: NavEstimate,
    camera: PinholeCamera,
    mount: CameraMount,
    ground_down_m: float,
    gsd_m: float,
    *,
    n_sigma: float = 3.0,
    margin_m: float = 10.0,
    max_off_nadir_rad: float = np.radians(70.0),
) -> SearchWindow | None:
    """The reference-map window for the INS-predicted pose.

    Footprint centre: the optical axis E = R_nc z_c meets the ground at
    p + h (E_N / E_D, E_E / E_D) (eq. 5), h the camera's height above ground_down_m. The window is
    the footprint bounding box grown on every side by n_sigma times the horizontal position
    sigma, plus the footprint shift an n_sigma attitude error causes (h * sigma_tilt / cos^2 of
    the axis' off-nadir angle), plus margin_m. Returns None when the camera sees no ground.
    """
    pos, R_nb = estimate_pose(estimate)
    centre, R_nc = camera_pose_ned(pos, R_nb, mount)
    height = ground_down_m - centre[2]
    if height <= 0:
        return None
    fp = footprint_bounds(centre, R_nc, camera, ground_down_m, max_off_nadir_rad)
    if fp is None:
        return None
    axis_n = R_nc[:, 2]  # optical axis in NED
    if axis_n[2] > 1e-6:
        axis_ground = centre[:2] + height * axis_n[:2] / axis_n[2]
    else:  # axis at or above the horizon: use the footprint centre
        axis_ground = np.array([(fp[0] + fp[1]) / 2, (fp[2] + fp[3]) / 2])
    cov = np.asarray(estimate.cov_pos_ned_m2, float)
    sig_pos = np.sqrt(max(cov[0, 0], cov[1, 1], 0.0))
    cov_att = np.asarray(estimate.cov_att_rad2, float)
    sig_tilt = np.sqrt(max(cov_att[0, 0], cov_att[1, 1], 0.0))
    cos_axis = np.clip(axis_n[2] / np.linalg.norm(axis_n), np.cos(max_off_nadir_rad), 1.0)
    sig_att_m = height * sig_tilt / cos_axis**2
    grow = n_sigma * np.hypot(sig_pos, sig_att_m) + margin_m
    bounds = (fp[0] - grow, fp[1] + grow, fp[2] - grow, fp[3] + grow)
    return SearchWindow(np.asarray(axis_ground, float), fp, bounds, float(grow), float(gsd_m), float(ground_down_m))
