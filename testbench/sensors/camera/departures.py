"""What a camera truly is and does, against what navigation is given: its mounting turned by a
boresight error (`misaligned`), its intrinsics off their calibration (`miscalibrated`), and the
pose it truly saw from when its clock is off (`exposure_pose`). CameraSensor renders with these;
navigation gets the calibrated mounting and intrinsics and the frame's stamp."""

from __future__ import annotations

import numpy as np

from testbench.core.camera_geometry import CameraMount, PinholeCamera
from testbench.core.messages import TruthState
from testbench.core.rotations import euler_to_dcm, quat_to_dcm, rotvec_to_quat
from testbench.core.units import STANDARD_GRAVITY_MPS2

__all__ = ["exposure_pose", "misaligned", "miscalibrated"]


def miscalibrated(camera: PinholeCamera, error: tuple[float, float, float]) -> PinholeCamera:
    """The true intrinsics of a calibrated camera: focal lengths scaled by 1 + error[0], the
    principal point moved by (error[1], error[2]) px; the same size and lens distortion."""
    focal, du, dv = error
    if not (focal or du or dv):
        return camera
    return PinholeCamera(camera.width_px, camera.height_px, camera.fx * (1.0 + focal), camera.fy * (1.0 + focal),
                         camera.cx + du, camera.cy + dv, tuple(camera.dist))


def misaligned(mount: CameraMount, error_rpy_deg: np.ndarray) -> CameraMount:
    """The mounting turned by a boresight error: R_bc_true = R_err R_bc, R_err the Z-Y-X rotation
    by error_rpy_deg (3,) about the body axes (deg); the lever arm is unchanged. Body axes rather
    than the mounting angles because a nadir camera (pitch -90 deg) is gimbal-locked in those."""
    if not np.any(error_rpy_deg):
        return mount
    return CameraMount(euler_to_dcm(np.radians(error_rpy_deg)) @ mount.R_bc, mount.lever_arm_b_m)


def exposure_pose(truth: TruthState, time_offset_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The vehicle's true position (3,) NED m at the origin and attitude R_nb (3, 3) body -> NED
    at time_offset_s before the tick's truth (a frame stamped at the tick but exposed earlier;
    negative: later). Extrapolated from the tick's state: the position to second order (its
    velocity, and the acceleration its specific force and standard gravity give), the attitude
    by the body rate held over the offset; over 0.1 s in a 30 deg bank turn that errs by under
    a millimetre and a microradian (the jerk's and the rate's change). Offset 0: the tick's pose."""
    R_nb = quat_to_dcm(truth.q_nb_wxyz)
    if time_offset_s == 0.0:
        return truth.pos_ned_m, R_nb
    dt = -float(time_offset_s)
    acc_n = R_nb @ np.asarray(truth.f_b_mps2, float) + np.array([0.0, 0.0, STANDARD_GRAVITY_MPS2])
    pos = np.asarray(truth.pos_ned_m, float) + np.asarray(truth.vel_ned_mps, float) * dt + 0.5 * acc_n * dt * dt
    return pos, R_nb @ quat_to_dcm(rotvec_to_quat(np.asarray(truth.omega_eb_b_rps, float) * dt))
