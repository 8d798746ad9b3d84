"""Strapdown INS: static invariants, coning/sculling, bias error growth, Schuler period."""

from __future__ import annotations

import math

import numpy as np
import pytest
from ins_sim import static_imu

from testbench.core import geodesy
from testbench.core.rotations import (
    euler_to_quat,
    quat_multiply,
    quat_to_dcm,
    quat_to_euler,
    rotvec_to_quat,
)
from testbench.navigation.ins.error_model import nav_error
from testbench.navigation.ins.mechanization import StrapdownINS, strapdown_step

LAT, LON, H = math.radians(47.0), math.radians(-97.0), 800.0


def test_static_ins_stays_still():
    q = euler_to_quat(np.radians([5.0, -3.0, 120.0]))
    ins = StrapdownINS(0.0, LAT, LON, H, [0, 0, 0], q)
    w, f = static_imu(LAT, H, q)
    dt = 0.01
    for k in range(6000):  # 60 s at 100 Hz
        ins.step((k + 1) * dt, w, f)
    err = nav_error(ins.lat_rad, ins.lon_rad, ins.h_m, ins.vel, ins.q, LAT, LON, H, np.zeros(3), q)
    assert np.all(np.abs(err[:3]) < 1e-6)  # m
    assert np.all(np.abs(err[3:6]) < 1e-7)  # m/s
    assert np.all(np.abs(err[6:9]) < 1e-10)  # rad


def test_vectorised_step_matches_scalar_class():
    rng = np.random.default_rng(1)
    n = 5
    lat = rng.uniform(-1.2, 1.2, n)
    lon = rng.uniform(-3, 3, n)
    h = rng.uniform(0, 3000, n)
    v = rng.normal(0, 40, (n, 3))
    q = rotvec_to_quat(rng.normal(0, 1, (n, 3)))
    dth, dv = rng.normal(0, 0.02, (n, 3)), rng.normal(0, 0.1, (n, 3))
    dthp, dvp = rng.normal(0, 0.02, (n, 3)), rng.normal(0, 0.1, (n, 3))
    out = strapdown_step(lat, lon, h, v, q, dth, dv, 0.01, dthp, dvp)
    for i in range(n):
        ins = StrapdownINS(0.0, lat[i], lon[i], h[i], v[i], q[i])
        ins._dth_prev, ins._dv_prev = tuple(dthp[i]), tuple(dvp[i])
        ins.step_increments(dth[i], dv[i], 0.01)
        np.testing.assert_allclose([ins.lat_rad, ins.lon_rad, ins.h_m], [out[0][i], out[1][i], out[2][i]], rtol=0, atol=1e-12)
        np.testing.assert_allclose(ins.vel, out[3][i], atol=1e-11)
        np.testing.assert_allclose(ins.q, out[4][i], atol=1e-14)


def _spinning_increments(q0, omega_b, lat, h, dt, n, gauss=3):
    """Exact (Gauss-Legendre) increments of a vehicle at rest on the Earth whose attitude turns
    at a constant body rate omega_b relative to NED: C_nb(t) = C_nb(0) Exp(omega_b t)."""
    xg, wg = np.polynomial.legendre.leggauss(gauss)
    wie = geodesy.earth_rate_ned_rps(lat)
    f_n = -geodesy.gravity_ned_mps2(lat, h)
    dth, dv = np.zeros((n, 3)), np.zeros((n, 3))
    for k in range(n):
        for x, wgt in zip(xg, wg):
            t = (k + 0.5 + 0.5 * x) * dt
            C_bn = quat_to_dcm(quat_multiply(q0, rotvec_to_quat(omega_b * t))).T
            dth[k] += 0.5 * wgt * dt * (omega_b + C_bn @ wie)
            dv[k] += 0.5 * wgt * dt * (C_bn @ f_n)
    return dth, dv


def _rotation_at_rest_errors(use_corrections: bool):
    q0 = euler_to_quat(np.radians([10.0, 20.0, 30.0]))
    omega_b = np.array([0.6, -0.5, 0.6])
    dt, n = 0.01, 2000  # 20 s
    dth, dv = _spinning_increments(q0, omega_b, LAT, H, dt, n)
    ins = StrapdownINS(0.0, LAT, LON, H, [0, 0, 0], q0)
    for k in range(n):
        if not use_corrections:
            ins._dth_prev = ins._dv_prev = (0.0, 0.0, 0.0)
        ins.step_increments(dth[k], dv[k], dt)
    q_true = quat_multiply(q0, rotvec_to_quat(omega_b * n * dt))
    err = nav_error(ins.lat_rad, ins.lon_rad, ins.h_m, ins.vel, ins.q, LAT, LON, H, np.zeros(3), q_true)
    return np.linalg.norm(err[:3]), np.linalg.norm(err[6:9])


def test_constant_rate_rotation_at_rest():
    """A vehicle rotating at 1 rad/s about a tilted body axis while at rest, 20 s at 100 Hz:
    with the coning/sculling corrections the INS holds position to a millimetre and the
    attitude to 1e-8 rad; dropping the two-sample terms costs over ten times more."""
    pos_err, att_err = _rotation_at_rest_errors(True)
    pos_err_plain, _ = _rotation_at_rest_errors(False)
    assert pos_err < 1e-3
    assert att_err < 1e-8
    assert pos_err_plain > 10 * pos_err


def test_accelerometer_bias_error_growth():
    """A north accelerometer bias b on a level, north-facing INS: dp_N = b t^2 / 2 (t << Schuler)."""
    q = np.array([1.0, 0, 0, 0])
    w, f = static_imu(LAT, H, q)
    b = 1e-3
    ins = StrapdownINS(0.0, LAT, LON, H, [0, 0, 0], q)
    dt, T = 0.01, 60.0
    for k in range(int(T / dt)):
        ins.step((k + 1) * dt, w, f + np.array([b, 0, 0]))
    err = nav_error(ins.lat_rad, ins.lon_rad, ins.h_m, ins.vel, ins.q, LAT, LON, H, np.zeros(3), q)
    # nav_error(estimate, truth) = estimate (-) truth
    assert err[0] == pytest.approx(0.5 * b * T**2, rel=2e-3)
    assert err[3] == pytest.approx(b * T, rel=2e-3)


def test_gyro_bias_tilt_error_growth():
    """A roll-axis gyro bias b tilts the INS by b t; the tilt resolves gravity into a spurious
    east acceleration g b t, so the east error grows as g b t^3 / 6."""
    q = np.array([1.0, 0, 0, 0])
    w, f = static_imu(LAT, H, q)
    b = math.radians(10.0) / 3600.0  # 10 deg/h
    ins = StrapdownINS(0.0, LAT, LON, H, [0, 0, 0], q)
    dt, T = 0.01, 60.0
    for k in range(int(T / dt)):
        ins.step((k + 1) * dt, w + np.array([b, 0, 0]), f)
    roll = quat_to_euler(np.array(ins.q))[0]
    assert roll == pytest.approx(b * T, rel=1e-2)
    g = float(geodesy.normal_gravity_mps2(LAT, H))
    east_est_m = nav_error(ins.lat_rad, ins.lon_rad, ins.h_m, ins.vel, ins.q, LAT, LON, H, np.zeros(3), q)[1]
    assert east_est_m == pytest.approx(g * b * T**3 / 6.0, rel=2e-2)


def test_schuler_period():
    """Free-inertial run (1 Hz, vertical channel held as a barometer would) with a 0.1 m/s
    north velocity error: the error oscillates with the Schuler period 2 pi sqrt(R/g)."""
    q = np.array([1.0, 0, 0, 0])
    w, f = static_imu(LAT, H, q)
    ins = StrapdownINS(0.0, LAT, LON, H, [0.1, 0, 0], q)
    dt, n = 1.0, 7000
    vn = np.empty(n)
    for k in range(n):
        ins.step((k + 1) * dt, w, f)
        ins.h_m, ins.vel = H, (ins.vel[0], ins.vel[1], 0.0)  # damp the unstable vertical channel
        vn[k] = ins.vel[0]
    t = (np.arange(n) + 1) * dt
    s = np.sign(vn)
    idx = np.nonzero(s[1:] != s[:-1])[0]
    # Linear interpolation of the zero crossings; successive crossings are half a period apart.
    tz = t[idx] - vn[idx] * dt / (vn[idx + 1] - vn[idx])
    assert len(tz) >= 2
    period = 2.0 * np.mean(np.diff(tz))
    r_m, r_n = geodesy.radii_of_curvature(LAT)
    g = float(geodesy.normal_gravity_mps2(LAT, H))
    expected = 2 * math.pi * math.sqrt((math.sqrt(r_m * r_n) + H) / g)
    assert abs(expected / 60.0 - 84.4) < 0.5  # the textbook 84.4 min
    assert period == pytest.approx(expected, rel=1e-2)
    # Amplitude of the position error: v0 / omega_s.
    assert np.max(np.abs(vn)) == pytest.approx(0.1, rel=2e-2)
