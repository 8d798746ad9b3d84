"""Measurement models of the error-state EKF: residual y = z - h(nominal), Jacobian
H = d h(nominal (+) error) / d error at zero error (ekf.n columns, error_model layout), noise R.

Each function takes the filter (`ErrorStateEKF`) for its nominal state and returns (y, H, R).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from testbench.core import geodesy
from testbench.core.interfaces import GeodeticOrigin
from testbench.core.rotations import dcm_to_euler, dcm_to_quat, heading_sensitivity, quat_to_rotvec, skew, wrap_pi
from testbench.navigation.ins.error_model import IA, IBA, IBB, IDS, IFX, IGN, IP, IV, IW


def gnss_position(ekf, lat_rad: float, lon_rad: float, alt_m: float, sigma_ned_m):
    """GNSS position (geodetic) -> residual in NED metres at the vehicle.

    The fix is the true position plus the receiver's correlated error (the b_gnss state) plus
    white noise of sigma_ned_m: H = [I 0 ... 0 I] (position and GNSS-error columns)."""
    ins = ekf.ins
    r_m, r_n = geodesy.radii_of_curvature(ins.lat_rad)
    y = np.array([
        (r_m + ins.h_m) * (lat_rad - ins.lat_rad),
        (r_n + ins.h_m) * math.cos(ins.lat_rad) * math.remainder(lon_rad - ins.lon_rad, 2 * math.pi),
        -(alt_m - ins.h_m),
    ]) - ekf.b_gnss
    H = np.zeros((3, ekf.n))
    H[:, IP] = np.eye(3)
    H[:, IGN] = np.eye(3)
    return y, H, np.diag(np.square(sigma_ned_m))


def gnss_velocity(ekf, vel_ned_mps, sigma_ned_mps):
    """GNSS velocity (NED m/s); H = [0 I 0 ...]."""
    y = np.asarray(vel_ned_mps, float) - np.array(ekf.ins.vel)
    H = np.zeros((3, ekf.n))
    H[:, IV] = np.eye(3)
    return y, H, np.diag(np.square(sigma_ned_mps))


def _c_en(lat_rad: float, lon_rad: float) -> np.ndarray:
    """C_en (3, 3): NED at (lat, lon) -> ECEF (geodesy.C_en for one point, without overhead)."""
    sl, cl, so, co = math.sin(lat_rad), math.cos(lat_rad), math.sin(lon_rad), math.cos(lon_rad)
    return np.array([[-sl * co, -so, -cl * co], [-sl * so, co, -cl * so], [cl, 0.0, -sl]])


def _ecef(lat_rad: float, lon_rad: float, h_m: float) -> np.ndarray:
    sl, cl = math.sin(lat_rad), math.cos(lat_rad)
    r_n = geodesy.A_M / math.sqrt(1.0 - geodesy.E2 * sl * sl)
    return np.array([(r_n + h_m) * cl * math.cos(lon_rad), (r_n + h_m) * cl * math.sin(lon_rad),
                     (r_n * (1.0 - geodesy.E2) + h_m) * sl])


@lru_cache(maxsize=16)
def _origin_frame(origin: GeodeticOrigin) -> tuple[np.ndarray, np.ndarray]:
    """(ECEF position of the origin (3,), C_ne at the origin (3, 3): ECEF -> origin NED)."""
    return _ecef(origin.lat_rad, origin.lon_rad, origin.alt_m), _c_en(origin.lat_rad, origin.lon_rad).T


def origin_rotation(lat_rad: float, lon_rad: float, origin: GeodeticOrigin) -> np.ndarray:
    """R_on (3, 3): vehicle-local NED -> NED at the scenario origin (v_o = R_on v_n)."""
    return _origin_frame(origin)[1] @ _c_en(lat_rad, lon_rad)


def nominal_pos_ned(ekf, origin: GeodeticOrigin) -> np.ndarray:
    """Nominal position (3,) in local NED at the scenario origin (m)."""
    ins = ekf.ins
    r0, c_ne0 = _origin_frame(origin)
    return c_ne0 @ (_ecef(ins.lat_rad, ins.lon_rad, ins.h_m) - r0)


def position_ned(ekf, pos_ned_m, cov_ned_m2, origin: GeodeticOrigin, att_sensitivity_m_per_rad=None,
                 appearance_gain: float = 0.0, vel_lag_s=None, from_map: bool = False):
    """Position fix in NED at the scenario origin (scene matching): the true position plus the
    error successive fixes share (the b_fix state, origin NED) plus white noise of covariance
    cov_ned_m2; H = [R_on 0 ... I].

    att_sensitivity_m_per_rad (3, 3), M: the fix leaned on the filter's own attitude (a pose
    solve with the INS attitude as prior), so its error holds -M phi; then H_phi = -M, and
    cov_ned_m2 must be the fix's covariance given the attitude (PositionFix). With the camera's
    boresight states (ekf.i_cam) the solve was seeded with the mounting corrected by the
    estimate b_cam_hat (NavEstimate.camera_boresight_b_rad), so its prior's camera attitude errs
    by psi = Log(Exp(phi) C Exp(b_cam) Exp(-b_cam_hat) C^T) = phi + C J db to first order (db =
    b_cam - b_cam_hat, J = I + [b_cam_hat x] / 2 the left Jacobian of Exp): the fix holds -M psi,
    H_phi = -M, H_b = -M C J.

    appearance_gain g (dimensionless): with the filter's appearance states (ekf.i_app), the fix
    also holds g b_app, the appearance error scaled by how strongly this fix shows it
    (ErrorStateEKF appearance_sigma_m); H[:, i_app] = g I. Ignored without those states.

    vel_lag_s tau (s), or a (3, 3) lag matrix L (s, origin NED): the fix was carried over its
    last tau seconds on the filter's estimated velocity (PositionFix.vel_lag_s), so it holds
    tau (v_est - v_true) = -tau dv: H_v = -tau R_on (-L R_on).

    from_map: the fix was matched against the reference map, so with the map error states
    (ekf.i_map) it also holds the map's displacement b_map (north, east): H[:2, i_map] = I."""
    ins = ekf.ins
    y = np.asarray(pos_ned_m, float) - nominal_pos_ned(ekf, origin) - ekf.b_fix
    H = np.zeros((3, ekf.n))
    H[:, IP] = origin_rotation(ins.lat_rad, ins.lon_rad, origin)
    H[:, IFX] = np.eye(3)
    if ekf.i_app is not None and appearance_gain:
        y = y - appearance_gain * ekf.b_app
        H[:, ekf.i_app] = appearance_gain * np.eye(3)
    if ekf.i_map is not None and from_map:
        y[:2] = y[:2] - ekf.b_map
        H[:2, ekf.i_map] = np.eye(2)
    if att_sensitivity_m_per_rad is not None:
        M = np.asarray(att_sensitivity_m_per_rad, float)
        H[:, IA] = -M
        if ekf.i_cam is not None:
            H[:, ekf.i_cam] = -M @ ekf.C_nb @ (np.eye(3) + 0.5 * skew(ekf.b_cam_rad))
    if vel_lag_s is not None:
        lag = np.asarray(vel_lag_s, float)
        H[:, IV] = -(lag @ H[:, IP] if lag.ndim == 2 else float(lag) * H[:, IP])
    return y, H, np.asarray(cov_ned_m2, float)


def add_lag(vel_lag_s, tau_s: float):
    """A fix's velocity lag (PositionFix.vel_lag_s: None, tau (s) or a lag matrix L (s)) after
    it is carried tau_s further on the estimated velocity: tau_s, tau + tau_s, or L + tau_s I."""
    if vel_lag_s is None:
        return tau_s
    lag = np.asarray(vel_lag_s, float)
    return lag + tau_s * (np.eye(lag.shape[0]) if lag.ndim == 2 else 1.0)


@dataclass(frozen=True)
class TimeOffsetTerms:
    """What a position fix of a camera whose clock is off holds of its time offset td (the
    frame's stamp minus its exposure; the filter's state ekf.i_td, estimate td_hat = ekf.td_s).

    The image shows the vehicle at t - td: at p(t) - v td, and with the attitude
    Exp(-omega_n td) C it had then (omega_n the body's rate in NED). The scene matcher solved it
    with the prior of t - td_hat (IsmnAid), so the fix errs from p(t) - v td by -M psi, where psi,
    the prior's attitude error against the image's, is phi - omega_n (td - td_hat). Hence
    z = p(t) - v td_hat + ... with H_td = -R_on v + M omega_n (position_column), and the fix
    carried to the stamp on the estimated velocity (carried: z + R_on v td_hat, the lag term
    -td_hat R_on on the velocity error). The image heading is the one of t - td:
    heading + psi_dot td_hat against the filter's, H_td = -psi_dot (heading_rate_rps).

    v_on_mps (3,): the estimated velocity in origin NED; omega_n_rps (3,): the estimated body
    rate relative to the Earth in NED; td_s: td_hat; heading_rate_rps: d heading / dt."""

    v_on_mps: np.ndarray
    omega_n_rps: np.ndarray
    td_s: float
    heading_rate_rps: float

    @classmethod
    def of(cls, ekf, origin: GeodeticOrigin) -> "TimeOffsetTerms":
        ins = ekf.ins
        C = ekf.C_nb
        omega_n = C @ np.asarray(ekf.omega_ib_b_rps, float) - geodesy.earth_rate_ned_rps(ins.lat_rad)
        v_on = origin_rotation(ins.lat_rad, ins.lon_rad, origin) @ np.asarray(ins.vel, float)
        return cls(v_on, omega_n, float(ekf.td_s), float(heading_sensitivity(C) @ omega_n))

    def carried(self, pos_ned_m, vel_lag_s):
        """(the fix carried to its stamp (3,) origin NED m, its velocity lag: vel_lag_s + td_hat)."""
        return np.asarray(pos_ned_m, float) + self.v_on_mps * self.td_s, add_lag(vel_lag_s, self.td_s)

    def position_column(self, att_sensitivity_m_per_rad=None) -> np.ndarray:
        """H_td (3,) of the carried fix: -R_on v, plus M omega_n with the attitude coupling M."""
        col = -self.v_on_mps
        if att_sensitivity_m_per_rad is not None:
            col = col + np.asarray(att_sensitivity_m_per_rad, float) @ self.omega_n_rps
        return col

    def carried_heading(self, heading_rad: float) -> float:
        return float(heading_rad) + self.heading_rate_rps * self.td_s


def image_pose(ekf, pos_ned_m, R_nb_img, cov_pose, origin: GeodeticOrigin, appearance_gain: float = 0.0,
               from_map: bool = False):
    """A camera's pose the image alone gives (PositionFix.image_*), as one measurement of
    position and attitude: pos_ned_m (3,) NED m at the origin and R_nb_img (3, 3) body -> NED,
    both through the camera's calibrated mounting, with their joint covariance cov_pose (6, 6)
    [position NED m, attitude NED rad] (the white part: the shared fix errors are states).

    Position rows as position_ned without an attitude coupling (the image alone does not lean
    on the filter). Attitude rows: the camera really sits at Exp(b_cam) R_bc (ekf.i_cam, body
    axes), so the body attitude read through the calibrated R_bc is R_nb_true Exp(b_cam) =
    Exp(C_true b_cam) Exp(phi) C, C_true b_cam = C b_cam - [C b_cam x] phi: y = Log(R_nb_img
    C^T) - C b_cam_hat, H_b = C, H_phi = I + [a x] / 2 - [C b_cam_hat x] with a = Log(R_nb_img C^T)
    (the inverse right Jacobian of Log to first order: a boresight of a degree is 0.017 rad, whose
    half is not small against the 1e-4 rad the image resolves). Without the boresight states the
    attitude rows are those of an attitude measurement alone (H_phi = I + [a x] / 2)."""
    y_p, H_p, _ = position_ned(ekf, pos_ned_m, np.eye(3), origin, appearance_gain=appearance_gain, from_map=from_map)
    C = ekf.C_nb
    y_a = _log_rotation(np.asarray(R_nb_img, float) @ C.T)
    H_a = np.zeros((3, ekf.n))
    H_a[:, IA] = np.eye(3) + 0.5 * skew(y_a)
    if ekf.i_cam is not None:
        b_n = C @ ekf.b_cam_rad
        y_a = y_a - b_n
        H_a[:, IA] -= skew(b_n)
        H_a[:, ekf.i_cam] = C
    return np.concatenate([y_p, y_a]), np.vstack([H_p, H_a]), np.asarray(cov_pose, float)


def _log_rotation(R: np.ndarray) -> np.ndarray:
    """The rotation vector (3,) rad of a rotation matrix R (3, 3) (R = Exp(v))."""
    return quat_to_rotvec(dcm_to_quat(R))


def baro_altitude(ekf, altitude_m: float, sigma_m: float):
    """Barometric altitude = h + b_baro; H[dp_D] = -1 (dh = -dp_D), H[b_baro] = 1."""
    y = np.array([altitude_m - (ekf.ins.h_m + ekf.b_baro)])
    H = np.zeros((1, ekf.n))
    H[0, IP.start + 2] = -1.0
    H[0, IBB] = 1.0
    return y, H, np.array([[sigma_m**2]])


def mag_vector(ekf, field_b_T, field_ned_T, sigma_T: float):
    """3-axis magnetometer against the onboard model: h = C_nb^T B_n.

    With C_true = (I + [phi x]) C_nb: h = C_nb^T B_n + C_nb^T [B_n x] phi, so H_phi = C_nb^T [B_n x].
    """
    C = ekf.C_nb
    B_n = np.asarray(field_ned_T, float)
    H = np.zeros((3, ekf.n))
    if ekf.i_mag is not None:
        # A heading bias b (mag_heading: heading = true + b) is the sensed field turned by -b
        # about down: B = Rz(-b) B_n, dB/db = -(e_D x B) = (B_E, -B_N, 0).
        c, s = math.cos(ekf.b_mag_rad), math.sin(ekf.b_mag_rad)
        B_n = np.array([c * B_n[0] + s * B_n[1], -s * B_n[0] + c * B_n[1], B_n[2]])
        H[:, ekf.i_mag] = C.T @ np.array([B_n[1], -B_n[0], 0.0])
    H[:, IA] = C.T @ skew(B_n)
    y = np.asarray(field_b_T, float) - C.T @ B_n
    return y, H, np.eye(3) * sigma_T**2


def mag_heading(ekf, field_b_T, field_ned_T, sigma_rad: float):
    """Magnetic heading: the body field levelled with the nominal roll and pitch, plus the
    model's declination, compared with the nominal yaw.

    The levelling uses the filter's own tilt, so a tilt error enters the heading: with
    C_true = Exp(phi) C_nb, the levelled field is Rz(yaw)^T (B_n + [B_n x] phi), and at an
    inclination I a north tilt error moves the heading by about -tan(I) times itself (x2.7 at
    70 deg). H therefore has tilt columns as well as the yaw one; with only the yaw column
    (the common heading-aiding shortcut) the filter read tilt error as heading information and
    claimed half the heading error it had (20-run batch of paper_ismn_800m: 0.9 mrad claimed,
    1.4-2.0 mrad RMS)."""
    C = ekf.C_nb
    roll, pitch, yaw = dcm_to_euler(C)
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    bx, by, bz = field_b_T
    # Levelled field: Ry(pitch) Rx(roll) B_b (body -> heading frame).
    hx = cp * bx + sp * sr * by + sp * cr * bz
    hy = cr * by - sr * bz
    B_n = np.asarray(field_ned_T, float)
    decl = math.atan2(B_n[1], B_n[0])
    heading = decl - math.atan2(hy, hx)
    y = np.array([float(wrap_pi(heading - yaw))])
    # Jacobian of heading = decl - atan2(h_y, h_x) with h = Rz(yaw)^T (B_n + [B_n x] phi).
    cy, sy = math.cos(yaw), math.sin(yaw)
    Rz_T = np.array([[cy, sy, 0.0], [-sy, cy, 0.0], [0.0, 0.0, 1.0]])
    h0 = Rz_T @ B_n
    dh = Rz_T @ skew(B_n)  # d h / d phi (3, 3)
    H = np.zeros((1, ekf.n))
    H[0, IA] = -(h0[0] * dh[1] - h0[1] * dh[0]) / (h0[0] ** 2 + h0[1] ** 2)
    if ekf.i_mag is not None:
        # The magnetic heading is the true one plus the bias (ErrorStateEKF mag_bias_*).
        y[0] = wrap_pi(y[0] - ekf.b_mag_rad)
        H[0, ekf.i_mag] = 1.0
    return y, H, np.array([[sigma_rad**2]])


def drag_specific_force(ekf, f_b_xy_mps2, v_b_xy_mps, mu_per_s: float, sigma_mps2: float):
    """Rotor-drag aiding: the accelerometers' body x, y specific force (2,) m/s^2, averaged
    over an interval, against h = -mu (1 + s) v_b_xy + b_a_xy (s = ekf.drag_scale, the
    filter's estimate of the scale error of mu), v_b_xy (2,) the nominal body velocity through
    the air averaged over the same interval: C^T (v - w) with the filter's wind states, C^T v
    without (calm air, air and ground velocity taken as one).

    With C_true = (I + [phi x]) C_nb, v_true = v + dv, w_true = w + dw and a = v - w:
    a_b_true = C^T a + C^T (dv - dw) + C^T [a x] phi, so with m = mu (1 + s): H_v = -m S C^T,
    H_w = +m (S C^T)_NE, H_phi = -m S C^T [a x], H_ba = S (S: the body x and y rows),
    H_s = -mu v_b_xy."""
    C = ekf.C_nb
    v = air_velocity_ned(ekf) if ekf.wind_states else np.array(ekf.ins.vel)
    v_b = np.asarray(v_b_xy_mps, float)
    mu_eff = mu_per_s * (1.0 + ekf.drag_scale)
    y = np.asarray(f_b_xy_mps2, float) - (-mu_eff * v_b + ekf.b_a[:2])
    H = np.zeros((2, ekf.n))
    Ct = C.T[:2]
    H[:, IV] = -mu_eff * Ct
    H[:, IA] = -mu_eff * Ct @ skew(v)
    H[:, IBA] = np.eye(3)[:2]
    H[:, IDS] = -mu_per_s * v_b
    if ekf.wind_states:
        H[:, IW] = mu_eff * Ct[:, :2]
    return y, H, np.eye(2) * sigma_mps2**2


def air_velocity_ned(ekf) -> np.ndarray:
    """(3,) the nominal velocity through the air, v - (w_N, w_E, 0), NED m/s."""
    v = np.array(ekf.ins.vel, float)
    v[:2] -= ekf.wind_ne_mps
    return v


def true_airspeed(ekf, airspeed_mps: float, sigma_mps: float):
    """Pitot true airspeed (m/s) against h = |v - w| (the speed through the air; the wind w is
    horizontal, ekf.wind_ne_mps). With u = (v - w) / |v - w|: H_v = u, H_w = -u_NE. The pitot's
    own angle-of-attack error is left in sigma."""
    a = air_velocity_ned(ekf)
    speed = float(np.linalg.norm(a))
    u = a / speed
    y = np.array([float(airspeed_mps) - speed])
    H = np.zeros((1, ekf.n))
    H[0, IV] = u
    H[0, IW] = -u[:2]
    return y, H, np.array([[sigma_mps**2]])


def zero_sideslip(ekf, sigma_rad: float):
    """Synthetic measurement of a fixed wing in coordinated flight: its velocity through the
    air has no body y (right) component, 0 against h = e_y C_true^T (v_true - w_true), with
    noise sigma_rad |v - w| (a sideslip of sigma_rad). With C_true = (I + [phi x]) C_nb:
    C_true^T a = C^T a + C^T [a x] phi, so H_v = e_y C^T, H_w = -(e_y C^T)_NE, H_phi = e_y C^T [a x]."""
    a = air_velocity_ned(ekf)
    Ct_y = ekf.C_nb[:, 1]  # the body y axis in NED: row y of C^T
    y = np.array([-float(Ct_y @ a)])
    H = np.zeros((1, ekf.n))
    H[0, IV] = Ct_y
    H[0, IW] = -Ct_y[:2]
    H[0, IA] = Ct_y @ skew(a)
    sigma = sigma_rad * float(np.linalg.norm(a))
    return y, H, np.array([[sigma**2]])


def fix_heading(ekf, heading_rad: float, sigma_rad: float):
    """A heading measured independently of the filter (a scene-matching pose solve's image-only
    yaw): y = heading - nominal yaw (wrapped), H on the attitude error through
    heading_sensitivity (a tilt error moves the yaw where the body's x axis is not level).
    With the camera's boresight states (ekf.i_cam) the solve was seeded with the mounting
    corrected by the estimate, so the heading it reads is off by what is left of the
    boresight, C (b - b_hat) in NED: H_b = h C, as the attitude rows of image_pose."""
    C = ekf.C_nb
    y = np.array([float(wrap_pi(heading_rad - dcm_to_euler(C)[2]))])
    H = np.zeros((1, ekf.n))
    h = heading_sensitivity(C)
    H[0, IA] = h
    if ekf.i_cam is not None:
        H[0, ekf.i_cam] = h @ C
    return y, H, np.array([[float(sigma_rad) ** 2]])


def optical_flow(ekf, flow_rate_c_rps, R_bc, range_m: float, cov_c_rps2, lever_arm_b_m=(0.0, 0.0, 0.0),
                 depth_sigma_fraction: float = 0.0, moments_c=None):
    """Optical flow: the ground's translational flow rate as the sensor's fit reads it (2,)
    rad/s, in the flow camera's frame (OpenCV: x right, y down; the camera's own rotation
    already taken out), over flat ground whose distance a pencil beam along body z ranges
    (range_m, m). R_bc (3, 3) camera -> body, l the lever arm (body FRD, m), omega the filter's
    bias-corrected body rate.

    The camera moves at t = R_cb (C^T v + omega x l) over the ground (camera frame); the ground
    plane's unit normal (down) there is n = R_cb C^T e_d, and its distance along it D = range
    (C e_z . e_d). A ground point at normalised (x, y) lies at depth Z = D / (n . (x, y, 1)) and
    moves in the image by ((-t_x + x t_z), (-t_y + y t_z)) / Z, a quadratic in (x, y). The fit
    reads a weighted mean of that field: at the image centre -(t_x, t_y) n_z / D, plus what
    moments_c ((2, 8), OpticalFlowSample) says it reads of the field's x, y, x^2, x y, y^2
    parts. Without moments_c the model is the centre's flow alone, -(t_x, t_y) / Z_centre (as
    PX4's EKF2 fuses a flow chip's output); with it, a 20 deg tilt's 2-4 % reading error
    (texture-dependent) is predicted rather than left as noise. Both are bilinear in (t, n):
    h = (t' B_k n) / D for k = x, y.

    H (C_true = (I + [phi x]) C_nb, v_true = v + dv, the range held as measured): d t / d v =
    R_cb C^T, d t / d phi = R_cb C^T [v x], d n / d phi = R_cb C^T [e_d x], d D / d phi = range
    (b x e_d)' with b = C e_z. With the flow's slow-error states b_f (ekf.i_flow, rad/s) the
    model is h + b_f, and H_bf = I. Noise: cov_c_rps2 (2, 2) plus the depth's relative error,
    which scales the whole of h (rank one: depth_sigma_fraction^2 h h')."""
    C = ekf.C_nb
    v = np.array(ekf.ins.vel, float)
    R_cb = np.asarray(R_bc, float).T
    omega = np.asarray(ekf.omega_ib_b_rps, float)
    RcCt = R_cb @ C.T
    t = R_cb @ (C.T @ v + np.cross(omega, np.asarray(lever_arm_b_m, float)))
    n = RcCt[:, 2]  # R_cb C^T e_d
    b_down = float(C[2, 2])
    D = float(range_m) * b_down
    B = flow_bilinear(moments_c)
    dF_dt = B @ n  # (2, 3)
    F = dF_dt @ t
    h = F / D
    y = np.asarray(flow_rate_c_rps, float) - h
    dF_dn = np.einsum("kij,i->kj", B, t)  # (2, 3)
    H = np.zeros((2, ekf.n))
    H[:, IV] = dF_dt @ RcCt / D
    b_x_ed = np.array([C[1, 2], -C[0, 2], 0.0])  # (C e_z) x e_d
    H[:, IA] = ((dF_dt @ RcCt @ skew(v) + dF_dn @ RcCt @ skew(np.array([0.0, 0.0, 1.0]))) / D
                - np.outer(F, range_m * b_x_ed) / D**2)
    if ekf.i_flow is not None:
        y = y - ekf.b_flow_rps
        H[:, ekf.i_flow] = np.eye(2)
    R = np.asarray(cov_c_rps2, float) + depth_sigma_fraction**2 * np.outer(h, h)
    return y, H, R


# c_j = t' Q_j n: the coefficient of the j-th field of FLOW_MOMENT_FIELDS in the flow of a
# camera translating at t over ground of normal n (times D): x-flow's x, y, x^2, x y parts,
# then y-flow's x, y, x y, y^2 (see optical_flow).
_FLOW_Q = np.zeros((8, 3, 3))
for _j, _entries in enumerate((((0, 0, -1.0), (2, 2, 1.0)), ((0, 1, -1.0),), ((2, 0, 1.0),), ((2, 1, 1.0),),
                               ((1, 0, -1.0),), ((1, 1, -1.0), (2, 2, 1.0)), ((2, 0, 1.0),), ((2, 1, 1.0),))):
    for _i, _l, _q in _entries:
        _FLOW_Q[_j, _i, _l] = _q
_FLOW_CENTRE = np.zeros((2, 3, 3))
_FLOW_CENTRE[0, 0, 2] = _FLOW_CENTRE[1, 1, 2] = -1.0  # -(t_x, t_y) n_z


def flow_bilinear(moments_c) -> np.ndarray:
    """B (2, 3, 3): the fit's reading of a translation's flow over flat ground, h_k D = t' B_k n
    (optical_flow); the image centre's flow alone without moments_c."""
    if moments_c is None:
        return _FLOW_CENTRE
    return _FLOW_CENTRE + np.einsum("kj,jil->kil", np.asarray(moments_c, float), _FLOW_Q)
