"""Rotation helpers: Euler angles, direction cosine matrices and quaternions.

Convention (stated once, used everywhere):
- R_ab is the DCM that maps a vector resolved in frame b to frame a: v_a = R_ab @ v_b.
  R_nb maps body (FRD) to local navigation (NED).
- Euler angles are aerospace Z-Y-X (yaw psi, then pitch theta, then roll phi), given as
  rpy = (roll, pitch, yaw) in radians: R_nb = Rz(psi) @ Ry(theta) @ Rx(phi).
- Quaternions are Hamilton, scalar first, q = (w, x, y, z); q_nb rotates body vectors to nav:
  v_n = q_nb * v_b * conj(q_nb). Quaternion products are Hamilton: q_ac = q_ab * q_bc.

All functions are vectorised over leading axes: rpy (..., 3), q (..., 4), R (..., 3, 3).
"""

from __future__ import annotations

import numpy as np


def skew(v):
    """Skew-symmetric cross-product matrix [v x], shape (..., 3, 3), so skew(a) @ b = a x b."""
    v = np.asarray(v, float)
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1] = -v[..., 2]
    out[..., 0, 2] = v[..., 1]
    out[..., 1, 0] = v[..., 2]
    out[..., 1, 2] = -v[..., 0]
    out[..., 2, 0] = -v[..., 1]
    out[..., 2, 1] = v[..., 0]
    return out


def euler_to_dcm(rpy_rad):
    """Z-Y-X Euler angles (roll, pitch, yaw) -> R_nb (body to nav), shape (..., 3, 3)."""
    rpy = np.asarray(rpy_rad, float)
    cr, sr = np.cos(rpy[..., 0]), np.sin(rpy[..., 0])
    cp, sp = np.cos(rpy[..., 1]), np.sin(rpy[..., 1])
    cy, sy = np.cos(rpy[..., 2]), np.sin(rpy[..., 2])
    out = np.empty(rpy.shape[:-1] + (3, 3))
    out[..., 0, 0] = cp * cy
    out[..., 0, 1] = sr * sp * cy - cr * sy
    out[..., 0, 2] = cr * sp * cy + sr * sy
    out[..., 1, 0] = cp * sy
    out[..., 1, 1] = sr * sp * sy + cr * cy
    out[..., 1, 2] = cr * sp * sy - sr * cy
    out[..., 2, 0] = -sp
    out[..., 2, 1] = sr * cp
    out[..., 2, 2] = cr * cp
    return out


def dcm_to_euler(R_nb):
    """R_nb (body to nav) -> Z-Y-X Euler angles (roll, pitch, yaw) in rad, shape (..., 3).

    Yaw is in (-pi, pi]; pitch is clipped into [-pi/2, pi/2] against rounding.
    """
    R = np.asarray(R_nb, float)
    roll = np.arctan2(R[..., 2, 1], R[..., 2, 2])
    pitch = -np.arcsin(np.clip(R[..., 2, 0], -1.0, 1.0))
    yaw = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    return np.stack([roll, pitch, yaw], axis=-1)


def quat_normalize(q):
    """Unit quaternion with a non-negative scalar part, shape (..., 4)."""
    q = np.asarray(q, float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0.0, -q, q)


def quat_multiply(q1, q2):
    """Hamilton product q1 * q2 (both scalar first), shape (..., 4)."""
    q1 = np.asarray(q1, float)
    q2 = np.asarray(q2, float)
    if q1.shape == (4,) and q2.shape == (4,):
        # Two single quaternions: the same arithmetic on Python floats (bit-identical, faster).
        w1, x1, y1, z1 = q1.tolist()
        w2, x2, y2, z2 = q2.tolist()
        return np.array([
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ])
    w1, x1, y1, z1 = np.moveaxis(q1, -1, 0)
    w2, x2, y2, z2 = np.moveaxis(q2, -1, 0)
    return np.stack(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ],
        axis=-1,
    )


def quat_conjugate(q):
    """Conjugate (inverse for a unit quaternion), shape (..., 4)."""
    q = np.asarray(q, float)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_to_dcm(q_nb):
    """Unit quaternion q_nb -> R_nb (body to nav), shape (..., 3, 3)."""
    q = np.asarray(q_nb, float)
    if q.shape == (4,):
        # One quaternion (the per-step case in navigation and control): the same arithmetic on
        # Python floats, bit-identical and about ten times faster than the array path.
        w, x, y, z = q.tolist()
        return np.array([
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ])
    w, x, y, z = np.moveaxis(q, -1, 0)
    out = np.empty(q.shape[:-1] + (3, 3))
    out[..., 0, 0] = 1 - 2 * (y * y + z * z)
    out[..., 0, 1] = 2 * (x * y - w * z)
    out[..., 0, 2] = 2 * (x * z + w * y)
    out[..., 1, 0] = 2 * (x * y + w * z)
    out[..., 1, 1] = 1 - 2 * (x * x + z * z)
    out[..., 1, 2] = 2 * (y * z - w * x)
    out[..., 2, 0] = 2 * (x * z - w * y)
    out[..., 2, 1] = 2 * (y * z + w * x)
    out[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return out


def dcm_to_quat(R_nb):
    """R_nb -> unit quaternion q_nb (scalar first, w >= 0), shape (..., 4).

    Shepperd's method: picks the numerically largest of w, x, y, z to divide by.
    """
    R = np.asarray(R_nb, float)
    tr = R[..., 0, 0] + R[..., 1, 1] + R[..., 2, 2]
    cand = np.stack([tr, R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]], axis=-1)
    k = np.argmax(cand, axis=-1)
    q = np.empty(R.shape[:-2] + (4,))
    # Each branch computes all four components from the largest one.
    s = np.sqrt(np.maximum(1.0 + 2.0 * np.take_along_axis(cand, k[..., None], -1)[..., 0] - tr, 1e-300))
    r21, r12 = R[..., 2, 1], R[..., 1, 2]
    r02, r20 = R[..., 0, 2], R[..., 2, 0]
    r10, r01 = R[..., 1, 0], R[..., 0, 1]
    w = np.where(k == 0, 0.5 * s, np.where(k == 1, (r21 - r12) / (2 * s), np.where(k == 2, (r02 - r20) / (2 * s), (r10 - r01) / (2 * s))))
    x = np.where(k == 0, (r21 - r12) / (2 * s), np.where(k == 1, 0.5 * s, np.where(k == 2, (r01 + r10) / (2 * s), (r02 + r20) / (2 * s))))
    y = np.where(k == 0, (r02 - r20) / (2 * s), np.where(k == 1, (r01 + r10) / (2 * s), np.where(k == 2, 0.5 * s, (r12 + r21) / (2 * s))))
    z = np.where(k == 0, (r10 - r01) / (2 * s), np.where(k == 1, (r02 + r20) / (2 * s), np.where(k == 2, (r12 + r21) / (2 * s), 0.5 * s)))
    q[..., 0], q[..., 1], q[..., 2], q[..., 3] = w, x, y, z
    return quat_normalize(q)


def euler_to_quat(rpy_rad):
    """Z-Y-X Euler angles (roll, pitch, yaw) -> q_nb, shape (..., 4)."""
    rpy = np.asarray(rpy_rad, float)
    hr, hp, hy = 0.5 * rpy[..., 0], 0.5 * rpy[..., 1], 0.5 * rpy[..., 2]
    cr, sr, cp, sp, cy, sy = np.cos(hr), np.sin(hr), np.cos(hp), np.sin(hp), np.cos(hy), np.sin(hy)
    q = np.stack(
        [
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ],
        axis=-1,
    )
    return quat_normalize(q)


def quat_to_euler(q_nb):
    """q_nb -> Z-Y-X Euler angles (roll, pitch, yaw) in rad, shape (..., 3)."""
    return dcm_to_euler(quat_to_dcm(q_nb))


def rotvec_to_quat(rotvec_rad):
    """Rotation vector (axis * angle, rad) -> unit quaternion, shape (..., 4).

    Uses the series form for small angles so that a zero vector maps exactly to identity.
    """
    v = np.asarray(rotvec_rad, float)
    angle = np.linalg.norm(v, axis=-1, keepdims=True)
    half = 0.5 * angle
    small = angle < 1e-8
    k = np.where(small, 0.5 - angle**2 / 48.0, np.sin(half) / np.where(small, 1.0, angle))
    return np.concatenate([np.cos(half), k * v], axis=-1)


def quat_to_rotvec(q):
    """Unit quaternion -> rotation vector (rad), shape (..., 3); angle in [0, pi]."""
    q = quat_normalize(q)
    vec = q[..., 1:]
    s = np.linalg.norm(vec, axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(s, q[..., :1])
    small = s < 1e-12
    k = np.where(small, 2.0, angle / np.where(small, 1.0, s))
    return k * vec


def rot_x(angle_rad):
    """Frame-rotation DCM about x: maps vectors of the rotated frame to the original one."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle_rad):
    """DCM about y (see rot_x for the sense)."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle_rad):
    """DCM about z (see rot_x for the sense)."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def wrap_pi(angle_rad):
    """Wrap angles into [-pi, pi)."""
    return (np.asarray(angle_rad, float) + np.pi) % (2.0 * np.pi) - np.pi


def heading_sensitivity(R_nb) -> np.ndarray:
    """d yaw / d phi (3,) for R_nb perturbed on the NED side, R' = Exp(phi) R_nb (phi: NED small
    angles, rad): a rotation about down moves the yaw one for one, and one about north or east
    moves it by as much as the body's x axis leans out of the horizontal."""
    C = np.asarray(R_nb, float)
    d = C[0, 0] ** 2 + C[1, 0] ** 2
    return np.array([-C[0, 0] * C[2, 0] / d, -C[1, 0] * C[2, 0] / d, 1.0])
