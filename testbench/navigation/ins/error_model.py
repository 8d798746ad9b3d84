"""Error-state model of the INS: state layout, continuous F, process noise, discretisation,
error injection and the error between two navigation states.

Error convention (truth = nominal (+) error):
- dp (3): position error in NED metres at the vehicle, curvilinear: dp_N = (R_M + h) dL,
  dp_E = (R_N + h) cos L dlambda, dp_D = -dh (R_M, R_N, L, h of the nominal state);
- dv (3): v_true - v_nominal, NED (m/s);
- phi (3): attitude error in NED (small angles, rad): C_nb_true = Exp(phi) C_nb_nominal;
- dbg (3), dba (3): gyro (rad/s) and accelerometer (m/s^2) bias errors, b_true = b_nom + db;
- dbb (1): barometer bias error (m);
- dgn (3): error of the GNSS receiver's slowly varying position error (NED m): the part of
  a fix error that is correlated over tens of seconds (ionosphere, orbit/clock, multipath),
  a first-order Gauss-Markov process, so that fusing fix after fix does not average it away
  as if it were white (which made the covariance several times too small);
- dfx (3): error of the position-fix (scene-matching) error that successive fixes share
  (origin NED m): overlapping frames matched against the same map disagree with it in the
  same way (season, map georeference, relief), a Gauss-Markov process along the flight;
- dsd (1): error of the rotor-drag scale s (dimensionless): the drag aiding's model is
  f_b = -mu (1 + s) v_b, and mu, taken at hover, changes with the rotor speeds the manoeuvre
  needs (a few per mille to a percent) and lasts for a minute, which the filter must not
  average away as white noise (that left the drag-aided position 2-11 m off against 2.3 m
  claimed, NEES 7.7 for 2 dof, in paper_swarm_relnav); Gauss-Markov;
- dw (2): error of the horizontal wind (north, east, m/s; the air moves with velocity
  (w_N, w_E, 0) over the ground): what airspeed aiding measures the velocity against
  (a fixed wing's pitot and zero sideslip give its velocity through the air, v - w); a random
  walk, since the wind changes with place and height as the vehicle flies.
- dap (3, optional, after all the others: ErrorStateEKF.i_app): error of the fixes' appearance
  error b_app (origin NED m), which a fix of quality q shows as g(q) b_app (InsEkfParams.
  fix_appearance_sigma_m); Gauss-Markov like dfx. Not in N_STATES: a filter carries it only
  when asked, and its rows of F and Q are set by the filter.
- dbm (1, optional, after dap: ErrorStateEKF.i_mag): error of the magnetic heading's bias
  (rad); dbf (2, optional, after dbm: ErrorStateEKF.i_flow): error of the optical flow's slowly
  varying error (rad/s, the flow camera's x and y); dbc (3, optional, last: ErrorStateEKF.
  i_cam): error of the scene-matching camera's boresight b_cam (body axes, rad: R_bc_true =
  Exp(b_cam) R_bc), a constant; dtd (1, after dbc: ErrorStateEKF.i_td): error of its time offset
  (s); dci (3, last: ErrorStateEKF.i_ci): error of its intrinsics error (principal point u, v
  px; focal length, relative), constants; dmp (2, last: ErrorStateEKF.i_map): error of the
  reference map's georeference error b_map (north, east, m), Gauss-Markov over the distance
  flown. Likewise carried only when asked.
Why each is there (what leaving it out did):
- b_fix decorrelates in turns too: scene matching's shared error is the disagreement between
  the scene and the map as one viewing geometry meets it, and a turn brings other tiles and
  geometry (paper_ismn_800m: after each 180 deg turn the position erred by 0.16-0.19 m against
  0.27 m claimed while the straight legs were consistent).
- b_app: scene matching under changed shadows errs together over a region, more as fewer tiles
  agree, and b_fix, which every fix sees alike, cannot hold an error that a good fix shares
  less than a poor one.
- b_mag: the crust's anomaly turns the magnetic heading by a few mrad, the same for every sample
  at one place; taken as white, each sample's 1 deg sigma averaged down to a fraction of a mrad
  and the filter claimed a heading the bias missed by several times that (300 nT: NEES 3.9/dof).
- b_flow: a flow sensor's reading of sub-pixel shifts errs with the ground in its view, the
  same while the view holds it (consecutive frames share 99 % of it at 5 m/s).
- b_cam, td, the intrinsics: a mount known to 0.1 deg moves the fixes of a camera 800 m up by
  1.4 m, the same way for a whole leg; a 20 ms time offset puts them 0.5 m behind at 25 m/s;
  a principal point error shifts them by height / focal per px in the camera's axes (so it
  turns with the track); straight legs flown both ways tell each from b_fix.
- b_map: every fix from a misplaced map errs by the map's displacement under its footprint;
  no fix tells it from the position (GNSS, while it lasts, does), so without it the filter
  claims the fixes' precision as accuracy.
- The IMU biases are not decayed towards zero by default (bias_model "random_walk"): a real
  bias is a turn-on constant plus the in-run process, a consumer MEMS gyro's turn-on bias
  (0.5 deg/s) is 180 times its instability, and decaying its estimate left a tilt error growing
  at 0.07 deg/s that GNSS could not hold (tests/navigation/ins).
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

import math

import numpy as np

from testbench.core.geodesy import A_M, E2, OMEGA_IE_RPS, radii_of_curvature
from testbench.core.rotations import (
    quat_conjugate,
    quat_multiply,
    quat_normalize,
    quat_to_rotvec,
    skew,
)

IP = slice(0, 3)
IV = slice(3, 6)
IA = slice(6, 9)
IBG = slice(9, 12)
IBA = slice(12, 15)
IBB = 15
IGN = slice(16, 19)
IFX = slice(19, 22)
IDS = 22
IW = slice(23, 25)
N_STATES = 25
N_NO_WIND = 23
"""States of a filter without the wind (no airspeed aiding): the wind's two come last so that
such a filter leaves them out, and does not pay for them in every covariance product."""
N_CORE = 15
"""Number of states that truth can be compared with (without the barometer bias)."""


def continuous_F(lat_rad, h_m, vel_ned_mps, C_nb, f_n_mps2, tau_g_s, tau_a_s, tau_baro_s=math.inf,
                 tau_gnss_s=math.inf, tau_fix_s=math.inf, tau_drag_s=math.inf, n=N_STATES):
    """Continuous-time error-state Jacobian F (n, n) at one nominal state, n = N_STATES or
    N_NO_WIND (the wind error, a random walk, has no dynamics: its rows are zero).

    lat_rad, h_m: nominal position; vel_ned_mps (3,); C_nb (3, 3) body->NED;
    f_n_mps2 (3,): specific force resolved in NED (C_nb f_b); tau_*: bias correlation times (s).
    Written element by element with Python floats: it runs at the covariance rate of every
    vehicle, where numpy's per-call overhead on 3-vectors would dominate.
    """
    vn, ve, vd = (float(x) for x in vel_ned_mps)
    fn, fe, fd = (float(x) for x in f_n_mps2)
    lat, h = float(lat_rad), float(h_m)
    sl, cl = math.sin(lat), math.cos(lat)
    w2 = 1.0 - E2 * sl * sl
    r_n = A_M / math.sqrt(w2)
    r_m = r_n * (1.0 - E2) / w2
    rm, rn = r_m + h, r_n + h
    tl = sl / cl
    w = OMEGA_IE_RPS
    # Earth rate w_ie and transport rate w_en in NED.
    ien, ied = w * cl, -w * sl
    enn, ene, end = ve / rn, -vn / rm, -ve * tl / rn

    # d(w_ie)/d(dp) (through latitude, dL = dp_N / (R_M + h)); d(w_en)/d(dp) (latitude and
    # height, dh = -dp_D); d(w_en)/d(dv).
    dwie = ((-w * sl / rm, 0.0, 0.0), (0.0, 0.0, 0.0), (-w * cl / rm, 0.0, 0.0))
    dwen = ((0.0, 0.0, ve / rn**2), (0.0, 0.0, -vn / rm**2), (-ve / (cl * cl * rn * rm), 0.0, -ve * tl / rn**2))
    dwen_dv = ((0.0, 1.0 / rn, 0.0), (-1.0 / rm, 0.0, 0.0), (0.0, -tl / rn, 0.0))

    F = np.zeros((n, n))
    # Position: derivative of the curvilinear error map (see module docstring).
    F[0, 0] = -vd / rm
    F[0, 2] = vn / rm
    F[1, 0] = ve * tl / rm
    F[1, 1] = -vd / rn - vn * tl / rm
    F[1, 2] = ve / rn
    F[0, 3] = F[1, 4] = F[2, 5] = 1.0

    sv = np.array(((0.0, -vd, ve), (vd, 0.0, -vn), (-ve, vn, 0.0)))  # [v x]
    a = (2.0 * ien + enn, ene, 2.0 * ied + end)  # 2 w_ie + w_en
    sa = np.array(((0.0, -a[2], a[1]), (a[2], 0.0, -a[0]), (-a[1], a[0], 0.0)))
    dwie, dwen, dwen_dv = np.array(dwie), np.array(dwen), np.array(dwen_dv)
    F[IV, IP] = sv @ (2.0 * dwie + dwen)
    F[IV, IV] = sv @ dwen_dv - sa
    F[IA, IP] = -(dwie + dwen)
    F[IA, IV] = -dwen_dv
    F[5, 2] += 2.0 * 9.80665 / math.sqrt(r_m * r_n)  # |dg/dh| ~ 2 g / R (free-air gradient)
    # -[f_n x]
    F[3, 7], F[3, 8] = fd, -fe
    F[4, 6], F[4, 8] = -fd, fn
    F[5, 6], F[5, 7] = fe, -fn
    # -[w_in x]
    b = (ien + enn, ene, ied + end)
    F[6, 7], F[6, 8] = b[2], -b[1]
    F[7, 6], F[7, 8] = -b[2], b[0]
    F[8, 6], F[8, 7] = b[1], -b[0]
    C = np.asarray(C_nb, float)
    F[IV, IBA] = -C
    F[IA, IBG] = -C
    d = np.arange(9, 15)
    F[d[:3], d[:3]] = -1.0 / tau_g_s
    F[d[3:], d[3:]] = -1.0 / tau_a_s
    F[IBB, IBB] = -1.0 / tau_baro_s if math.isfinite(tau_baro_s) else 0.0
    g = -1.0 / tau_gnss_s if math.isfinite(tau_gnss_s) else 0.0
    F[16, 16] = F[17, 17] = F[18, 18] = g
    g = -1.0 / tau_fix_s if math.isfinite(tau_fix_s) else 0.0
    F[19, 19] = F[20, 20] = F[21, 21] = g
    F[IDS, IDS] = -1.0 / tau_drag_s if math.isfinite(tau_drag_s) else 0.0
    return F


def process_noise_diag(noise, baro_bias_rw_m_sqrt_s: float, gnss_error_sigma_m: float = 0.0,
                       gnss_error_tau_s: float = math.inf, fix_error_sigma_m: float | np.ndarray = 0.0,
                       fix_error_tau_s: float = math.inf, drag_scale_sigma: float = 0.0,
                       drag_scale_tau_s: float = math.inf, wind_rw_mps_sqrt_s: float = 0.0,
                       n: int = N_STATES) -> np.ndarray:
    """Diagonal of G Qc G^T (n,): continuous process-noise PSD mapped into the error states (n:
    N_STATES, or N_NO_WIND without the wind). wind_rw_mps_sqrt_s: the horizontal wind's random
    walk (per axis).

    The white gyro and accelerometer noises enter through -C_nb; they are isotropic, so
    C_nb (s^2 I) C_nb^T = s^2 I and the mapped PSD stays diagonal. Bias driving noise of a
    Gauss-Markov process with variance s^2 and correlation time tau: 2 s^2 / tau, plus the
    rate random walk's PSD.
    """
    q = np.empty(n)
    q[IP] = 0.0
    q[IV] = noise.accel_vrw_mps_sqrt_s**2
    q[IA] = noise.gyro_arw_rad_sqrt_s**2
    q[IBG] = 2.0 * noise.gyro_bias_sigma_rps**2 / noise.gyro_bias_tau_s + noise.gyro_rrw_rps_sqrt_s**2
    q[IBA] = 2.0 * noise.accel_bias_sigma_mps2**2 / noise.accel_bias_tau_s + noise.accel_rrw_mps2_sqrt_s**2
    q[IBB] = baro_bias_rw_m_sqrt_s**2
    q[IGN] = 2.0 * gnss_error_sigma_m**2 / gnss_error_tau_s if math.isfinite(gnss_error_tau_s) else 0.0
    # fix_error_sigma_m: one figure or (3,) per NED axis.
    q[IFX] = 2.0 * np.square(fix_error_sigma_m) / fix_error_tau_s if math.isfinite(fix_error_tau_s) else 0.0
    q[IDS] = 2.0 * drag_scale_sigma**2 / drag_scale_tau_s if math.isfinite(drag_scale_tau_s) else 0.0
    if n > IW.start:
        q[IW] = wind_rw_mps_sqrt_s**2
    return q


def discretize(F: np.ndarray, qc_diag: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray]:
    """Transition Phi = I + F T + (F T)^2 / 2 and process noise Qd (trapezoidal rule,
    Qd = T/2 (Phi Qc Phi^T + Qc)), both second order in T; no matrix exponential."""
    FT = F * T
    Phi = FT + 0.5 * (FT @ FT)
    Phi.flat[:: F.shape[0] + 1] += 1.0
    Qd = (0.5 * T) * ((Phi * qc_diag) @ Phi.T)
    Qd.flat[:: F.shape[0] + 1] += 0.5 * T * qc_diag
    return Phi, Qd


def reset_jacobian(dphi: np.ndarray, n: int = N_STATES) -> np.ndarray:
    """Jacobian G (n, n) of the error reset after injecting dphi into the attitude (global
    error): Exp(phi+) = Exp(phi) Exp(-dphi) gives d phi+/d phi = I + 1/2 [dphi x]; P+ = G P G^T."""
    G = np.eye(n)
    x, y, z = 0.5 * float(dphi[0]), 0.5 * float(dphi[1]), 0.5 * float(dphi[2])
    G[6:9, 6:9] += ((0.0, -z, y), (z, 0.0, -x), (-y, x, 0.0))
    return G


def inject_nav(lat_rad, lon_rad, h_m, vel_ned_mps, q_nb_wxyz, dx):
    """Nominal navigation state (+) error dx[:9] -> (lat, lon, h, vel (3,), q (4,)).

    The inverse of `nav_error` (exactly for position and velocity, to rounding for attitude).
    """
    lat, h = float(lat_rad), float(h_m)
    sl = math.sin(lat)
    w2 = 1.0 - E2 * sl * sl
    r_n = A_M / math.sqrt(w2)
    r_m = r_n * (1.0 - E2) / w2
    d = [float(x) for x in dx[:9]]
    lat1 = lat + d[0] / (r_m + h)
    lon1 = float(lon_rad) + d[1] / ((r_n + h) * math.cos(lat))
    h1 = h - d[2]
    vel1 = np.array([float(vel_ned_mps[i]) + d[3 + i] for i in range(3)])
    a = math.sqrt(d[6] ** 2 + d[7] ** 2 + d[8] ** 2)
    k = 0.5 - a * a / 48.0 if a < 1e-4 else math.sin(0.5 * a) / a
    aw, ax, ay, az = math.cos(0.5 * a), k * d[6], k * d[7], k * d[8]
    bw, bx, by, bz = (float(x) for x in q_nb_wxyz)
    q1 = np.array([  # Exp(phi) * q (Hamilton)
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ])
    return lat1, lon1, h1, vel1, quat_normalize(q1)


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
