"""Per-neighbour EKF on relative position and velocity (NED), fusing camera bearings and UWB
ranges over time.

State x = [r (3), w (3)]: r = p_peer - p_self (m, NED), w = dr/dt (m/s). Process: the peer's
velocity is a random walk (white acceleration of spectral density sigma_accel^2 per axis: its
manoeuvres); our OWN velocity change over a prediction step, dv_self from our own estimate
(when the caller gives it), is known and taken out: w <- w - dv_self and r advances by
(w - dv_self / 2) dt (our velocity taken to change evenly over the step).
Without it our own manoeuvres would have to hide in sigma_accel too, and a follower swinging
at 2 m/s^2 while its bearings were stale carried its neighbours' estimates 10 m away with a
claimed sigma of 1 m. Measurements:
- bearing: normalised image coordinates m = (d_x/d_z, d_y/d_z) of d = R_nc^T (r - c), c the
  camera centre offset R_nb l_cam (NED), R_nc = R_nb R_bc with the OWN ESTIMATED attitude; noise:
  the detection's (bearing_noise_cov: (sigma_px / f)^2 alike over the image, "pixel", or
  stretched as the lens stretches angles, "angle") plus the attitude uncertainty mapped
  through (1 + m^2);
- range: rho = |r + b| + n, b = R_nb (l_uwb_peer - l_uwb_self) (zero for one installation).
Robustness to NLOS (a positive excess W >= 0 on the range): the normalised innovation squared
of a range longer than predicted is gated at the chi-square(1) quantile and rejected ranges
are counted (a shorter one cannot be NLOS and is always fused); after
`max_consecutive_rejects` in a row (the filter, not the range, is probably wrong) the next
range is accepted with its noise inflated so that its NIS equals the gate (a bounded pull).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2


_EVEN_CHANGE_MAX_S = 0.3  # steps longer than this get the own-displacement uncertainty in Q


# Identity blocks reused every step (np.eye allocates; these are only ever read).
_I2 = np.eye(2)
_I3 = np.eye(3)
_I6 = np.eye(6)
_I2.flags.writeable = _I3.flags.writeable = _I6.flags.writeable = False


def constant_velocity_F(dt_s: float) -> np.ndarray:
    """Transition (6, 6) of the relative state [r, w] (NED m, m/s) over dt_s: r += dt_s w."""
    F = _I6.copy()
    F[:3, 3:] = dt_s * _I3
    return F


def bearing_noise_cov(m_xy: np.ndarray, sigma_px: float, focal_px: float, model: str) -> np.ndarray:
    """Covariance (2, 2) of a detection's normalised image coordinates m_xy (2,) (undistorted)
    for a centre error of sigma_px pixels at the image centre (focal length focal_px).

    "pixel": (sigma_px / f)^2 I, alike over the whole image. "angle": the error is an angle,
    sigma_px / f radians wherever the vehicle stands, which a rectilinear (pinhole) projection
    stretches radially by 1 + r^2 and tangentially by sqrt(1 + r^2) (r = |m| = tan of the
    angle off the optical axis): (sigma_px / f)^2 (1 + m.m) (I + m m^T). At the horizontal edge
    of a 120 deg field (r = 1.73) that is 4x radially and 2x tangentially.

    Why "angle": an LED detection's error is mostly the vehicle's own extent and what stands
    on its line of sight (which LEDs are lit, a vehicle 100 m behind it), both angles. On the
    arrowhead (paper_swarm_relnav, LED, 90 s) the centres within 60 px of a side camera's
    left or right edge erred by 3.7-6.5 px (sd) horizontally and 0.9-1.3 px vertically against
    0.99 / 0.37 px inside, so a constant pixel sigma weighted the edge bearings up to
    sixteen times too heavily (docs/measurements.md, "Bearings at the cameras' edges")."""
    s2 = (sigma_px / focal_px) ** 2
    if model == "pixel":
        return _I2 * s2
    if model != "angle":
        raise ValueError(f"bearing_sigma_model: {model!r}, expected 'pixel' or 'angle'")
    m = np.asarray(m_xy, float)
    return s2 * (1.0 + float(m @ m)) * (_I2 + np.outer(m, m))


@dataclass(frozen=True)
class FilterSettings:
    """sigma_accel_mps2: relative acceleration noise; range_sigma_m: UWB noise;
    bearing_sigma_px: pixel noise of a detection centre (at the image centre);
    bearing_sigma_model: how that noise spreads over the image, "pixel" or "angle"
    (bearing_noise_cov); robust: gate ranges (NLOS);
    gate_prob: chi-square gate probability (ranges and bearings);
    max_consecutive_rejects: after this many rejected ranges in a row, accept one softly;
    init_vel_sigma_mps: initial relative-velocity uncertainty."""

    sigma_accel_mps2: float = 1.0
    range_sigma_m: float = 0.10
    bearing_sigma_px: float = 1.0
    bearing_sigma_model: str = "pixel"
    robust: bool = True
    gate_prob: float = 0.999
    max_consecutive_rejects: int = 10
    init_vel_sigma_mps: float = 3.0


class NeighbourFilter:
    """EKF of one neighbour's relative state (see module docstring)."""

    def __init__(self, t_s: float, r0_ned_m, cov_r0, settings: FilterSettings | None = None, w0=None):
        self.s = settings or FilterSettings()
        self.t_s = float(t_s)
        self.x = np.zeros(6)
        self.x[:3] = np.asarray(r0_ned_m, float)
        if w0 is not None:
            self.x[3:] = np.asarray(w0, float)
        self.P = np.zeros((6, 6))
        self.P[:3, :3] = np.asarray(cov_r0, float)
        self.P[3:, 3:] = np.eye(3) * self.s.init_vel_sigma_mps**2
        self.gate1 = float(chi2.ppf(self.s.gate_prob, 1))
        self.gate2 = float(chi2.ppf(self.s.gate_prob, 2))
        self.consecutive_rejects = 0
        self.consecutive_bearing_rejects = 0
        self.counters = {"range_accepted": 0, "range_rejected": 0, "range_soft": 0,
                         "bearing_accepted": 0, "bearing_rejected": 0}
        self.last_bearing_t_s = -np.inf
        self.last_range_t_s = -np.inf
        self.v_self: np.ndarray | None = None  # own velocity (NED m/s) at t_s, when known

    def predict(self, t_s: float, v_self_ned_mps=None) -> None:
        """Advance to t_s; v_self_ned_mps (3,): our own estimated velocity at t_s, whose change
        since the last step is our own acceleration (known, taken out of w)."""
        dt = float(t_s) - self.t_s
        dv = None
        if v_self_ned_mps is not None and (self.v_self is None or dt > 0):
            v = np.asarray(v_self_ned_mps, float)
            if self.v_self is not None:
                dv = v - self.v_self
                # Our velocity taken to change evenly over the step: the mean relative velocity
                # is w - dv / 2, and F below moves r with the new w - dv.
                self.x[3:] -= dv
                self.x[:3] += 0.5 * dt * dv
            self.v_self = v.copy()
        if dt <= 0:
            return
        F = constant_velocity_F(dt)
        q = self.s.sigma_accel_mps2**2
        Q = np.zeros((6, 6))
        Q[:3, :3] = _I3 * q * dt**3 / 3
        Q[:3, 3:] = Q[3:, :3] = _I3 * q * dt**2 / 2
        Q[3:, 3:] = _I3 * q * dt
        if dv is not None and dt > _EVEN_CHANGE_MAX_S:
            # Over a long gap our velocity did not change evenly (a follower swinging about its
            # slot): the displacement dv dt / 2 is uncertain by as much again.
            Q[:3, :3] += np.diag((0.5 * dt * dv) ** 2)
        self.x = F @ self.x
        self.P = F @ self.P @ F.T + Q
        self.t_s = float(t_s)

    def _update(self, y: np.ndarray, H: np.ndarray, R: np.ndarray) -> None:
        S = H @ self.P @ H.T + R
        K = np.linalg.solve(S, H @ self.P).T
        self.x = self.x + K @ y
        I_KH = _I6 - K @ H
        self.P = I_KH @ self.P @ I_KH.T + K @ R @ K.T  # Joseph form keeps P symmetric PSD
        self.P = 0.5 * (self.P + self.P.T)

    # -- measurements ---------------------------------------------------------------------

    def bearing_model(self, R_nc: np.ndarray, cam_offset_ned_m) -> tuple[np.ndarray, np.ndarray]:
        """Predicted normalised image coordinates (2,) and their Jacobian (2, 6)."""
        d = (self.x[:3] - np.asarray(cam_offset_ned_m, float)) @ R_nc  # R_nc^T (r - c)
        z = d[2] if abs(d[2]) > 1e-6 else 1e-6
        h = np.array([d[0] / z, d[1] / z])
        J = np.array([[1 / z, 0.0, -d[0] / z**2], [0.0, 1 / z, -d[1] / z**2]])
        H = np.zeros((2, 6))
        H[:, :3] = J @ R_nc.T
        return h, H

    def update_bearing(self, t_s: float, m_xy, R_nc: np.ndarray, cam_offset_ned_m, focal_px: float,
                       att_sigma_rad: float = 0.0, v_self_ned_mps=None) -> tuple[float, bool]:
        """Fuse normalised image coordinates m_xy (2,) seen by a camera with attitude R_nc
        (camera -> NED, own estimate) and centre offset cam_offset_ned_m; v_self_ned_mps: our
        own velocity estimate at t_s (see predict). Returns (NIS, accepted)."""
        self.predict(t_s, v_self_ned_mps)
        m = np.asarray(m_xy, float)
        h, H = self.bearing_model(R_nc, cam_offset_ned_m)
        d = (self.x[:3] - cam_offset_ned_m) @ R_nc
        if d[2] <= 0.1 * np.linalg.norm(d):  # behind or beside the camera: a wrong association
            self.counters["bearing_rejected"] += 1
            self.consecutive_bearing_rejects += 1
            return float("inf"), False
        R = (bearing_noise_cov(m, self.s.bearing_sigma_px, focal_px, self.s.bearing_sigma_model)
             + _I2 * (att_sigma_rad**2 * (1.0 + m @ m) ** 2))
        y = m - h
        S = H @ self.P @ H.T + R
        nis = float(y @ np.linalg.solve(S, y))
        if nis > self.gate2:
            self.counters["bearing_rejected"] += 1
            self.consecutive_bearing_rejects += 1
            return nis, False
        self.consecutive_bearing_rejects = 0
        self._update(y, H, R)
        self.counters["bearing_accepted"] += 1
        self.last_bearing_t_s = float(t_s)
        return nis, True

    def update_range(self, t_s: float, range_m: float, lever_diff_ned_m=(0.0, 0.0, 0.0),
                     v_self_ned_mps=None) -> tuple[float, bool]:
        """Fuse one UWB range; lever_diff_ned_m = R_nb (l_peer - l_self); v_self_ned_mps as in
        predict. Returns (NIS, accepted)."""
        self.predict(t_s, v_self_ned_mps)
        a = self.x[:3] + np.asarray(lever_diff_ned_m, float)
        n = float(np.linalg.norm(a))
        if n < 1e-6:
            return float("nan"), False
        H = np.zeros((1, 6))
        H[0, :3] = a / n
        R = np.array([[self.s.range_sigma_m**2]])
        y = np.array([float(range_m) - n])
        S = float((H @ self.P @ H.T + R)[0, 0])
        nis = float(y[0] ** 2 / S)
        # NLOS only lengthens a range: a range much SHORTER than predicted is a line-of-sight
        # range telling that the estimate has drifted, and is fused (rejecting it left one
        # estimate 4.6 m long while its neighbour receded at 2.5 m/s).
        if self.s.robust and nis > self.gate1 and y[0] > 0.0:
            self.consecutive_rejects += 1
            if self.consecutive_rejects <= self.s.max_consecutive_rejects:
                self.counters["range_rejected"] += 1
                return nis, False
            # Persistent disagreement: accept softly (NIS brought down to the gate).
            R = R + (y[0] ** 2 / self.gate1 - S)
            self.counters["range_soft"] += 1
        # (An accepted range says nothing of the direction: it leaves the bearing rejects count.)
        self.consecutive_rejects = 0
        self._update(y, H, R)
        self.counters["range_accepted"] += 1
        self.last_range_t_s = float(t_s)
        return nis, True


def initial_covariance(rel_ned_m, range_sigma_m: float, angle_sigma_rad: float) -> np.ndarray:
    """Covariance (3, 3) of a position from one range (along the line of sight) and one
    bearing (across it): e e^T sigma_rho^2 + (I - e e^T) (rho sigma_theta)^2."""
    r = np.asarray(rel_ned_m, float)
    rho = float(np.linalg.norm(r))
    e = r / max(rho, 1e-6)
    E = np.outer(e, e)
    return E * range_sigma_m**2 + (np.eye(3) - E) * (rho * angle_sigma_rad) ** 2
