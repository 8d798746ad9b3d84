"""Error-state model of the INS: state layout, continuous F, process noise, discretisation,
error injection and the error between two navigation states.

Error convention (truth = nominal (+) error):
- dp (3): position error in NED metres at the vehicle, curvilinear: dp_N = (R_M + h) dL,
  dp_E = (R_N + h) cos L dlambda, dp_D = -dh (R_M, R_N, L, h of the nominal state);
- dv (3): v_true - v_nominal, NED (m/s);
- phi (3): attitude error in NED (small angles, rad): C_nb_true = Exp(phi) C_nb_nominal;
- dbg (3), dba (3): gyro (rad/s) and accelerometer (m/s^2) bias errors, b_true = b_nom + db;
- dbb (1): barometer bias error (m).
The nominal biases are subtracted from the raw IMU data: omega = omega_meas - b_g.

Continuous error dynamics (phi-angle model, Titterton & Weston ch. 12 / Groves ch. 14, in
this sign convention; neglecting the e^2-sized terms dR/dL and dg/dL):
  dp' = F_pp dp + dv
  dv' = -[f_n x] phi - C_nb dba + [v x](2 dw_ie + dw_en) - [(2 w_ie + w_en) x] dv + dg - C_nb n_a
  phi' = -[w_in x] phi - dw_ie - dw_en - C_nb dbg - C_nb n_g
  db'  = -db / tau + w_b
with dw_ie, dw_en the changes of the Earth and transport rates with dp and dv, and
dg = (0, 0, 2 g / R) dp_D (the gravity gradient that makes the vertical channel unstable).
"""

from __future__ import annotations

import numpy as np

from testbench.core.geodesy import OMEGA_IE_RPS, radii_of_curvature
from testbench.core.rotations import (
    quat_conjugate,
    quat_multiply,
    quat_normalize,
    quat_to_rotvec,
    rotvec_to_quat,
    skew,
)

IP = slice(0, 3)
IV = slice(3, 6)
IA = slice(6, 9)
IBG = slice(9, 12)
IBA = slice(12, 15)
IBB = 15
N_STATES = 16
N_CORE = 15
"""Number of states that truth can be compared with (without the barometer bias)."""


def continuous_F(lat_rad, h_m, vel_ned_mps, C_nb, f_n_mps2, tau_g_s, tau_a_s, tau_baro_s=np.inf):
    """Continuous-time error-state Jacobian F (16, 16) at one nominal state.

    lat_rad, h_m: nominal position; vel_ned_mps (3,); C_nb (3, 3) body->NED;
    f_n_mps2 (3,): specific force resolved in NED (C_nb f_b); tau_*: bias correlation times (s).
    """
    v = np.asarray(vel_ned_mps, float)
    vn, ve, vd = v
    r_m, r_n = radii_of_curvature(lat_rad)
    rm, rn = r_m + h_m, r_n + h_m
    sl, cl = np.sin(lat_rad), np.cos(lat_rad)
    tl = sl / cl
    w = OMEGA_IE_RPS
    wie = np.array([w * cl, 0.0, -w * sl])
    wen = np.array([ve / rn, -vn / rm, -ve * tl / rn])

    # d(w_ie)/d(dp): only through latitude, dL = dp_N / (R_M + h).
    dwie_dp = np.zeros((3, 3))
    dwie_dp[0, 0] = -w * sl / rm
    dwie_dp[2, 0] = -w * cl / rm
    # d(w_en)/d(dp): latitude (tan L) and height (dh = -dp_D).
    dwen_dp = np.zeros((3, 3))
    dwen_dp[2, 0] = -ve / (cl * cl * rn * rm)
    dwen_dp[0, 2] = ve / rn**2
    dwen_dp[1, 2] = -vn / rm**2
    dwen_dp[2, 2] = -ve * tl / rn**2
    dwen_dv = np.zeros((3, 3))
    dwen_dv[0, 1] = 1.0 / rn
    dwen_dv[1, 0] = -1.0 / rm
    dwen_dv[2, 1] = -tl / rn

    F = np.zeros((N_STATES, N_STATES))
    # Position: derivative of the curvilinear error map (see module docstring).
    F[0, 0] = -vd / rm
    F[0, 2] = vn / rm
    F[1, 0] = ve * tl / rm
    F[1, 1] = -vd / rn - vn * tl / rm
    F[1, 2] = ve / rn
    F[IP, IV] = np.eye(3)

    sv = skew(v)
    F[IV, IP] = sv @ (2.0 * dwie_dp + dwen_dp)
    g_over_r = 2.0 * 9.80665 / np.sqrt(r_m * r_n)  # |dg/dh| ~ 2 g / R (free-air gradient)
    F[5, 2] += g_over_r
    F[IV, IV] = sv @ dwen_dv - skew(2.0 * wie + wen)
    F[IV, IA] = -skew(f_n_mps2)
    F[IV, IBA] = -C_nb

    F[IA, IP] = -(dwie_dp + dwen_dp)
    F[IA, IV] = -dwen_dv
    F[IA, IA] = -skew(wie + wen)
    F[IA, IBG] = -C_nb

    F[IBG, IBG] = -np.eye(3) / tau_g_s
    F[IBA, IBA] = -np.eye(3) / tau_a_s
    F[IBB, IBB] = -1.0 / tau_baro_s if np.isfinite(tau_baro_s) else 0.0
    return F


def process_noise_diag(noise, baro_bias_rw_m_sqrt_s: float) -> np.ndarray:
    """Diagonal of G Qc G^T (16,): continuous process-noise PSD mapped into the error states.

    The white gyro and accelerometer noises enter through -C_nb; they are isotropic, so
    C_nb (s^2 I) C_nb^T = s^2 I and the mapped PSD stays diagonal. Bias driving noise of a
    Gauss-Markov process with variance s^2 and correlation time tau: 2 s^2 / tau, plus the
    rate random walk's PSD.
    """
    q = np.empty(N_STATES)
    q[IP] = 0.0
    q[IV] = noise.accel_vrw_mps_sqrt_s**2
    q[IA] = noise.gyro_arw_rad_sqrt_s**2
    q[IBG] = 2.0 * noise.gyro_bias_sigma_rps**2 / noise.gyro_bias_tau_s + noise.gyro_rrw_rps_sqrt_s**2
    q[IBA] = 2.0 * noise.accel_bias_sigma_mps2**2 / noise.accel_bias_tau_s + noise.accel_rrw_mps2_sqrt_s**2
    q[IBB] = baro_bias_rw_m_sqrt_s**2
    return q


def discretize(F: np.ndarray, qc_diag: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray]:
    """Transition Phi = I + F T + (F T)^2 / 2 and process noise Qd (trapezoidal rule,
    Qd = T/2 (Phi Qc Phi^T + Qc)), both second order in T; no matrix exponential."""
    FT = F * T
    Phi = np.eye(F.shape[0]) + FT + 0.5 * (FT @ FT)
    Qd = (0.5 * T) * ((Phi * qc_diag) @ Phi.T)
    Qd[np.diag_indices_from(Qd)] += 0.5 * T * qc_diag
    return Phi, Qd


def reset_jacobian(dphi: np.ndarray, n: int = N_STATES) -> np.ndarray:
    """Jacobian G of the error reset after injecting dphi into the attitude (global error):
    Exp(phi+) = Exp(phi) Exp(-dphi) gives d phi+/d phi = I + 1/2 [dphi x]; P+ = G P G^T."""
    G = np.eye(n)
    G[IA, IA] += 0.5 * skew(dphi)
    return G


def inject_nav(lat_rad, lon_rad, h_m, vel_ned_mps, q_nb_wxyz, dx):
    """Nominal navigation state (+) error dx[:9] -> (lat, lon, h, vel (3,), q (4,)).

    The inverse of `nav_error` (exactly for position and velocity, to rounding for attitude).
    """
    dx = np.asarray(dx, float)
    r_m, r_n = radii_of_curvature(lat_rad)
    lat1 = lat_rad + dx[0] / (r_m + h_m)
    lon1 = lon_rad + dx[1] / ((r_n + h_m) * np.cos(lat_rad))
    h1 = h_m - dx[2]
    vel1 = np.asarray(vel_ned_mps, float) + dx[IV]
    q1 = quat_normalize(quat_multiply(rotvec_to_quat(dx[IA]), q_nb_wxyz))
    return float(lat1), float(lon1), float(h1), vel1, q1


def nav_error(lat_rad, lon_rad, h_m, vel_ned_mps, q_nb_wxyz,
              lat_ref_rad, lon_ref_rad, h_ref_m, vel_ref_ned_mps, q_ref_nb_wxyz) -> np.ndarray:
    """Error (9,) = state (-) reference: [dp_ned_m, dv_ned_mps, phi_rad], the error that makes
    reference (+) error = state (`inject_nav`). With state = truth and reference = estimate
    this is the true error of the estimate in the filter's convention."""
    r_m, r_n = radii_of_curvature(lat_ref_rad)
    out = np.empty(9)
    out[0] = (r_m + h_ref_m) * (lat_rad - lat_ref_rad)
    out[1] = (r_n + h_ref_m) * np.cos(lat_ref_rad) * (np.angle(np.exp(1j * (lon_rad - lon_ref_rad))))
    out[2] = -(h_m - h_ref_m)
    out[IV] = np.asarray(vel_ned_mps, float) - np.asarray(vel_ref_ned_mps, float)
    out[IA] = quat_to_rotvec(quat_multiply(q_nb_wxyz, quat_conjugate(q_ref_nb_wxyz)))
    return out
