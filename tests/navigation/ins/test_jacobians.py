"""Analytic F and H of the error-state EKF vs central finite differences of the nonlinear
mechanisation and measurement functions."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from testbench.core import geodesy
from testbench.core.interfaces import GeodeticOrigin
from testbench.core.rotations import euler_to_quat, quat_multiply, quat_to_dcm, rotvec_to_quat
from testbench.navigation.ins import measurements as meas
from testbench.navigation.ins.ekf import ErrorStateEKF
from testbench.navigation.ins.error_model import IA, N_CORE, N_STATES, continuous_F, inject_nav, nav_error
from testbench.navigation.ins.imu_noise import imu_noise_from_datasheet

TAU_G, TAU_A = 300.0, 200.0


def _derivative(x, w_meas, f_meas):
    """Nonlinear continuous dynamics: returns a function s -> state advanced by s along the flow
    (first order, which is all a central difference in s needs)."""
    lat, lon, h, v, q, bg, ba = x
    w_ib = w_meas - bg
    f_b = f_meas - ba
    r_m, r_n = geodesy.radii_of_curvature(lat)
    wie = geodesy.earth_rate_ned_rps(lat)
    wen = geodesy.transport_rate_ned_rps(lat, h, v)
    C = quat_to_dcm(q)
    v_dot = C @ f_b - np.cross(2 * wie + wen, v) + geodesy.gravity_ned_mps2(lat, h)
    lat_dot = v[0] / (r_m + h)
    lon_dot = v[1] / ((r_n + h) * math.cos(lat))
    h_dot = -v[2]

    def advance(s):
        q_s = quat_multiply(quat_multiply(rotvec_to_quat(-(wie + wen) * s), q), rotvec_to_quat(w_ib * s))
        return (lat + lat_dot * s, lon + lon_dot * s, h + h_dot * s, v + v_dot * s, q_s,
                bg * math.exp(-s / TAU_G), ba * math.exp(-s / TAU_A))

    return advance


def _error(x, x_ref):
    e = np.empty(N_CORE)
    e[:9] = nav_error(*x[:5], *x_ref[:5])
    e[9:12] = x[5] - x_ref[5]
    e[12:15] = x[6] - x_ref[6]
    return e


def _inject(x, dx):
    lat, lon, h, v, q = inject_nav(*x[:5], dx)
    return (lat, lon, h, v, q, x[5] + dx[9:12], x[6] + dx[12:15])


def _error_rate(x_hat, dx, w_meas, f_meas, s=1e-2):
    x = _inject(x_hat, dx)
    adv, adv_hat = _derivative(x, w_meas, f_meas), _derivative(x_hat, w_meas, f_meas)
    return (_error(adv(s), adv_hat(s)) - _error(adv(-s), adv_hat(-s))) / (2 * s)


def test_F_matches_finite_differences():
    x_hat = (0.7, -1.6, 1200.0, np.array([40.0, -25.0, 3.0]), euler_to_quat(np.radians([8.0, -4.0, 140.0])),
             np.radians([3.0, -2.0, 5.0]) / 3600, np.array([2e-3, -1e-3, 3e-3]))
    w_meas = np.array([0.1, -0.05, 0.2])
    f_meas = np.array([0.5, -0.3, -9.5])
    steps = np.array([1.0] * 3 + [0.01] * 3 + [1e-4] * 3 + [1e-6] * 3 + [1e-3] * 3)
    F_num = np.empty((N_CORE, N_CORE))
    for j in range(N_CORE):
        d = np.zeros(N_CORE)
        d[j] = steps[j]
        F_num[:, j] = (_error_rate(x_hat, d, w_meas, f_meas) - _error_rate(x_hat, -d, w_meas, f_meas)) / (2 * steps[j])
    C = quat_to_dcm(x_hat[4])
    F = continuous_F(x_hat[0], x_hat[2], x_hat[3], C, C @ (f_meas - x_hat[6]), TAU_G, TAU_A)[:N_CORE, :N_CORE]
    # Absolute tolerance per column: the FD resolution of each perturbation size, and the
    # neglected e^2-sized terms (dR/dL, dg/dL), all below 1e-7 in position-derived entries.
    np.testing.assert_allclose(F, F_num, rtol=1e-4, atol=2e-7)
    # The small terms are there, not just within the tolerance of zero.
    assert F[5, 2] == pytest.approx(F_num[5, 2], rel=1e-2)  # gravity gradient ~3e-6 /s^2
    assert abs(F_num[6, 0]) > 1e-12 and F[6, 0] == pytest.approx(F_num[6, 0], rel=1e-2)


def _ekf_at(x_hat):
    noise = imu_noise_from_datasheet(0.15, 7.0, 0.02, 14.0)
    ekf = ErrorStateEKF(noise, wind_states=True)  # every column, the wind's too
    lat, lon, h, v, q = x_hat
    ekf.initialize(0.0, lat, lon, h, v, q, np.eye(N_STATES))
    ekf.b_gnss = np.array([0.7, -0.4, 1.1])
    ekf.b_fix = np.array([-0.3, 0.8, 0.2])
    ekf.b_baro = 1.5
    ekf.drag_scale = 0.02
    ekf.wind_ne_mps = np.array([4.0, -6.0])
    return ekf


def _numeric_H(ekf, model, steps):
    """H = -d y / d dx, evaluating the residual with the nominal replaced by nominal (+) dx."""
    y0 = model(ekf)[0]
    H = np.empty((y0.size, ekf.n))
    for j in range(ekf.n):
        ys = []
        for sign in (1.0, -1.0):
            e = copy.deepcopy(ekf)
            d = np.zeros(ekf.n)
            d[j] = sign * steps[j]
            e.inject(d)
            ys.append(model(e)[0])
        H[:, j] = -(ys[0] - ys[1]) / (2 * steps[j])
    return H


STEPS = np.array([1.0] * 3 + [0.01] * 3 + [1e-5] * 3 + [1e-6] * 3 + [1e-3] * 3 + [0.1] + [0.1] * 6 + [1e-3] + [0.01] * 2)
X_HAT = (0.7, -1.6, 1200.0, np.array([40.0, -25.0, 3.0]), euler_to_quat(np.radians([8.0, -4.0, 140.0])))
ORIGIN = GeodeticOrigin(0.7 - 3000 / 6.37e6, -1.6 + 2000 / 4.9e6, 300.0)
B_NED = np.array([17e-6, 1e-6, 52e-6])


@pytest.mark.parametrize(
    "name, model",
    [
        ("gnss_pos", lambda e: meas.gnss_position(e, 0.7 + 1e-6, -1.6 - 2e-6, 1190.0, [2, 2, 4])),
        ("gnss_vel", lambda e: meas.gnss_velocity(e, [41.0, -24.0, 2.0], [0.1] * 3)),
        ("position_fix", lambda e: meas.position_ned(e, [3000.0, -2000.0, -900.0], np.eye(3) * 25, ORIGIN)),
        ("baro", lambda e: meas.baro_altitude(e, 1203.0, 1.0)),
        ("mag_vector", lambda e: meas.mag_vector(e, np.array([10e-6, 12e-6, 50e-6]), B_NED, 1e-7)),
        # Magnetic heading levelled with the nominal tilt: the field as the unperturbed nominal
        # attitude would read it (y = 0), so that the tilt columns are first-order exact.
        ("mag_heading", lambda e: meas.mag_heading(e, quat_to_dcm(X_HAT[4]).T @ B_NED, B_NED, 0.01)),
        # Rotor drag with wind states: the body velocity through the air the residual uses is
        # the (perturbed) nominal's own, v - w.
        ("drag", lambda e: meas.drag_specific_force(e, [-1.2, 0.4], (e.C_nb.T @ meas.air_velocity_ned(e))[:2], 0.365, 0.05)),
        # Airspeed aiding: the speed and the body-y velocity through the air, v - wind.
        ("airspeed", lambda e: meas.true_airspeed(e, 46.0, 0.3)),
        ("sideslip", lambda e: meas.zero_sideslip(e, 0.01)),
    ],
)
def test_H_matches_finite_differences(name, model):
    ekf = _ekf_at(X_HAT)
    H = model(ekf)[1]
    H_num = _numeric_H(ekf, model, STEPS)
    # Entries ~ y / R (~1e-6) from the residual's own scale factors are second order.
    scale = np.abs(H).max()
    np.testing.assert_allclose(H, H_num, rtol=1e-5, atol=3e-6 * scale, err_msg=name)


@pytest.mark.parametrize("moments", [False, True], ids=["centre", "moments"])
def test_optical_flow_H_with_the_flow_error_states_matches_finite_differences(moments):
    noise = imu_noise_from_datasheet(0.15, 7.0, 0.02, 14.0)
    ekf = ErrorStateEKF(noise, wind_states=True, flow_bias_sigma_rps=0.005, flow_bias_tau_s=20.0)
    lat, lon, h, v, q = X_HAT
    ekf.initialize(0.0, lat, lon, h, v, q, np.eye(ekf.n))
    ekf.b_flow_rps = np.array([0.002, -0.001])
    ekf.omega_ib_b_rps = (0.02, -0.03, 0.01)
    # A flow camera pitched 80 deg down and yawed, 3 cm off the centre of gravity.
    from testbench.core.camera_geometry import mount_rotation

    R_bc = mount_rotation(2.0, -80.0, 15.0)

    # The fit's reading of the quadratic flow fields (a textured frame's: weights off centre).
    moments_c = (np.random.default_rng(4).normal(0.0, 0.05, (2, 8)) + [[0.1, 0, 0.06, 0, 0, 0, 0, 0],
                                                                    [0, 0, 0, 0, 0, 0.1, 0, 0.06]]) if moments else None

    def model(e):
        return meas.optical_flow(e, [0.3, -0.2], R_bc, 60.0, np.eye(2) * 1e-6, (0.03, 0.0, 0.01), 0.02, moments_c)

    H = model(ekf)[1]
    steps = np.r_[STEPS, 1e-4, 1e-4]
    H_num = _numeric_H(ekf, model, steps)
    assert ekf.i_flow == slice(N_STATES, N_STATES + 2)
    np.testing.assert_allclose(H, H_num, rtol=1e-5, atol=3e-6 * np.abs(H).max())


@pytest.mark.parametrize("name", ["mag_vector", "mag_heading"])
def test_mag_H_with_the_heading_bias_state_matches_finite_differences(name):
    """With the magnetic bias state (one more column, last) at a non-zero estimate."""
    noise = imu_noise_from_datasheet(0.15, 7.0, 0.02, 14.0)
    ekf = ErrorStateEKF(noise, wind_states=True, mag_bias_sigma_rad=0.005, mag_bias_correlation_m=2000.0)
    lat, lon, h, v, q = X_HAT
    ekf.initialize(0.0, lat, lon, h, v, q, np.eye(ekf.n))
    ekf.b_mag_rad = 0.01
    assert ekf.n == N_STATES + 1 and ekf.i_mag == N_STATES
    field_b_T = quat_to_dcm(X_HAT[4]).T @ B_NED
    model = {"mag_vector": lambda e: meas.mag_vector(e, field_b_T + np.array([1e-7, -2e-7, 1e-7]), B_NED, 1e-7),
             "mag_heading": lambda e: meas.mag_heading(e, field_b_T, B_NED, 0.01)}[name]
    H = model(ekf)[1]
    assert abs(H[0, ekf.i_mag]) > 0.1 * np.abs(H).max()  # the bias column is there
    H_num = _numeric_H(ekf, model, np.r_[STEPS, 1e-5])
    np.testing.assert_allclose(H, H_num, rtol=1e-5, atol=3e-6 * np.abs(H).max(), err_msg=name)


def test_map_fix_H_with_the_map_error_states_matches_finite_differences():
    """A scene-matching fix with the map's georeference states at a non-zero estimate: its north
    and east seen whole."""
    noise = imu_noise_from_datasheet(0.15, 7.0, 0.02, 14.0)
    ekf = ErrorStateEKF(noise, wind_states=True, map_error_sigma_m=2.5, map_error_correlation_m=4000.0)
    lat, lon, h, v, q = X_HAT
    ekf.initialize(0.0, lat, lon, h, v, q, np.eye(ekf.n))
    ekf.b_map = np.array([1.5, -2.0])
    assert ekf.i_map == slice(N_STATES, N_STATES + 2)

    def model(e):
        return meas.position_ned(e, [3000.0, -2000.0, -900.0], np.eye(3) * 25, ORIGIN, from_map=True)

    y, H, _ = model(ekf)
    plain = meas.position_ned(ekf, [3000.0, -2000.0, -900.0], np.eye(3) * 25, ORIGIN)[0]
    np.testing.assert_allclose(plain - y, [1.5, -2.0, 0.0])  # the nominal map error taken out of the residual
    np.testing.assert_array_equal(H[:2, ekf.i_map], np.eye(2))
    H_num = _numeric_H(ekf, model, np.r_[STEPS, 0.1, 0.1])
    np.testing.assert_allclose(H, H_num, rtol=1e-5, atol=3e-6 * np.abs(H).max())


def test_calm_air_drag_H_matches_finite_differences():
    """Rotor drag without wind states (calm air): the ground velocity is the air velocity."""
    noise = imu_noise_from_datasheet(0.15, 7.0, 0.02, 14.0)
    ekf = ErrorStateEKF(noise)
    lat, lon, h, v, q = X_HAT
    ekf.initialize(0.0, lat, lon, h, v, q, np.eye(ekf.n))
    ekf.drag_scale = 0.02

    def model(e):
        return meas.drag_specific_force(e, [-1.2, 0.4], (e.C_nb.T @ np.array(e.ins.vel))[:2], 0.365, 0.05)

    H = model(ekf)[1]
    assert H.shape == (2, ekf.n) and not ekf.wind_states
    np.testing.assert_allclose(H, _numeric_H(ekf, model, STEPS), rtol=1e-5, atol=3e-6 * np.abs(H).max())


def test_reset_jacobian_matches_finite_differences():
    """After injecting dphi, the new attitude error phi+ = Log(Exp(phi) Exp(-dphi)) has
    d phi+ / d phi = I + [dphi x] / 2."""
    from testbench.core.rotations import quat_conjugate, quat_to_rotvec
    from testbench.navigation.ins.error_model import reset_jacobian

    dphi = np.array([0.02, -0.03, 0.05])
    G = reset_jacobian(dphi)[6:9, 6:9]

    def phi_plus(phi):
        return quat_to_rotvec(quat_multiply(rotvec_to_quat(phi), quat_conjugate(rotvec_to_quat(dphi))))

    G_num = np.empty((3, 3))
    for j in range(3):
        d = np.zeros(3)
        d[j] = 1e-6
        G_num[:, j] = (phi_plus(dphi + d) - phi_plus(dphi - d)) / 2e-6
    np.testing.assert_allclose(G, G_num, atol=1e-3)  # first order in dphi (|dphi|^2 ~ 4e-3)


def _boresight_ekf():
    noise = imu_noise_from_datasheet(0.15, 7.0, 0.02, 14.0)
    ekf = ErrorStateEKF(noise, wind_states=True, camera_boresight_sigma_rad=0.01)
    lat, lon, h, v, q = X_HAT
    ekf.initialize(0.0, lat, lon, h, v, q, np.eye(ekf.n))
    ekf.b_cam_rad = np.array([0.004, -0.006, 0.003])
    assert ekf.n == N_STATES + 3 and ekf.i_cam == slice(N_STATES, N_STATES + 3)
    return ekf


def test_image_pose_H_with_the_camera_boresight_states_matches_finite_differences():
    """The image-only pose (position and attitude rows) with the boresight states (three more
    columns, last) at a non-zero estimate; the image's attitude the estimate's, so that the
    residual's own second-order terms vanish."""
    ekf = _boresight_ekf()
    C = quat_to_dcm(X_HAT[4])
    R_img = quat_to_dcm(rotvec_to_quat(C @ ekf.b_cam_rad)) @ C

    def model(e):
        return meas.image_pose(e, [3000.0, -2000.0, -900.0], R_img, np.eye(6), ORIGIN)

    H = model(ekf)[1]
    assert np.abs(H[3:, ekf.i_cam]).max() > 0.5
    H_num = _numeric_H(ekf, model, np.r_[STEPS, 1e-5, 1e-5, 1e-5])
    np.testing.assert_allclose(H, H_num, rtol=1e-5, atol=3e-6 * np.abs(H).max())


def test_fix_heading_H_with_the_camera_boresight_states_matches_finite_differences():
    """The image heading of a solve seeded with the mounting corrected by the boresight
    estimate reads the heading of Exp(phi + C db) C: its boresight columns are its attitude
    columns times C (finite differences over db of that heading)."""
    from testbench.core.rotations import dcm_to_euler

    ekf = _boresight_ekf()
    C = quat_to_dcm(X_HAT[4])
    exp = lambda v: quat_to_dcm(rotvec_to_quat(np.asarray(v, float)))  # noqa: E731
    H = meas.fix_heading(ekf, 0.3, 0.01)[1]
    d = 1e-6
    for j in range(3):
        e = np.eye(3)[j] * d
        num = (dcm_to_euler(exp(C @ e) @ C)[2] - dcm_to_euler(exp(-C @ e) @ C)[2]) / (2 * d)
        assert H[0, ekf.i_cam.start + j] == pytest.approx(num, rel=1e-5, abs=1e-7)
        num_phi = (dcm_to_euler(exp(e) @ C)[2] - dcm_to_euler(exp(-e) @ C)[2]) / (2 * d)
        assert H[0, IA.start + j] == pytest.approx(num_phi, rel=1e-5, abs=1e-7)
    assert np.abs(H[0, ekf.i_cam]).max() > 0.5


def test_coupled_fix_H_with_the_camera_boresight_states_follows_the_seeded_solve():
    """A fix that leaned on the prior (error -M psi, psi the seed's camera attitude error) from
    a solve seeded with the mounting corrected by the boresight estimate: psi = Log(R_nc_true
    R_nc_seed^T), R_nc_true = Exp(phi) C Exp(b_hat + db) R_bc, R_nc_seed = C Exp(b_hat) R_bc.
    Its attitude and boresight columns are -M d psi / d (phi, db), by finite differences."""
    from testbench.core.camera_geometry import mount_rotation
    from testbench.core.rotations import dcm_to_quat, quat_to_rotvec

    ekf = _boresight_ekf()
    C = quat_to_dcm(X_HAT[4])
    R_bc = mount_rotation(0.0, -90.0, 0.0)
    exp = lambda v: quat_to_dcm(rotvec_to_quat(np.asarray(v, float)))  # noqa: E731
    b = ekf.b_cam_rad
    seed = C @ exp(b) @ R_bc

    def psi(phi, db):
        return quat_to_rotvec(dcm_to_quat(exp(phi) @ C @ exp(b + db) @ R_bc @ seed.T))

    M = np.array([[60.0, -20.0, 5.0], [15.0, 70.0, -8.0], [3.0, 4.0, 2.0]])
    H = meas.position_ned(ekf, [3000.0, -2000.0, -900.0], np.eye(3), ORIGIN, M)[1]
    d = 1e-6
    for j in range(3):
        e = np.eye(3)[j] * d
        np.testing.assert_allclose(H[:, IA.start + j], -M @ (psi(e, 0 * e) - psi(-e, 0 * e)) / (2 * d), rtol=1e-5, atol=1e-6)
        # (to first order in b_hat: what is left is |b_hat|^2 / 12 of M, 1e-3 here against the
        # 0.1 its first-order term makes)
        np.testing.assert_allclose(H[:, ekf.i_cam.start + j], -M @ (psi(0 * e, e) - psi(0 * e, -e)) / (2 * d),
                                   rtol=1e-5, atol=1e-3)
    assert np.abs(H[:, ekf.i_cam]).max() > 10.0
