"""A rolling-shutter camera as scene matching models it: each image row exposed at its own time
(core.camera_geometry.row_delay_s), seen from the pose the estimate's motion gives then.

The frame's pose (the one solved for, and the one the estimate predicts at the frame's time)
is its middle row's. Row v is exposed dt = row_delay_s(v) later; over dt the camera moves by
v_c dt and turns by Exp(omega_n dt), from the estimated velocity and body rate (the motion is
held over the readout: at 0.23 rad/s of yaw and 30 ms the rate's change over a readout is a
microradian). Both the orthorectification (ground -> pixel) and the pose solve (each
correspondence's own pose, pose.PointPoses) use it.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from testbench.core.camera_geometry import PinholeCamera, row_delay_s
from testbench.navigation.ismn.pose import PointPoses


@dataclass(frozen=True)
class RowMotion:
    """The camera's motion over a rolling-shutter readout, as estimated.

    camera: full-resolution intrinsics and distortion (the rows the shutter reads are the
    distorted ones); readout_s: first row to last (s); vel_ned_mps (3,): the camera centre's
    velocity (NED m/s); omega_ned_rps (3,): its angular rate (NED rad/s, R_nc(t + dt) =
    Exp(omega dt) R_nc(t))."""

    camera: PinholeCamera
    readout_s: float
    vel_ned_mps: np.ndarray
    omega_ned_rps: np.ndarray

    def delays_s(self, uv_px: np.ndarray) -> np.ndarray:
        """(N,) exposure delays after the middle row (s) of undistorted full-resolution pixels
        uv_px (N, 2)."""
        return row_delay_s(sensor_rows(self.camera, uv_px), self.camera.height_px, self.readout_s)

    def point_poses(self, uv_px: np.ndarray) -> PointPoses:
        """Each pixel's camera pose relative to the middle row's (pose.PointPoses)."""
        dt = self.delays_s(uv_px)
        turns = Rotation.from_rotvec(dt[:, None] * self.omega_ned_rps).as_matrix() if len(dt) else np.zeros((0, 3, 3))
        return PointPoses(dt[:, None] * self.vel_ned_mps, turns)

    def project(self, centre_ned_m: np.ndarray, R_nc: np.ndarray, P_ned_m: np.ndarray, iterations: int = 3) -> np.ndarray:
        """(N, 2) undistorted full-resolution pixels where the rolling shutter sees the NED
        points P_ned_m (N, 3) (nan behind the camera), the frame's pose (centre, R_nc) the middle
        row's: each point on the row whose own pose sees it there, by fixed-point iteration
        from the middle row's projection (each step shrinks the row's error by about
        readout_s times the image's motion rate in rows per second: 1e-3 in a 30 deg turn)."""
        P = np.asarray(P_ned_m, float)
        c = np.asarray(centre_ned_m, float)
        K = self.camera.K
        dt = np.zeros(len(P))
        uv = np.full((len(P), 2), np.nan)
        for _ in range(iterations + 1):
            d = _rotate(P - c - dt[:, None] * self.vel_ned_mps, -dt[:, None] * self.omega_ned_rps)
            xc = d @ R_nc  # rows: R_cn Exp(-omega dt) (P - c - v dt)
            front = xc[:, 2] > 1e-6
            z = np.where(front, xc[:, 2], 1.0)
            uv = np.c_[K[0, 0] * xc[:, 0] / z + K[0, 2], K[1, 1] * xc[:, 1] / z + K[1, 2]]
            uv[~front] = np.nan
            dt = np.nan_to_num(self.delays_s(np.nan_to_num(uv)))
        return uv


def _rotate(d: np.ndarray, rotvecs: np.ndarray) -> np.ndarray:
    """Rows of d (N, 3) turned by the rotation vectors (N, 3) (Rodrigues)."""
    angle = np.linalg.norm(rotvecs, axis=1, keepdims=True)
    k = rotvecs / np.where(angle > 0.0, angle, 1.0)
    cos, sin = np.cos(angle), np.sin(angle)
    return d * cos + np.cross(k, d) * sin + k * np.sum(k * d, axis=1, keepdims=True) * (1.0 - cos)


def sensor_rows(camera: PinholeCamera, uv_px: np.ndarray) -> np.ndarray:
    """(N,) sensor rows (distorted pixels: the rows the shutter reads) of undistorted pixels
    uv_px (N, 2) of `camera`."""
    uv = np.asarray(uv_px, float).reshape(-1, 2)
    if not camera.has_distortion:
        return uv[:, 1].copy()
    xy = np.c_[(uv[:, 0] - camera.cx) / camera.fx, (uv[:, 1] - camera.cy) / camera.fy, np.ones(len(uv))]
    px, _ = cv2.projectPoints(xy, np.zeros(3), np.zeros(3), camera.K, np.asarray(camera.dist, float))
    return px.reshape(-1, 2)[:, 1]
