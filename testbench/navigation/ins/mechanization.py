"""Strapdown inertial mechanisation in WGS-84, local-level NED (DESIGN.md, paper eq. 1-2).

State: geodetic latitude L, longitude lambda, height h (rad, rad, m above the ellipsoid),
velocity relative to the Earth in NED v_ned (m/s), attitude q_nb (body FRD -> NED, Hamilton,
scalar first; core/rotations.py conventions).

One IMU interval of length dt with increments dtheta_b = omega_ib_b dt (rad) and
dv_b = f_ib_b dt (m/s), treated as the integrals over the interval (what an IMU outputs):

- coning (attitude) and sculling (velocity) corrections with the previous interval's
  increments (two-sample algorithms, Savage; exact for rates and forces varying linearly
  over the two intervals):
      dtheta_c = dtheta + (1/12) dtheta_prev x dtheta
      dv_c     = dv + 1/2 dtheta x dv + 1/6 dtheta x (dtheta x dv)
                    + (1/12) (dtheta_prev x dv + dv_prev x dtheta);
  (the second-order rotation term makes a constant-rate rotation exact to third order: the
  first-order sculling term is -1/12 dt^3 [w x]^2 f there and needs its +1/6 partner);
- velocity: v+ = v + (I - 1/2 [w_in dt x]) C_nb dv_c + (g - (2 w_ie + w_en) x v) dt
  (Coriolis, transport rate, normal gravity evaluated at the start of the interval);
- position (trapezoidal velocity): h+ = h - vD_avg dt; L+ = L + vN_avg dt / (R_M + h_avg);
  lambda+ = lambda + vE_avg dt / ((R_N + h_avg) cos L_avg);
- attitude: q+ = Exp(-w_in dt) * q * Exp(dtheta_c)  (nav frame turns with w_in = w_ie + w_en,
  body frame with the gyro increment).

`strapdown_step` is pure and vectorised over leading axes; `StrapdownINS` is a thin stateful
wrapper for one vehicle. Both run the same arithmetic (`_step`), written component by
component so that it runs on numpy arrays (many vehicles / Monte Carlo) or on Python floats
(one vehicle at the IMU rate, where numpy's per-call overhead would dominate).
"""

from __future__ import annotations

import math

import numpy as np

from testbench.core import geodesy
from testbench.core.geodesy import A_M, E2, OMEGA_IE_RPS


class _ScalarOps:
    """Python-float backend of `_step`."""

    sin = staticmethod(math.sin)
    cos = staticmethod(math.cos)
    sqrt = staticmethod(math.sqrt)

    @staticmethod
    def sinc_half(a):
        """sin(a/2)/a, with its series near 0."""
        if a < 1e-4:
            return 0.5 - a * a / 48.0
        return math.sin(0.5 * a) / a

    @staticmethod
    def gravity(lat, h):
        return float(geodesy.normal_gravity_mps2(lat, h))


class _ArrayOps:
    """numpy backend of `_step`."""

    sin = staticmethod(np.sin)
    cos = staticmethod(np.cos)
    sqrt = staticmethod(np.sqrt)

    @staticmethod
    def sinc_half(a):
        return 0.5 * np.sinc(a / (2.0 * np.pi))  # np.sinc(x) = sin(pi x)/(pi x)

    @staticmethod
    def gravity(lat, h):
        return geodesy.normal_gravity_mps2(lat, h)


def _cross(a0, a1, a2, b0, b1, b2):
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


def _quat_mul(a, b):
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


def _exp_quat(m, x, y, z):
    """Rotation vector -> unit quaternion (components)."""
    a = m.sqrt(x * x + y * y + z * z)
    k = m.sinc_half(a)
    return (m.cos(0.5 * a), k * x, k * y, k * z)


def _step(m, lat, lon, h, v, q, dth, dv, dth_prev, dv_prev, dt):
    """One mechanisation interval on components. v, dth, dv, ...: 3-tuples; q: 4-tuple."""
    vn, ve, vd = v
    sl, cl = m.sin(lat), m.cos(lat)
    w2 = 1.0 - E2 * sl * sl
    r_n = A_M / m.sqrt(w2)
    r_m = r_n * (1.0 - E2) / w2
    tl = sl / cl
    # Earth rate and transport rate in NED at the start of the interval.
    wie_n, wie_d = OMEGA_IE_RPS * cl, -OMEGA_IE_RPS * sl
    wen_n, wen_e, wen_d = ve / (r_n + h), -vn / (r_m + h), -ve * tl / (r_n + h)
    win = (wie_n + wen_n, wen_e, wie_d + wen_d)
    g = m.gravity(lat, h)

    # Coning and sculling corrections (body frame).
    c = _cross(*dth_prev, *dth)
    dthc = (dth[0] + c[0] / 12.0, dth[1] + c[1] / 12.0, dth[2] + c[2] / 12.0)
    rot = _cross(*dth, *dv)
    rot2 = _cross(*dth, *rot)
    s1 = _cross(*dth_prev, *dv)
    s2 = _cross(*dv_prev, *dth)
    dvb = tuple(dv[i] + 0.5 * rot[i] + rot2[i] / 6.0 + (s1[i] + s2[i]) / 12.0 for i in range(3))

    # Specific-force increment resolved in NED: C_nb(q) dvb, then half the nav-frame turn.
    qw, qx, qy, qz = q
    c00 = 1 - 2 * (qy * qy + qz * qz)
    c01 = 2 * (qx * qy - qw * qz)
    c02 = 2 * (qx * qz + qw * qy)
    c10 = 2 * (qx * qy + qw * qz)
    c11 = 1 - 2 * (qx * qx + qz * qz)
    c12 = 2 * (qy * qz - qw * qx)
    c20 = 2 * (qx * qz - qw * qy)
    c21 = 2 * (qy * qz + qw * qx)
    c22 = 1 - 2 * (qx * qx + qy * qy)
    fn = (
        c00 * dvb[0] + c01 * dvb[1] + c02 * dvb[2],
        c10 * dvb[0] + c11 * dvb[1] + c12 * dvb[2],
        c20 * dvb[0] + c21 * dvb[1] + c22 * dvb[2],
    )
    t = _cross(win[0] * dt, win[1] * dt, win[2] * dt, *fn)
    fn = (fn[0] - 0.5 * t[0], fn[1] - 0.5 * t[1], fn[2] - 0.5 * t[2])

    # Velocity: specific force + gravity - Coriolis/centripetal (2 w_ie + w_en) x v.
    cor = _cross(2.0 * wie_n + wen_n, wen_e, 2.0 * wie_d + wen_d, vn, ve, vd)
    vn1 = vn + fn[0] - cor[0] * dt
    ve1 = ve + fn[1] - cor[1] * dt
    vd1 = vd + fn[2] + (g - cor[2]) * dt

    # Position with the mean velocity over the interval.
    h1 = h - 0.5 * (vd + vd1) * dt
    h_avg = 0.5 * (h + h1)
    dlat = 0.5 * (vn + vn1) * dt / (r_m + h_avg)
    cl_mid = cl - 0.5 * dlat * sl  # cos(L + dL/2) to first order
    lat1 = lat + dlat
    lon1 = lon + 0.5 * (ve + ve1) * dt / ((r_n + h_avg) * cl_mid)

    # Attitude: nav frame turns by w_in dt, body by the coning-corrected increment.
    qn = _exp_quat(m, -win[0] * dt, -win[1] * dt, -win[2] * dt)
    qb = _exp_quat(m, *dthc)
    q1 = _quat_mul(_quat_mul(qn, q), qb)
    norm = m.sqrt(q1[0] ** 2 + q1[1] ** 2 + q1[2] ** 2 + q1[3] ** 2)
    q1 = tuple(x / norm for x in q1)
    return lat1, lon1, h1, (vn1, ve1, vd1), q1


def _split(a, n):
    a = np.asarray(a, float)
    return tuple(a[..., i] for i in range(n))


def strapdown_step(lat_rad, lon_rad, h_m, vel_ned_mps, q_nb_wxyz, dtheta_b_rad, dv_b_mps, dt_s,
                   dtheta_prev_b_rad=None, dv_prev_b_mps=None):
    """Advance the navigation state over one IMU interval (vectorised over leading axes).

    lat_rad, lon_rad, h_m: (...); vel_ned_mps (..., 3); q_nb_wxyz (..., 4);
    dtheta_b_rad, dv_b_mps (..., 3): this interval's angle and velocity increments (body FRD),
        already corrected for sensor biases;
    dt_s: interval length (s), scalar or (...);
    dtheta_prev_b_rad, dv_prev_b_mps (..., 3): previous interval's increments for the coning
        and sculling corrections (None: no correction, e.g. the first sample).
    Returns (lat_rad, lon_rad, h_m, vel_ned_mps (..., 3), q_nb_wxyz (..., 4)).
    """
    zeros = np.zeros(np.shape(dtheta_b_rad))
    dth_prev = zeros if dtheta_prev_b_rad is None else dtheta_prev_b_rad
    dv_prev = zeros if dv_prev_b_mps is None else dv_prev_b_mps
    lat, lon, h, v, q = _step(
        _ArrayOps,
        np.asarray(lat_rad, float),
        np.asarray(lon_rad, float),
        np.asarray(h_m, float),
        _split(vel_ned_mps, 3),
        _split(q_nb_wxyz, 4),
        _split(dtheta_b_rad, 3),
        _split(dv_b_mps, 3),
        _split(dth_prev, 3),
        _split(dv_prev, 3),
        np.asarray(dt_s, float),
    )
    return lat, lon, h, np.stack(np.broadcast_arrays(*v), axis=-1), np.stack(np.broadcast_arrays(*q), axis=-1)


class StrapdownINS:
    """Free-inertial navigator of one vehicle (no aiding), driven by bias-corrected IMU data.

    Holds the state as Python floats and calls the scalar backend of the same arithmetic as
    `strapdown_step`. Units and frames as in the module docstring.
    """

    def __init__(self, t_s: float, lat_rad: float, lon_rad: float, h_m: float,
                 vel_ned_mps, q_nb_wxyz):
        self.t_s = float(t_s)
        self.lat_rad, self.lon_rad, self.h_m = float(lat_rad), float(lon_rad), float(h_m)
        self.vel = tuple(float(x) for x in vel_ned_mps)
        q = np.asarray(q_nb_wxyz, float)
        self.q = tuple(float(x) for x in q / np.linalg.norm(q))
        self._dth_prev = (0.0, 0.0, 0.0)
        self._dv_prev = (0.0, 0.0, 0.0)

    @property
    def vel_ned_mps(self) -> np.ndarray:
        return np.array(self.vel)

    @property
    def q_nb_wxyz(self) -> np.ndarray:
        return np.array(self.q)

    def step_increments(self, dtheta_b_rad, dv_b_mps, dt_s: float) -> None:
        """Advance by one interval with increments (rad, m/s, body FRD) over dt_s."""
        dth = (float(dtheta_b_rad[0]), float(dtheta_b_rad[1]), float(dtheta_b_rad[2]))
        dv = (float(dv_b_mps[0]), float(dv_b_mps[1]), float(dv_b_mps[2]))
        self.lat_rad, self.lon_rad, self.h_m, self.vel, self.q = _step(
            _ScalarOps, self.lat_rad, self.lon_rad, self.h_m, self.vel, self.q,
            dth, dv, self._dth_prev, self._dv_prev, float(dt_s),
        )
        self._dth_prev, self._dv_prev = dth, dv
        self.t_s += float(dt_s)

    def step(self, t_s: float, omega_ib_b_rps, f_ib_b_mps2) -> None:
        """Advance to t_s with the mean rate (rad/s) and specific force (m/s^2) over the interval."""
        dt = float(t_s) - self.t_s
        if dt <= 0.0:
            return
        w, f = omega_ib_b_rps, f_ib_b_mps2
        self.step_increments((w[0] * dt, w[1] * dt, w[2] * dt), (f[0] * dt, f[1] * dt, f[2] * dt), dt)
        self.t_s = float(t_s)
