"""Bearing and range geometry of relative navigation (DESIGN.md eq. 17-19).

Frames: camera c (OpenCV: x right, y down, z optical axis), body b (FRD), nav n (local NED).
R_bc from the camera mount (camera -> body), R_nb from the vehicle's OWN ESTIMATED attitude
(body -> NED), so R_nc = R_nb R_bc. Relative position r = p_peer - p_self (centres of gravity,
NED, m). The camera's optical centre sits at p_self + R_nb l_cam; the UWB antennas at
p + R_nb l_uwb on each vehicle (the swarm shares one installation, and the peer's attitude,
unknown to us, is taken equal to our own: then the antenna lever arms cancel in the range).
"""

from __future__ import annotations

import cv2
import numpy as np

from testbench.core.camera_geometry import CameraMount, PinholeCamera


def undistort_normalized(camera: PinholeCamera, uv_px) -> np.ndarray:
    """Pixels (n, 2) full-frame -> ideal normalised image coordinates (x/z, y/z), (n, 2).

    Inverts K and the OpenCV distortion model (cv2.undistortPoints, iterative)."""
    uv = np.asarray(uv_px, float).reshape(-1, 1, 2)
    if not camera.has_distortion:
        return np.column_stack([(uv[:, 0, 0] - camera.cx) / camera.fx, (uv[:, 0, 1] - camera.cy) / camera.fy])
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-12)
    out = cv2.undistortPoints(uv, camera.K, np.asarray(camera.dist, float), R=np.eye(3), P=np.eye(3), criteria=crit)
    return out.reshape(-1, 2)


def los_camera(camera: PinholeCamera, uv_px) -> np.ndarray:
    """Unit line-of-sight vectors (n, 3) in the camera frame for full-frame pixels (n, 2):
    K^-1 [u v 1]^T after undistortion, normalised."""
    xy = undistort_normalized(camera, uv_px)
    d = np.column_stack([xy, np.ones(len(xy))])
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def project_relative(camera: PinholeCamera, mount: CameraMount, R_nb: np.ndarray, rel_ned_m) -> tuple[np.ndarray, np.ndarray]:
    """Pixel (n, 2) and camera depth (n,) of neighbours at relative positions rel_ned_m (n, 3).

    Camera frame vector: d_c = R_bc^T R_nb^T (r - R_nb l_cam); pixel through cv2.projectPoints
    (distortion included)."""
    r = np.asarray(rel_ned_m, float).reshape(-1, 3)
    R_nc = np.asarray(R_nb) @ mount.R_bc
    d_c = (r - np.asarray(R_nb) @ mount.lever_arm_b_m) @ R_nc  # rows: R_nc^T d
    uv, _ = cv2.projectPoints(d_c.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), camera.K, np.asarray(camera.dist, float))
    return uv.reshape(-1, 2), d_c[:, 2]


def uwb_range(rel_ned_m, R_nb: np.ndarray, uwb_lever_b_m=(0.0, 0.0, 0.0), peer_R_nb: np.ndarray | None = None) -> float:
    """Antenna-to-antenna range (m) for relative position r (3,): |r + R_nb_peer l - R_nb l|.

    peer_R_nb defaults to our own attitude (the lever arms then cancel)."""
    lever = np.asarray(uwb_lever_b_m, float)
    Rp = np.asarray(R_nb if peer_R_nb is None else peer_R_nb)
    return float(np.linalg.norm(np.asarray(rel_ned_m, float) + Rp @ lever - np.asarray(R_nb) @ lever))


def relative_from_bearing_range(camera: PinholeCamera, mount: CameraMount, R_nb: np.ndarray, uv_px,
                                range_m: float) -> np.ndarray:
    """Neighbour position relative to self (NED, m) from one pixel and one UWB range (eq. 19).

    The line of sight from the camera centre c = R_nb l_cam (relative to our CG) is
    e = R_nb R_bc los_c; the neighbour lies at r = c + s e with s >= 0 chosen so that the
    antenna range |r + (R_nb l_uwb)_peer - R_nb l_uwb| equals range_m. With equal attitudes the
    antenna terms cancel and s solves |c + s e| = rho: s = -c.e + sqrt((c.e)^2 - |c|^2 + rho^2).
    """
    R_nb = np.asarray(R_nb, float)
    e = R_nb @ mount.R_bc @ los_camera(camera, uv_px)[0]
    c = R_nb @ mount.lever_arm_b_m
    ce = float(c @ e)
    disc = ce * ce - float(c @ c) + float(range_m) ** 2
    s = -ce + np.sqrt(max(disc, 0.0))
    return c + s * e
