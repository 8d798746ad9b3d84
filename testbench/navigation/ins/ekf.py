"""Error-state extended Kalman filter around the strapdown INS (25 states, or 23 without the
wind; error_model.py).

Nominal state: the strapdown INS (lat, lon, h, v_ned, q_nb) plus gyro bias b_g (rad/s),
accelerometer bias b_a (m/s^2), barometer bias b_baro (m) and the GNSS receiver's correlated
position error b_gnss (NED m), the error that successive position fixes share b_fix
(origin NED m) and the rotor-drag scale drag_scale (dimensionless), all Gauss-Markov processes,
and, with wind_states, the horizontal wind wind_ne_mps (north, east, m/s), a random walk.

Prediction runs the mechanisation at every IMU sample (~11 us). The covariance is propagated
at a lower rate: the IMU samples of `cov_interval_s` (default 0.05 s, i.e. 5-10 IMU samples)
are accumulated (elapsed time and the specific force resolved in NED) and P is propagated
once over that interval with Phi = I + F T + (F T)^2 / 2 built at the end of it. F changes
slowly (attitude by a few centiradians in a turn over 0.05 s), so the error of this choice is
far below the model's own approximations, and it divides the cost of the n x n matrix
work by the number of samples. Every update first flushes the pending interval, so P is
always current when a measurement is used.

Updates: y = z - h(x_nominal), H = dh/d(error), chi-square gate on the NIS at a configurable
probability, Joseph-form covariance update, injection of the error into the nominal state and
the covariance reset P <- G P G^T (error_model.reset_jacobian).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from scipy.stats import chi2

from testbench.core.errors import SimulationAborted
from testbench.core.messages import CorrectionInfo
from testbench.core.rotations import quat_to_dcm
from testbench.navigation.ins.error_model import (
    IA,
    IBA,
    IBB,
    IBG,
    IDS,
    IFX,
    IGN,
    IW,
    N_NO_WIND,
    N_STATES,
    continuous_F,
    discretize,
    inject_nav,
    process_noise_diag,
    reset_jacobian,
)
from testbench.navigation.ins.imu_noise import ImuNoiseSI
from testbench.navigation.ins.mechanization import StrapdownINS
from testbench.navigation.ins.reacquire import Reacquisition


@lru_cache(maxsize=64)
def chi2_threshold(probability: float, dof: int) -> float:
    """Gate on the NIS: the chi-square quantile with `dof` degrees of freedom."""
    return float(chi2.ppf(probability, dof))


class ErrorStateEKF(Reacquisition):
    """Error-state EKF of one vehicle. Shapes: P (n, n), n = self.n: N_STATES (25) with
    wind_states, else N_NO_WIND (23), plus 3 with the appearance states, 1 with the magnetic
    heading bias, 2 with the optical flow's slow error, 3 with a camera's boresight error, 1 with
    its time offset, 3 with its intrinsics error and 2 with the map's error; error vector layout
    in error_model (the appearance states, self.i_app, then the magnetic bias, self.i_mag, the
    flow's error, self.i_flow, the boresight, self.i_cam, the time offset, self.i_td, the
    intrinsics, self.i_ci, and the map's error, self.i_map, come last).

    noise: IMU noise model; gate_probability: chi-square gate (e.g. 0.999; 1.0 disables);
    cov_interval_s: covariance propagation interval (0: every IMU sample);
    baro_bias_rw_m_sqrt_s: random walk of the barometer bias state;
    gnss_error_sigma_m, gnss_error_tau_s: steady-state sigma per axis and correlation time of
    the GNSS receiver's correlated position error (0 sigma: no such error is modelled);
    fix_error_sigma_m, fix_error_tau_s: the same for the error successive position fixes share
    (sigma: one figure for every axis, or (3,) per NED axis); fix_error_turn_rad: the shared fix
    error also decorrelates as the view turns, by exp(-|d psi| / fix_error_turn_rad) for a heading
    change d psi (inf: time alone).
    drag_scale_sigma, drag_scale_tau_s: steady-state sigma and correlation time of the rotor-drag
    scale's error (error_model, dsd; 0 sigma: the drag model is taken as exact).
    wind_states: carry the horizontal wind (two more states, for airspeed aiding);
    wind_rw_mps_sqrt_s: its random walk (per axis).
    appearance_sigma_m: steady-state sigma (one figure or (3,) per NED axis) of a second error
    that successive position fixes share, the appearance error (0: no such states). Three
    Gauss-Markov states after the others (self.i_app), with fix_error_tau_s and
    fix_error_turn_rad, seen by each fix with its own gain (measurements.position_ned).
    mag_bias_sigma_rad, mag_bias_correlation_m: steady-state sigma and correlation distance of
    the magnetic heading's bias (0 sigma: no such state). One Gauss-Markov state after the
    others (self.i_mag) that decorrelates with the distance flown, exp(-d / correlation).
    flow_bias_sigma_rps, flow_bias_tau_s, flow_bias_correlation_rad: steady-state sigma (rad/s)
    of the optical flow's slowly varying error b_f, two Gauss-Markov states in the flow camera's
    x and y (0 sigma: none; measurements.optical_flow reads h + b_f), and how it decorrelates:
    over time (tau) and over the ground the view passes, exp(-T / tau - |flow| T / correlation),
    |flow| the translation's flow rate the last sample showed (flow_view_rate_rps, rad/s, set by
    the flow aiding).
    camera_boresight_sigma_rad: 1-sigma per body axis of the scene-matching camera's boresight
    error b_cam (its true mounting R_bc_true = Exp(b_cam) R_bc, body axes, rad; 0: no such
    states): three random constants after the others (self.i_cam), learnt from the image's
    pose against the INS attitude (measurements.image_pose), then through the MAP fixes'
    attitude coupling (measurements.position_ned).
    camera_time_offset_sigma_s: 1-sigma of the scene-matching camera's time offset td (its
    frames' stamp minus their true exposure, s; 0: no such state): one random constant after the
    others (self.i_td), learnt from the position fixes (measurements.position_ned): a fix is of
    the position td before its stamp, v td behind, and seen through the attitude the image had then.
    camera_intrinsics_sigma: 1-sigmas (3,) of the scene-matching camera's intrinsics error
    [principal point u, v (px, true minus calibrated), focal length (relative)] (all 0: no such
    states): three random constants after the others (self.i_ci), learnt from the fixes through
    their sensitivity to them (PositionFix.intrinsics_sensitivity).
    map_error_sigma_m, map_error_correlation_m: 1-sigma per axis and correlation distance of the
    reference map's georeference error b_map (north, east, m; 0 sigma: none): two Gauss-Markov
    states after the others (self.i_map) that every scene-matching fix sees whole and that
    decorrelate with the distance flown, exp(-d / correlation).
    gyro_scale_sigma, scale_corr_angle_rad: the gyros' scale-factor and cross-axis error (1 sigma,
    rad per rad turned) is a constant error in each rate the IMU reads, which the error state
    does not carry: it enters P as attitude noise per angle turned, s^2 Theta |dtheta| per axis,
    so that turning Theta = scale_corr_angle_rad (a corner) adds the variance (s Theta)^2 that
    the constant error builds over it (0: off).
    bias_model: "random_walk" (the IMU bias errors are driven by the Gauss-Markov process's
    noise, 2 s^2 / tau, plus the rate random walk, and never decay; the nominal biases are
    held) or "gauss_markov" (errors and nominal biases decay with tau: right only when the whole
    bias is the zero-mean in-run process; error_model says why). vehicle_id is only used in
    error messages. Why each optional state is there: error_model's module docstring.
    """

    def __init__(self, noise: ImuNoiseSI, *, gate_probability: float = 0.999,
                 cov_interval_s: float = 0.05, baro_bias_rw_m_sqrt_s: float = 0.01,
                 gnss_error_sigma_m: float = 0.0, gnss_error_tau_s: float = math.inf,
                 fix_error_sigma_m: float | np.ndarray = 0.0, fix_error_tau_s: float = math.inf,
                 fix_error_turn_rad: float = math.inf, bias_model: str = "random_walk", gyro_scale_sigma: float = 0.0,
                 scale_corr_angle_rad: float = 0.5 * math.pi, drag_scale_sigma: float = 0.0,
                 drag_scale_tau_s: float = math.inf, wind_states: bool = False, wind_rw_mps_sqrt_s: float = 0.0,
                 appearance_sigma_m: float | np.ndarray = 0.0, mag_bias_sigma_rad: float = 0.0,
                 mag_bias_correlation_m: float = math.inf, flow_bias_sigma_rps: float = 0.0,
                 flow_bias_tau_s: float = math.inf, flow_bias_correlation_rad: float = math.inf,
                 camera_boresight_sigma_rad: float = 0.0, camera_time_offset_sigma_s: float = 0.0,
                 camera_intrinsics_sigma=(0.0, 0.0, 0.0), map_error_sigma_m: float = 0.0,
                 map_error_correlation_m: float = math.inf, vehicle_id: str | None = None):
        if bias_model not in ("random_walk", "gauss_markov"):
            raise ValueError(f"bias_model {bias_model!r}: expected 'random_walk' or 'gauss_markov'")
        self.noise = noise
        self.wind_states = bool(wind_states)
        n_base = N_STATES if wind_states else N_NO_WIND
        app_var_m2 = np.broadcast_to(np.square(np.asarray(appearance_sigma_m, float)), (3,)).copy()
        self._app_var_m2 = app_var_m2
        self.i_app: slice | None = slice(n_base, n_base + 3) if np.any(app_var_m2 > 0.0) else None
        """The appearance error's three states (NED m), or None without them."""
        n_app = n_base + (3 if self.i_app is not None else 0)
        self._mag_var_rad2 = float(mag_bias_sigma_rad) ** 2
        self.mag_bias_correlation_m = float(mag_bias_correlation_m)
        self.i_mag: int | None = n_app if self._mag_var_rad2 > 0.0 else None
        """The magnetic heading bias's state (rad), or None without it."""
        n_mag = n_app + (1 if self.i_mag is not None else 0)
        self._flow_var = float(flow_bias_sigma_rps) ** 2
        self.flow_bias_tau_s = float(flow_bias_tau_s)
        self.flow_bias_correlation_rad = float(flow_bias_correlation_rad)
        self.i_flow: slice | None = slice(n_mag, n_mag + 2) if self._flow_var > 0.0 else None
        """The optical flow's slowly varying error's two states (camera x, y, rad/s), or None."""
        n_flow = n_mag + (2 if self.i_flow is not None else 0)
        self.i_cam: slice | None = slice(n_flow, n_flow + 3) if camera_boresight_sigma_rad > 0.0 else None
        """The scene-matching camera's boresight error's three states (body axes, rad), or None."""
        n_cam = n_flow + (3 if self.i_cam is not None else 0)
        self.i_td: int | None = n_cam if camera_time_offset_sigma_s > 0.0 else None
        """The scene-matching camera's time offset's state (its frames' stamp minus their exposure, s), or None."""
        n_td = n_cam + (1 if self.i_td is not None else 0)
        self.i_ci: slice | None = slice(n_td, n_td + 3) if np.any(np.asarray(camera_intrinsics_sigma) > 0.0) else None
        """The scene-matching camera's intrinsics error's three states (principal point u, v px;
        focal length, relative), or None."""
        n_ci = n_td + (3 if self.i_ci is not None else 0)
        self._map_var_m2 = float(map_error_sigma_m) ** 2
        self.map_error_correlation_m = float(map_error_correlation_m)
        self.i_map: slice | None = slice(n_ci, n_ci + 2) if self._map_var_m2 > 0.0 else None
        """The reference map's georeference error's two states (north, east, m), or None."""
        self.n = n_ci + (2 if self.i_map is not None else 0)
        """Number of error states (the length of dx, the size of P)."""
        # Correlation times of the IMU bias ERRORS in F (inf: random walk) and of the nominal biases.
        gm = bias_model == "gauss_markov"
        self._tau_bg_s = noise.gyro_bias_tau_s if gm else math.inf
        self._tau_ba_s = noise.accel_bias_tau_s if gm else math.inf
        self.gate_probability = float(gate_probability)
        self.cov_interval_s = float(cov_interval_s)
        self.vehicle_id = vehicle_id
        # Attitude variance per radian turned (see the class docstring).
        self._att_var_per_rad = float(gyro_scale_sigma) ** 2 * float(scale_corr_angle_rad)
        self.gnss_error_tau_s = float(gnss_error_tau_s)
        self.fix_error_tau_s = float(fix_error_tau_s)
        self.fix_error_turn_rad = float(fix_error_turn_rad)
        self._fix_var_m2 = np.broadcast_to(np.square(np.asarray(fix_error_sigma_m, float)), (3,)).copy()
        self.drag_scale_tau_s = float(drag_scale_tau_s)
        self._qc = process_noise_diag(noise, baro_bias_rw_m_sqrt_s, gnss_error_sigma_m, self.gnss_error_tau_s,
                                      fix_error_sigma_m, self.fix_error_tau_s, drag_scale_sigma, self.drag_scale_tau_s,
                                      wind_rw_mps_sqrt_s, n=n_base)
        if self.i_app is not None:
            # The same Gauss-Markov process as the shared fix error, with its own sigma.
            q_app = 2.0 * app_var_m2 / self.fix_error_tau_s if math.isfinite(self.fix_error_tau_s) else np.zeros(3)
            self._qc = np.concatenate([self._qc, q_app])
        if self.i_mag is not None:
            self._qc = np.concatenate([self._qc, [0.0]])  # driven by distance, in flush()
        if self.i_flow is not None:
            self._qc = np.concatenate([self._qc, [0.0, 0.0]])  # a Gauss-Markov step in flush()
        # The camera's boresight, time offset and intrinsics are constants (a mount that does not
        # move, the clocks' offset and not their drift, the lens's calibration): no process noise.
        self._qc = np.concatenate([self._qc, np.zeros(self.n - n_flow)])
        self.ins: StrapdownINS | None = None
        self.b_g = np.zeros(3)
        self.b_a = np.zeros(3)
        self.b_baro = 0.0
        self._zero_estimated_errors()
        self.flow_view_rate_rps = 0.0  # |translational flow| of the last flow sample (rad/s), held until the next
        self.P = np.zeros((self.n, self.n))
        self.omega_ib_b_rps = np.zeros(3)  # last bias-corrected gyro rate
        self._acc_turn_rad = 0.0
        self._acc_yaw_rad = 0.0  # |heading change| over the pending interval (fix_error_turn_rad)

    # ------------------------------------------------------------------ state
    def initialize(self, t_s: float, lat_rad: float, lon_rad: float, h_m: float, vel_ned_mps,
                   q_nb_wxyz, P0: np.ndarray, b_g=None, b_a=None, b_baro: float = 0.0) -> None:
        """Set the nominal state and its error covariance P0 (n, n); the GNSS and fix errors, the drag scale and the wind start at 0."""
        self.ins = StrapdownINS(t_s, lat_rad, lon_rad, h_m, vel_ned_mps, q_nb_wxyz)
        self.b_g = np.zeros(3) if b_g is None else np.array(b_g, float)
        self.b_a = np.zeros(3) if b_a is None else np.array(b_a, float)
        self.b_baro = float(b_baro)
        self._zero_estimated_errors()
        self.P = np.array(P0, float)
        self._acc_turn_rad = 0.0
        self._acc_yaw_rad = 0.0
        self._check("initial covariance")

    def _zero_estimated_errors(self) -> None:
        """The nominal values of the GNSS and fix errors, the appearance and magnetic biases,
        the drag scale, the flow's error, the camera's boresight, time offset and intrinsics and
        the wind at 0, and the pending propagation interval empty."""
        self.b_gnss, self.b_fix, self.b_app = np.zeros(3), np.zeros(3), np.zeros(3)
        self.b_mag_rad = self.drag_scale = self.td_s = 0.0
        self.b_flow_rps, self.wind_ne_mps = np.zeros(2), np.zeros(2)
        self.b_cam_rad, self.intrinsics_error, self.b_map = np.zeros(3), np.zeros(3), np.zeros(2)
        self._acc_T = 0.0
        self._acc_fn = [0.0, 0.0, 0.0]

    @property
    def t_s(self) -> float:
        return self.ins.t_s

    @property
    def C_nb(self) -> np.ndarray:
        """Nominal attitude R_nb (3, 3), body FRD -> NED."""
        return quat_to_dcm(self.ins.q)

    def covariance(self) -> np.ndarray:
        """Current error covariance (n, n), with any pending propagation applied."""
        self.flush()
        return self.P.copy()

    # ------------------------------------------------------------- prediction
    def propagate(self, t_s: float, omega_ib_b_rps, f_ib_b_mps2) -> None:
        """Advance to t_s with the raw IMU output (rad/s, m/s^2, body FRD) held over the interval."""
        ins = self.ins
        dt = t_s - ins.t_s
        if not dt > 0.0:
            return
        bg, ba = self.b_g, self.b_a
        wx, wy, wz = omega_ib_b_rps[0] - bg[0], omega_ib_b_rps[1] - bg[1], omega_ib_b_rps[2] - bg[2]
        fx, fy, fz = f_ib_b_mps2[0] - ba[0], f_ib_b_mps2[1] - ba[1], f_ib_b_mps2[2] - ba[2]
        ins.step_increments((wx * dt, wy * dt, wz * dt), (fx * dt, fy * dt, fz * dt), dt)
        ins.t_s = float(t_s)
        self.omega_ib_b_rps = (wx, wy, wz)
        # Specific force in NED (for F's -[f_n x] block), accumulated over the interval.
        qw, qx, qy, qz = ins.q
        acc = self._acc_fn
        acc[0] += ((1 - 2 * (qy * qy + qz * qz)) * fx + 2 * (qx * qy - qw * qz) * fy + 2 * (qx * qz + qw * qy) * fz) * dt
        acc[1] += (2 * (qx * qy + qw * qz) * fx + (1 - 2 * (qx * qx + qz * qz)) * fy + 2 * (qy * qz - qw * qx) * fz) * dt
        acc[2] += (2 * (qx * qz - qw * qy) * fx + 2 * (qy * qz + qw * qx) * fy + (1 - 2 * (qx * qx + qy * qy)) * fz) * dt
        self._acc_T += dt
        if self._att_var_per_rad:
            self._acc_turn_rad += math.sqrt(wx * wx + wy * wy + wz * wz) * dt
        if self.fix_error_turn_rad < math.inf:
            # Heading rate: the NED down component of the body rate (third row of C_nb).
            self._acc_yaw_rad += abs(2 * (qx * qz - qw * qy) * wx + 2 * (qy * qz + qw * qx) * wy
                                     + (1 - 2 * (qx * qx + qy * qy)) * wz) * dt
        if self._acc_T >= self.cov_interval_s:
            self.flush()

    def flush(self) -> None:
        """Propagate P over the accumulated interval (no-op when nothing is pending)."""
        T = self._acc_T
        if T <= 0.0:
            return
        ins = self.ins
        f_n = np.array(self._acc_fn) / T
        F = continuous_F(ins.lat_rad, ins.h_m, ins.vel, self.C_nb, f_n,
                         self._tau_bg_s, self._tau_ba_s, tau_gnss_s=self.gnss_error_tau_s, tau_fix_s=self.fix_error_tau_s,
                         tau_drag_s=self.drag_scale_tau_s, n=self.n)
        ia = self.i_app
        if ia is not None and math.isfinite(self.fix_error_tau_s):
            F[ia, ia] = -np.eye(3) / self.fix_error_tau_s
        Phi, Qd = discretize(F, self._qc, T)
        if self._acc_turn_rad:
            Qd[IA, IA] += (self._att_var_per_rad * self._acc_turn_rad) * np.eye(3)
        P = Phi @ self.P @ Phi.T + Qd
        self.P = 0.5 * (P + P.T)
        # Gauss-Markov nominal states decay like their errors do (consistent model).
        if math.isfinite(self._tau_bg_s):
            self.b_g *= math.exp(-T / self._tau_bg_s)
        if math.isfinite(self._tau_ba_s):
            self.b_a *= math.exp(-T / self._tau_ba_s)
        if math.isfinite(self.gnss_error_tau_s):
            self.b_gnss *= math.exp(-T / self.gnss_error_tau_s)
        if math.isfinite(self.fix_error_tau_s):
            self.b_fix *= math.exp(-T / self.fix_error_tau_s)
            self.b_app *= math.exp(-T / self.fix_error_tau_s)
        if math.isfinite(self.drag_scale_tau_s):
            self.drag_scale *= math.exp(-T / self.drag_scale_tau_s)
        if self._acc_yaw_rad > 0.0:
            # The view's turn: a Gauss-Markov step in heading, x <- a x + w, var(w) = (1 - a^2) s^2.
            a = math.exp(-self._acc_yaw_rad / self.fix_error_turn_rad)
            self._gauss_markov_step(IFX, a, np.diag(self._fix_var_m2))
            self.b_fix *= a
            if ia is not None:
                self._gauss_markov_step(ia, a, np.diag(self._app_var_m2))
                self.b_app *= a
        vn, ve, _ = ins.vel
        if self.i_mag is not None:
            # The magnetic bias decorrelates over the ground flown.
            a = math.exp(-math.hypot(vn, ve) * T / self.mag_bias_correlation_m)
            self._gauss_markov_step(self.i_mag, a, self._mag_var_rad2)
            self.b_mag_rad *= a
        if self.i_map is not None:
            # So does the map's error under the footprint (not with time, nor in turns).
            a = math.exp(-math.hypot(vn, ve) * T / self.map_error_correlation_m)
            self._gauss_markov_step(self.i_map, a, self._map_var_m2 * np.eye(2))
            self.b_map = self.b_map * a
        if self.i_flow is not None:
            # The flow's error decorrelates with time and with the ground its view passes.
            k = T / self.flow_bias_tau_s + self.flow_view_rate_rps * T / self.flow_bias_correlation_rad
            if k > 0.0:
                a = math.exp(-k)
                self._gauss_markov_step(self.i_flow, a, self._flow_var * np.eye(2))
                self.b_flow_rps = self.b_flow_rps * a
        self._acc_T = 0.0
        self._acc_fn = [0.0, 0.0, 0.0]
        self._acc_turn_rad = 0.0
        self._acc_yaw_rad = 0.0
        self._check("covariance propagation")

    def _gauss_markov_step(self, idx, a: float, steady_cov) -> None:
        """One Gauss-Markov step of the error states idx (a slice or an index) in P:
        x <- a x + w, cov(w) = (1 - a^2) steady_cov (the states' steady-state covariance,
        (k, k) for a slice, a variance for an index)."""
        self.P[idx, :] *= a
        self.P[:, idx] *= a
        self.P[idx, idx] += (1.0 - a * a) * steady_cov

    # ---------------------------------------------------------------- updates
    def update(self, kind: str, t_s: float, y, H, R, gate: bool = True) -> CorrectionInfo:
        """Kalman update with residual y (m,), Jacobian H (m, n), noise R (m, m).

        The NIS y^T S^-1 y is compared with the chi-square quantile at gate_probability;
        a rejected measurement leaves the state untouched.
        """
        self.flush()
        y = np.atleast_1d(np.asarray(y, float))
        H = np.atleast_2d(np.asarray(H, float))
        R = np.atleast_2d(np.asarray(R, float))
        P = self.P
        PHt = P @ H.T
        S = H @ PHt + R
        S = 0.5 * (S + S.T)
        try:
            S_inv = np.linalg.inv(S)
        except np.linalg.LinAlgError:
            raise SimulationAborted(f"EKF {kind} update: singular innovation covariance",
                                    t_s=t_s, vehicle_id=self.vehicle_id) from None
        nis = float(y @ S_inv @ y)
        accepted = bool(np.isfinite(nis)) and (
            not gate or self.gate_probability >= 1.0 or nis <= chi2_threshold(self.gate_probability, y.size)
        )
        if accepted:
            K = PHt @ S_inv
            dx = K @ y
            IKH = np.eye(self.n) - K @ H
            P = IKH @ P @ IKH.T + K @ R @ K.T  # Joseph form
            self.inject(dx)
            # Covariance reset P <- G P G^T; G is the identity but for its attitude block.
            Ga = reset_jacobian(dx[IA])[IA, IA]
            P[IA, :] = Ga @ P[IA, :]
            P[:, IA] = P[:, IA] @ Ga.T
            self.P = 0.5 * (P + P.T)
            self._check(f"{kind} update")
        return CorrectionInfo(t_s=float(t_s), kind=kind, innovation=y, innovation_cov=S,
                              nis=nis, accepted=accepted)

    def check(self, kind: str, t_s: float, y, H, R) -> CorrectionInfo:
        """The innovation, its covariance and NIS of a measurement (y (m,), H (m, n), R (m, m)),
        without fusing it: accepted=False, the state untouched (a source held out, e.g. GNSS
        while the spoofing monitor alarms, still shows in the corrections how far off it is)."""
        self.flush()
        y = np.atleast_1d(np.asarray(y, float))
        H = np.atleast_2d(np.asarray(H, float))
        S = H @ self.P @ H.T + np.atleast_2d(np.asarray(R, float))
        S = 0.5 * (S + S.T)
        nis = float(y @ np.linalg.solve(S, y))
        return CorrectionInfo(t_s=float(t_s), kind=kind, innovation=y, innovation_cov=S, nis=nis, accepted=False)

    def inject(self, dx: np.ndarray) -> None:
        """Nominal <- nominal (+) dx (n,)."""
        ins = self.ins
        lat, lon, h, v, q = inject_nav(ins.lat_rad, ins.lon_rad, ins.h_m, ins.vel, ins.q, dx)
        ins.lat_rad, ins.lon_rad, ins.h_m = lat, lon, h
        ins.vel = tuple(float(x) for x in v)
        ins.q = tuple(float(x) for x in q)
        self.b_g = self.b_g + dx[IBG]
        self.b_a = self.b_a + dx[IBA]
        self.b_baro += float(dx[IBB])
        self.b_gnss = self.b_gnss + dx[IGN]
        self.b_fix = self.b_fix + dx[IFX]
        self.drag_scale += float(dx[IDS])
        if self.wind_states:
            self.wind_ne_mps = self.wind_ne_mps + dx[IW]
        if self.i_app is not None:
            self.b_app = self.b_app + dx[self.i_app]
        if self.i_mag is not None:
            self.b_mag_rad += float(dx[self.i_mag])
        if self.i_flow is not None:
            self.b_flow_rps = self.b_flow_rps + dx[self.i_flow]
        if self.i_cam is not None:
            self.b_cam_rad = self.b_cam_rad + dx[self.i_cam]
        if self.i_td is not None:
            self.td_s += float(dx[self.i_td])
        if self.i_ci is not None:
            self.intrinsics_error = self.intrinsics_error + dx[self.i_ci]
        if self.i_map is not None:
            self.b_map = self.b_map + dx[self.i_map]

    # ------------------------------------------------------------------ guard
    def _check(self, where: str) -> None:
        P = self.P
        ins = self.ins
        state_ok = math.isfinite(ins.lat_rad + ins.lon_rad + ins.h_m + sum(ins.vel) + sum(ins.q))
        # A sum is finite only if every element is (inf - inf is nan).
        if not state_ok or not math.isfinite(float(P.sum())) or float(P.diagonal().min()) < 0.0:
            raise SimulationAborted(
                f"EKF diverged after {where}: non-finite state or covariance, or negative "
                f"variance (state finite: {state_ok}, covariance finite: {bool(np.all(np.isfinite(P)))}, "
                f"min variance {float(np.min(np.diag(P))):.3g})",
                t_s=ins.t_s, vehicle_id=self.vehicle_id,
            )
