"""Frozen dataclasses passed between the pipeline stages (DESIGN.md: messages, not dicts).

Frames and units are in every field name: `_ned_m` local NED metres at the scenario origin,
`_b_` body FRD, `_rps` rad/s, `_mps` m/s, `_mps2` m/s^2, `q_nb_wxyz` body->nav quaternion
(Hamilton, scalar first). Arrays are float64 numpy arrays of the stated shape; treat them as
read-only (producers do not keep references they later mutate).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, slots=True)
class TruthState:
    """True state of one vehicle at time t_s, as the dynamics computed it.

    lat_rad, lon_rad, alt_m: WGS-84 geodetic position (alt above the ellipsoid, taken as MSL).
    pos_ned_m (3,): position in local NED at the scenario origin.
    vel_ned_mps (3,): velocity relative to the Earth, resolved in NED.
    q_nb_wxyz (4,), rpy_rad (3,): attitude body(FRD)->NED; roll, pitch, yaw (Z-Y-X).
    omega_eb_b_rps (3,): body rate relative to the Earth, body axes (what an autopilot damps).
    omega_ib_b_rps (3,): body rate relative to inertial space, body axes (what a gyro senses).
    f_b_mps2 (3,): specific force at the centre of gravity, body axes (what an accelerometer
        senses; about (0, 0, -g) in level unaccelerated flight).
    airspeed_mps: true airspeed; height_agl_m: height above the terrain below the vehicle.
    pressure_pa, temperature_k: static atmosphere at the vehicle (for the barometer).
    wind_ned_mps (3,): the air's velocity over the ground at the vehicle, NED (steady wind plus
        turbulence; zeros in calm air): vel_ned_mps minus it is the velocity through the air.
    """

    t_s: float
    lat_rad: float
    lon_rad: float
    alt_m: float
    pos_ned_m: np.ndarray
    vel_ned_mps: np.ndarray
    q_nb_wxyz: np.ndarray
    rpy_rad: np.ndarray
    omega_eb_b_rps: np.ndarray
    omega_ib_b_rps: np.ndarray
    f_b_mps2: np.ndarray
    airspeed_mps: float
    height_agl_m: float
    pressure_pa: float
    temperature_k: float
    wind_ned_mps: np.ndarray


@dataclass(frozen=True, slots=True)
class ImuSample:
    """One IMU output: angular rate and specific force in the IMU's body axes (FRD)."""

    t_s: float
    omega_ib_b_rps: np.ndarray
    f_ib_b_mps2: np.ndarray


@dataclass(frozen=True, slots=True)
class MagSample:
    """Magnetometer output: magnetic flux density in body axes (tesla), shape (3,)."""

    t_s: float
    field_b_T: np.ndarray


@dataclass(frozen=True, slots=True)
class BaroSample:
    """Barometer output: static pressure (Pa) and the standard-atmosphere altitude it implies (m)."""

    t_s: float
    pressure_pa: float
    altitude_m: float


@dataclass(frozen=True, slots=True)
class RadarAltSample:
    """Radar altimeter output: the range (m) to the nearest ground inside its beam, measured
    from the antenna (core.radar_beam); beam_half_angle_rad tells the user which beam that was."""

    t_s: float
    range_m: float
    beam_half_angle_rad: float


@dataclass(frozen=True, slots=True)
class OpticalFlowSample:
    """Optical-flow sensor output: how far the ground moved in its image over the last interval.

    t_s: the later frame's time; dt_s: the interval between the two frames (s); flow_c_rad (2,):
    the ground's move in the later frame relative to the earlier, in normalised image
    coordinates (camera frame, OpenCV: x right, y down; the shift in pixels over fx and fy),
    so rad for a small angle: translation and the camera's own rotation together, as a flow
    chip measures it; cov_c_rad2 (2, 2): its covariance as the chip's fit claims it (white
    residuals: see sensors.image_shift); texture_dn2: the image's squared gradient along its
    weakest direction (DN^2 / px^2), low over bare fields and along rows; residual_dn: the
    fit's residual SD (DN); R_bc (3, 3): the sensor's mounting, camera -> body; lever_arm_b_m
    (3,): where it sits on the body (FRD, m); rotation_c (2, 3): the flow the fit reads per rad
    of the camera's rotation about its x, y and z axes (at the image centre alone it would be
    [[0, -1, 0], [1, 0, 0]]; off-centre pixels move more, and the texture weighs them: about
    5 % more over 45 deg); moments_c (2, 8) or None: what the fit reads (2,) of each of the
    flow fields (x, 0), (y, 0), (x^2, 0), (x y, 0), (0, x), (0, y), (0, x y), (0, y^2), x and y
    the normalised image coordinates (FLOW_MOMENT_FIELDS): a tilted camera's ground lies nearer
    on one side, so its translation's flow is such a polynomial, and the texture weighs its parts.
    The mounting is the installation's: the vehicle knows it."""

    t_s: float
    dt_s: float
    flow_c_rad: np.ndarray
    cov_c_rad2: np.ndarray
    texture_dn2: float
    residual_dn: float
    R_bc: np.ndarray
    lever_arm_b_m: np.ndarray
    rotation_c: np.ndarray
    moments_c: np.ndarray | None = None


# The flow fields whose reading OpticalFlowSample.moments_c gives, in its column order: which
# component of the flow (0: x, 1: y) and the monomial of the normalised image coordinates.
FLOW_MOMENT_FIELDS = ((0, "x"), (0, "y"), (0, "xx"), (0, "xy"), (1, "x"), (1, "y"), (1, "xy"), (1, "yy"))


@dataclass(frozen=True, slots=True)
class GnssFix:
    """GNSS receiver output, valid at t_s (the time of validity, before latency).

    pos_sigma_m / vel_sigma_mps: the receiver's own 1-sigma accuracy claim per axis (N, E, D).
    A spoofed receiver reports its usual sigmas: it does not know it is lied to.
    """

    t_s: float
    lat_rad: float
    lon_rad: float
    alt_m: float
    vel_ned_mps: np.ndarray
    pos_sigma_m: np.ndarray
    vel_sigma_mps: np.ndarray


@dataclass(frozen=True, slots=True)
class UwbRange:
    """One UWB two-way range from this vehicle's node to node `peer_id` (metres).

    rss_dbm: received signal strength. The measurement carries no truth about NLOS.
    """

    t_s: float
    peer_id: str
    range_m: float
    rss_dbm: float


@dataclass(frozen=True, slots=True)
class AirspeedSample:
    """Pitot-static true airspeed (m/s)."""

    t_s: float
    airspeed_mps: float


@dataclass(frozen=True, slots=True)
class StateObservation:
    """An ideal full-state observation (the `ideal_state` sensor), used by the truth
    pass-through navigator for control studies without navigation error."""

    t_s: float
    truth: TruthState


@dataclass(frozen=True, slots=True)
class PositionFix:
    """An absolute position fix (e.g. from scene matching) in local NED with its covariance.

    cov_ned_m2 (3, 3): the fix's error covariance; quality: matcher's own figure in [0, 1];
    source names the producer.

    A producer that leaned on the navigator's own attitude (a pose solve with the INS attitude
    as prior) says how: att_sensitivity_m_per_rad (3, 3), M, with the fix's error
    = -M phi + n, phi the navigator's attitude error (NED small angles, truth = Exp(phi) estimate),
    and cov_given_att_ned_m2 (3, 3), the covariance of n. A navigator that models the coupling
    fuses the fix with H_phi = -M and noise cov(n); one that does not uses cov_ned_m2. None: the
    fix is independent of the navigator's attitude.

    heading_rad, heading_sigma_rad: the body's heading (Z-Y-X yaw, rad, from north) that the
    image alone gives, independent of the navigator's attitude, and its 1-sigma; None when the
    producer does not offer one.

    image_pos_ned_m (3,), image_R_nb (3, 3), image_pose_cov (6, 6): the pose the image alone gives,
    independent of the navigator (a scene matcher's pose solve without its INS prior): the body
    position (NED m at the origin) and attitude (body -> NED) through the camera's calibrated
    mounting, and their joint covariance [position NED m, attitude NED small angles rad]. A
    navigator that carries the camera's boresight error as states fuses this pose instead of
    pos_ned_m (the image's attitude against the INS attitude is what shows the boresight);
    None when the producer does not offer it.

    vel_lag_s, tau (s) or a (3, 3) matrix L (s, NED): the producer found the position tau s
    before t_s and carried it to t_s on the navigator's own estimated velocity (terrain-aided
    navigation: a window's offset from a dead-reckoned track), so its error holds
    tau (v_est - v_true), or L (v_est - v_true) where the lag differs by axis; a navigator fuses
    it with H_v = -tau (-L). None: no such term.

    intrinsics_sensitivity (3, 3): how the fix moves (NED m) with an error of the camera's
    intrinsics left in the producer's solve, per column: its principal point's u and v (m per
    px: the true one minus the one solved with) and its focal length's relative error (m per
    unit: true = solved (1 + e)), for a navigator that carries those errors as states; None
    when the producer does not say.
    """

    t_s: float
    pos_ned_m: np.ndarray
    cov_ned_m2: np.ndarray
    quality: float
    source: str = "ismn"
    att_sensitivity_m_per_rad: np.ndarray | None = None
    cov_given_att_ned_m2: np.ndarray | None = None
    heading_rad: float | None = None
    heading_sigma_rad: float | None = None
    vel_lag_s: float | np.ndarray | None = None
    image_pos_ned_m: np.ndarray | None = None
    image_R_nb: np.ndarray | None = None
    image_pose_cov: np.ndarray | None = None
    intrinsics_sensitivity: np.ndarray | None = None


@dataclass(frozen=True, slots=True)
class CorrectionInfo:
    """What a navigator did with one measurement.

    innovation (m,), innovation_cov (m, m), nis = y^T S^-1 y, accepted after gating.
    """

    t_s: float
    kind: str
    innovation: np.ndarray
    innovation_cov: np.ndarray
    nis: float
    accepted: bool


@dataclass(frozen=True, slots=True)
class NavEstimate:
    """A navigator's estimate of its own vehicle's state (the only state controllers see).

    pos_ned_m, vel_ned_mps (3,); q_nb_wxyz (4,); rpy_rad (3,);
    omega_b_rps (3,): bias-corrected body rate relative to the Earth (for rate damping);
    cov_pos_ned_m2, cov_vel_ned_m2s2, cov_att_rad2 (3, 3): marginal covariances;
    airspeed_mps: estimated true airspeed when the vehicle measures it, else None;
    wind_ne_mps (2,), cov_wind_ne_m2s2 (2, 2): the estimated horizontal wind (the air's
        velocity over the ground, north and east) and its covariance, when the navigator
        estimates the wind, else None.
    camera_boresight_b_rad (3,), cov_camera_boresight_rad2 (3, 3): the estimated boresight
        error of the scene-matching camera (body axes, rad: its true mounting is Exp(b) R_bc)
        and its covariance, when the navigator estimates it, else None. A scene matcher seeds
        its solve with the mounting corrected by it.
    camera_time_offset_s, var_camera_time_offset_s2: the estimated time offset of the
        scene-matching camera (its frames' stamp minus their exposure, s) and its variance, when
        the navigator estimates it, else None. A scene matcher takes the pose that long before a
        frame's stamp as its prior.
    camera_intrinsics_error (3,), cov_camera_intrinsics_error (3, 3): the estimated error of
        the scene-matching camera's intrinsics, [principal point u, v (px: the true one minus
        the calibrated one), focal length (relative: true = calibrated (1 + e))], and its
        covariance, when the navigator estimates it, else None. A scene matcher solves with the
        intrinsics corrected by it.
    map_error_ne_m (2,), cov_map_error_ne_m2 (2, 2): the estimated georeference error of the
        reference map under the scene matcher's footprint (north, east, m: where the map shows
        the ground minus where it is) and its covariance, when the navigator estimates it, else
        None.
    """

    t_s: float
    pos_ned_m: np.ndarray
    vel_ned_mps: np.ndarray
    q_nb_wxyz: np.ndarray
    rpy_rad: np.ndarray
    omega_b_rps: np.ndarray
    cov_pos_ned_m2: np.ndarray
    cov_vel_ned_m2s2: np.ndarray
    cov_att_rad2: np.ndarray
    airspeed_mps: float | None = None
    wind_ne_mps: np.ndarray | None = None
    cov_wind_ne_m2s2: np.ndarray | None = None
    camera_boresight_b_rad: np.ndarray | None = None
    cov_camera_boresight_rad2: np.ndarray | None = None
    camera_time_offset_s: float | None = None
    var_camera_time_offset_s2: float | None = None
    camera_intrinsics_error: np.ndarray | None = None
    cov_camera_intrinsics_error: np.ndarray | None = None
    map_error_ne_m: np.ndarray | None = None
    cov_map_error_ne_m2: np.ndarray | None = None


@dataclass(frozen=True, slots=True)
class SurfaceCommand:
    """Fixed-wing actuator command: normalised surfaces in [-1, 1], throttle in [0, 1].

    Sign conventions are JSBSim's: positive elevator is trailing edge down (nose down),
    positive aileron rolls right, positive rudder yaws left (check a bundled model's own
    FCS before relying on these for it).
    """

    aileron: float = 0.0
    elevator: float = 0.0
    rudder: float = 0.0
    throttle: float = 0.0


@dataclass(frozen=True, slots=True)
class RotorCommand:
    """Multirotor command: normalised motor commands in [0, 1], one per rotor (model order)."""

    motors: tuple[float, ...] = ()


@dataclass(frozen=True, slots=True)
class GuidanceStatus:
    """What guidance commands at one control tick, so that scoring can compare it with truth.

    leg_index: active leg or waypoint index; on_leg: True on a straight leg (not turning).
    alt_cmd_m: commanded altitude above the scenario origin (up positive, = -down_ned).
    airspeed_cmd_mps: commanded true airspeed (nan for a multirotor).
    line_start_ne_m, line_end_ne_m (2,): the straight path being followed (north, east), nan
        while turning; target_ned_m (3,): the active waypoint or goal point (nan if none).
    bank_cmd_rad: commanded bank angle; cross_track_est_m: cross-track error the controller
        sees on its estimate (right of track positive).
    """

    t_s: float
    leg_index: int = -1
    on_leg: bool = False
    alt_cmd_m: float = float("nan")
    airspeed_cmd_mps: float = float("nan")
    line_start_ne_m: tuple[float, float] = (float("nan"), float("nan"))
    line_end_ne_m: tuple[float, float] = (float("nan"), float("nan"))
    target_ned_m: tuple[float, float, float] = (float("nan"), float("nan"), float("nan"))
    bank_cmd_rad: float = float("nan")
    cross_track_est_m: float = float("nan")
