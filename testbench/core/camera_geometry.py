"""Pinhole camera geometry shared by the renderer (sensors) and scene matching (navigation).

Frames (write the frame change next to every rotation):
- camera c: OpenCV convention, x right, y down, z along the optical axis;
- body b: FRD; R_bc maps camera vectors to body vectors (v_b = R_bc @ v_c);
- nav n: local NED; R_nb from the vehicle attitude.
A nadir camera (mount pitch -90 deg) has R_bc = [[0,-1,0],[1,0,0],[0,0,1]]: image right x_c
is the right wing (body y), image down y_c points aft (body -x), the optical axis is body z.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from testbench.core.rotations import euler_to_dcm

# Camera axes expressed in body axes for a camera looking along body +x (forward), zero
# mounting angles: optical axis z_c = x_b, image right x_c = y_b (right wing), image down
# y_c = z_b (down). Columns are the camera axes in body coordinates: v_b = R_B_C0 @ v_c.
R_B_C0 = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def mount_rotation(roll_deg: float, pitch_deg: float, yaw_deg: float) -> np.ndarray:
    """R_bc (camera -> body) for a camera mounted with Z-Y-X angles relative to body axes.

    Zero angles: the camera looks forward along body x with the image top up. Pitch -90 deg
    points it straight down (nadir) with the image top towards the nose; yaw 90 deg looks
    right (starboard), yaw -90 deg left. The angles rotate a "camera body" frame whose x is the
    optical axis; R_bc = R(rpy) @ R_B_C0.
    """
    rpy = np.radians([roll_deg, pitch_deg, yaw_deg])
    return euler_to_dcm(rpy) @ R_B_C0


@dataclass(frozen=True)
class PinholeCamera:
    """Intrinsics and lens distortion (OpenCV model) of one camera.

    width_px, height_px: image size; fx, fy, cx, cy in pixels (pixel centres at integers);
    dist: (k1, k2, p1, p2, k3) in OpenCV order.
    """

    width_px: int
    height_px: int
    fx: float
    fy: float
    cx: float
    cy: float
    dist: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)

    @classmethod
    def from_hfov(cls, width_px: int, height_px: int, hfov_deg: float, dist=(0.0,) * 5) -> "PinholeCamera":
        """Square pixels, principal point at the image centre, focal length from the
        horizontal field of view: fx = (W/2) / tan(hfov/2)."""
        f = 0.5 * width_px / np.tan(np.radians(hfov_deg) / 2.0)
        return cls(width_px, height_px, f, f, (width_px - 1) / 2.0, (height_px - 1) / 2.0, tuple(dist))

    @property
    def K(self) -> np.ndarray:
        """3x3 intrinsic matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def has_distortion(self) -> bool:
        return any(abs(d) > 0.0 for d in self.dist)


@dataclass(frozen=True)
class CameraMount:
    """Where a camera sits on the body: R_bc (camera -> body), lever arm of the optical centre
    from the centre of gravity in body axes (m)."""

    R_bc: np.ndarray
    lever_arm_b_m: np.ndarray


def camera_pose_ned(pos_ned_m, R_nb, mount: CameraMount) -> tuple[np.ndarray, np.ndarray]:
    """Camera optical centre in NED (m) and R_nc (camera -> NED) from the vehicle pose.

    R_nc = R_nb @ R_bc; the lever arm is rotated into NED with the vehicle attitude.
    """
    R_nc = np.asarray(R_nb) @ mount.R_bc
    centre = np.asarray(pos_ned_m, float) + np.asarray(R_nb) @ mount.lever_arm_b_m
    return centre, R_nc


def row_delay_s(v_px, height_px: int, readout_s: float):
    """Exposure time of image row(s) v_px (pixel rows, the first row 0; fractional rows allowed)
    after the frame's middle row (s), for a rolling shutter reading the rows out over readout_s
    (the first row first; the frame's time and stamp are its middle row's):
    readout_s * ((v + 0.5) / height_px - 0.5), negative for the rows above the middle."""
    return readout_s * ((np.asarray(v_px, float) + 0.5) / float(height_px) - 0.5)
