"""The INS/EKF navigator's configuration blocks (`navigation.params` of an ins_ekf vehicle):
initial uncertainty, IMU noise overrides, measurement noise overrides, rotor-drag and
airspeed aiding, and the navigator's own settings (InsEkfParams); those of the states of the
scene-matching fixes' error sources are in fix_error_settings, the optical flow's in flow_settings.
Each field's docstring says what it is, in which unit, and why its default is what it is."""

from __future__ import annotations

from typing import Literal

import pydantic

from testbench.core.registry import ParamsModel
from testbench.navigation.ins.fix_error_settings import (
    CameraBoresight,
    CameraIntrinsicsParams,
    CameraTimeOffsetParams,
    MapErrorParams,
)
from testbench.navigation.ins.flow_settings import OpticalFlowAiding
from testbench.navigation.ins.gnss_monitor import GnssMonitorParams


class InitialSigmas(ParamsModel):
    """1-sigma initial uncertainty per axis (used where the initial estimate carries none)."""

    pos_m: float = pydantic.Field(3.0, gt=0)
    vel_mps: float = pydantic.Field(0.2, gt=0)
    tilt_deg: float | None = pydantic.Field(None, gt=0)
    """None: the levelling accuracy of a static alignment with the IMU preset, its accelerometer
    turn-on bias over g (1e-4 rad per 0.1 mg), at least 0.05 deg (mounting and alignment
    residuals). The estimate starts at the aligned state; a sigma far above what the alignment
    leaves (0.5 deg for the paper IMU's 0.006 deg) made the scene matcher's attitude prior
    weak for the first half minute, and its fixes then erred by 2-3 m while claiming 1.2 m."""
    heading_deg: float = pydantic.Field(2.0, gt=0)
    gyro_bias_deg_h: float | None = pydantic.Field(None, gt=0)
    """None: the IMU preset's turn-on bias."""
    accel_bias_ug: float | None = pydantic.Field(None, gt=0)
    """None: the IMU preset's turn-on bias."""
    baro_bias_m: float = pydantic.Field(5.0, gt=0)
    """The barometer's turn-on bias as a height: the default sensor's 50 Pa at ~10.5 Pa/m
    (1.3 km) is 4.8 m. With 3 m the first barometer updates pulled the height by more than
    the filter allowed for, and the 20-run average NEES sat above its band for 30 s."""


class ImuNoiseParams(ParamsModel):
    """IMU noise in datasheet units (overrides the preset entry by entry)."""

    gyro_arw_deg_sqrt_h: float | None = pydantic.Field(None, gt=0)
    gyro_bias_instability_deg_h: float | None = pydantic.Field(None, gt=0)
    accel_vrw_mps_sqrt_h: float | None = pydantic.Field(None, gt=0)
    accel_bias_instability_ug: float | None = pydantic.Field(None, gt=0)
    gyro_rrw_deg_h_sqrt_h: float | None = pydantic.Field(None, ge=0)
    accel_rrw_ug_sqrt_h: float | None = pydantic.Field(None, ge=0)
    gyro_bias_tau_s: float = pydantic.Field(300.0, gt=0)
    accel_bias_tau_s: float = pydantic.Field(300.0, gt=0)
    flicker_fit_band_s: tuple[pydantic.PositiveFloat, pydantic.PositiveFloat] | None = None
    """Coasting times (s, shortest and longest) over which the filter's white noise and bias
    random walk are refitted to drift as the sensor's flicker bias does (imu_noise.
    fit_to_flicker): for a filter that goes tens of seconds between aids, such as terrain-aided
    navigation's one fix per 20 s window. None: the datasheet's figures as they are, one
    Gauss-Markov bias of sigma B and the tau above, which over 10-60 s expects half the drift
    (a quarter of the variance) a flicker floor of B gives. Needs imu_bias_model random_walk."""

    @pydantic.model_validator(mode="after")
    def _band_ordered(self) -> "ImuNoiseParams":
        if self.flicker_fit_band_s is not None and not self.flicker_fit_band_s[0] < self.flicker_fit_band_s[1]:
            raise ValueError(f"flicker_fit_band_s {list(self.flicker_fit_band_s)}: expected [shortest, longest] "
                             "coasting time in s, shortest first")
        return self


class DragAiding(ParamsModel):
    """Rotor-drag velocity aiding of a multirotor (the momentum-drag fusion of PX4's EKF2,
    EKF2_DRAG_CTRL with EKF2_MCOEF). The rotors' in-plane drag makes the accelerometers' body
    x and y specific force -mu times the body velocity, so in calm air the accelerometers
    measure velocity, and the INS cannot drift in velocity (and, through it, in course) once
    GNSS is gone. Fused every interval_s with the specific force and the nominal body velocity
    averaged over the interval. Not for fixed wings (no such drag law, see AirspeedAiding), nor
    on the ground.

    The drag measures the velocity through the air. Without wind states (the default) the
    filter takes it for the velocity over the ground, which holds only in calm air: in a wind
    the estimate drifts with the air. With wind_states the filter carries the horizontal wind
    as two states (as AirspeedAiding does), learnt while GNSS or position fixes tie the
    velocity over the ground, and held, as a random walk, after; what the wind does then
    (turbulence, a change of wind) is beyond any drag model's reach."""

    coefficient_per_s: float | None = pydantic.Field(None, gt=0)
    """mu (1/s); None: from the aircraft's sidecar at hover (core.rotor_drag.momentum_drag_per_s)."""
    interval_s: float = pydantic.Field(0.2, gt=0, le=1.0)
    sigma_mps2: float = pydantic.Field(0.05, gt=0)
    """Error of the averaged specific force against the model, per axis: mu changes with the
    rotor speeds (+-5 % for +-10 % thrust), i.e. ~0.07 m/s^2 at 4 m/s in a manoeuvre, far less
    in steady flight; the accelerometers' white noise over 0.2 s is a few mm/s^2. In gentle
    formation flight (paper_swarm_relnav: 0.25 m/s^2, 0.5 deg/s turns) the innovations are
    0.008-0.011 / 0.004-0.006 m/s^2 RMS in body x / y, and that scenario sets 0.03 (0.02 and
    0.01 left the position overconfident: the error is not white at 5 Hz)."""
    thrust_scaled: bool = False
    """Scale mu by the rotor speed the thrust implies, sqrt(T / (m g)) with T / m the
    accelerometers' -f_bz averaged over the interval (each rotor drags c omega_i v and
    omega_i = sqrt(T_i / k_T); the sidecar's mu is at hover). tb_quad in level flight at 4 / 8 m/s
    holds 0.988 / 0.962 of its weight on thrust (the tilted drag lifts the rest), so its rotors
    drag 0.6 / 1.9 % less per m/s than the hover mu (0.9 % in a hover tilted into a 5 m/s wind).
    False: mu at hover, its scale error left to the scale state below."""
    scale_sigma: float = pydantic.Field(0.006, ge=0)
    """Steady-state sigma of the slow part of mu's error, a scale (1 + s) the filter estimates
    (error_model, dsd): the part of the model error that lasts for tens of seconds, which fused
    as white noise at 5 Hz would be averaged away. paper_swarm_relnav (oracle detector, 300 s,
    GNSS denied from 30 s) without it: the followers' drag-aided velocity erred by -0.4 to
    -6 cm/s along track (-0.1 to -1.2 %) in spells of a minute, and their positions by 2-11 m
    against 2.3 m claimed (horizontal position NEES mean 7.6 for 2 dof; two navigators flagged
    lost); with 0.006: NEES 1.5, position error mean 2.9 -> 1.8 m, max 10.6 -> 6.9 m, none
    lost (0.01: NEES 1.4, 1.95 m, 8.2 m). 0: mu taken as exact."""
    scale_tau_s: float = pydantic.Field(60.0, gt=0)
    """Correlation time of that scale error (s)."""
    wind_states: bool = False
    """Carry the horizontal wind as two filter states: the drag is fused against the velocity
    through the air, v - w (False: calm air assumed, w = 0)."""
    wind_sigma_mps: float = pydantic.Field(3.0, gt=0)
    """Initial uncertainty of the wind, per horizontal axis (m/s), with wind_states."""
    wind_reset_after_s: float | None = pydantic.Field(5.0, gt=0)
    """With wind_states: after this long with every drag sample refused by the gate, the
    wind's covariance grows by the disagreement and the sample is fused (ErrorStateEKF.reset_wind;
    None: never). Without it a gust that outruns the wind's sigma locks the drag out for good
    (multirotor_wind_drag, seed 1: 22 % of the samples taken at 270-300 s, NIS median 37, the
    wind estimate held 5 m/s off)."""
    wind_rw_mps_sqrt_s: float = pydantic.Field(0.05, ge=0)
    """Random walk of the wind (m/s/sqrt(s)), with wind_states. A Dryden gust field of sigma s
    and correlation time tau (its scale length over the airspeed: 263 m at 100 m height, tens
    of seconds for a multirotor) walks about s sqrt(2 / tau) per sqrt(s): 0.2 for light
    turbulence (1 m/s, 40 s)."""


class AirspeedAiding(ParamsModel):
    """Airspeed velocity aiding of a fixed wing (the true-airspeed and synthetic-sideslip
    fusion of PX4's EKF2, EKF2_ARSP_THR and EKF2_FUSE_BETA, with its two wind states). The pitot
    gives the speed through the air, and a wing in coordinated flight flies with no sideslip,
    so the velocity through the air, v - w, is measured in speed and in direction about the
    nose; the filter estimates the horizontal wind w while GNSS is there and holds it after.
    Without it a fixed wing's INS is free-inertial once GNSS is gone: swarm_fixedwing's leader
    drifted to 22 m in 130 s, and in its turns, where the filter can tell tilt from position
    through the vertical channel, each barometer sample moved the horizontal estimate by up to
    5 m (the gain of a 35 m horizontal sigma correlated with a 2 cm one).
    Fused as one two-dimensional measurement every interval_s (speed and body-y velocity
    through the air), above min_airspeed_mps."""

    sigma_mps: float = pydantic.Field(0.3, gt=0)
    """Error of the true airspeed against |v - w|: the pitot's noise and bias (2 Pa and 1 Pa on
    290 Pa of dynamic pressure at 22 m/s: 0.08 and 0.04 m/s) and its angle-of-attack and
    installation error (a few per mille)."""
    sideslip_sigma_deg: float | None = pydantic.Field(0.5, gt=0)
    """Sideslip the zero-sideslip measurement allows (deg; None: the airspeed alone is fused).
    tb_fixedwing in swarm_fixedwing: 0.01 deg RMS on straight legs, 0.29 deg RMS (0.93 deg at
    most) in its 5 deg-bank turns."""
    wind_sigma_mps: float = pydantic.Field(3.0, gt=0)
    """Initial uncertainty of the wind, per horizontal axis (m/s)."""
    wind_rw_mps_sqrt_s: float = pydantic.Field(0.05, ge=0)
    """Random walk of the wind (m/s/sqrt(s)): 0.5 m/s over 100 s as the vehicle flies through
    it, for a steady wind. In turbulence the gusts walk faster, about sigma sqrt(2 / tau) with
    tau the scale length over the airspeed: light turbulence at 800 m (2.2 m/s, 533 m, 21 s at
    25 m/s) ~0.7 (docs/measurements.md, "Wind")."""
    wind_reset_after_s: float | None = pydantic.Field(5.0, gt=0)
    """After this long with every airspeed sample refused by the gate, the wind's covariance
    grows by the disagreement and the sample is fused (ErrorStateEKF.reset_wind; None: never)."""
    interval_s: float = pydantic.Field(0.2, gt=0, le=1.0)
    """Fuse at most this often (the pitot samples faster; its noise is white)."""
    min_airspeed_mps: float = pydantic.Field(8.0, ge=0)
    """Below this (on the ground, in the take-off run) nothing is fused."""


class MagBias(ParamsModel):
    """The magnetic heading's bias as a filter state (ErrorStateEKF.i_mag): the field the
    magnetometer senses differs from the onboard WMM by the crust's anomaly (world.
    magnetic_anomaly), which turns the magnetic heading by about the horizontal anomaly across
    the horizontal field (100 nT against 17 000 nT: 6 mrad, 0.34 deg), alike for every sample
    over a region. The WMM's own declination uncertainty, mostly that, is 0.3-0.5 deg (1
    sigma). While another source fixes the heading (GNSS velocity in manoeuvres, the scene
    matcher's image heading) the filter learns the bias; after, it keeps it as long as the
    anomaly lasts along the flight.

    sigma_deg: steady-state sigma of the bias; correlation_m: the ground distance over which
    it decorrelates (a Gauss-Markov process in distance: the anomaly's correlation length,
    about twice its sources' depth)."""

    sigma_deg: float = pydantic.Field(0.3, gt=0.0, le=20.0)
    correlation_m: float = pydantic.Field(2000.0, gt=0.0)


class MeasurementSigmas(ParamsModel):
    """Measurement noise overrides; None uses the message's own figure or the default."""

    # Barometer: matched to the default sensor, a little wider (1 Pa RMS = 0.09 m at 1 km,
    # dp/dh ~ 11 Pa/m; a 20-run batch gives NIS 0.63).
    baro_m: float = pydantic.Field(0.12, gt=0)
    # Magnetic heading: 3x the white part (100 nT over the ~17 uT horizontal field = 0.34 deg).
    # The heading is computed with the estimated tilt, and at a ~70 deg inclination a tilt error
    # enters it x2.7: measurements.mag_heading carries that in H's tilt columns (before, only
    # this sigma stood for it, and the filter claimed half its heading error); the margin stays
    # for what no state carries (field model, soft iron).
    mag_heading_deg: float = pydantic.Field(1.0, gt=0)
    mag_T: float = pydantic.Field(1.0e-6, gt=0)
    gnss_pos_m: float | None = pydantic.Field(None, gt=0)
    gnss_vel_mps: float | None = pydantic.Field(None, gt=0)
    position_fix_scale: float = pydantic.Field(1.0, gt=0)


class InsEkfParams(ParamsModel):
    """`navigation.params` of an ins_ekf vehicle (InsEkfNavigator.Params)."""

    imu_preset: str = "paper"
    imu: ImuNoiseParams = ImuNoiseParams()
    imu_bias_model: Literal["random_walk", "gauss_markov"] = "random_walk"
    """How the filter carries the IMU biases (see ErrorStateEKF): random_walk holds the
    turn-on bias it has estimated; gauss_markov lets estimates decay towards zero."""

    @pydantic.model_validator(mode="after")
    def _flicker_fit_needs_random_walk(self) -> "InsEkfParams":
        if self.imu.flicker_fit_band_s is not None and self.imu_bias_model != "random_walk":
            raise ValueError("imu.flicker_fit_band_s fits the bias random walk of imu_bias_model "
                             f"random_walk; got imu_bias_model {self.imu_bias_model!r}")
        return self
    initial_sigma: InitialSigmas = InitialSigmas()
    initial_error: Literal["none", "sampled"] = "none"
    """The error the pre-flight alignment leaves in the starting position, velocity and
    attitude. none: the estimate starts at the true state (the alignment is modelled as
    exact) while the filter claims initial_sigma; sampled: the starting state is displaced
    by a draw from the filter's own P0 (position, velocity, tilt and heading blocks), from
    the vehicle's "navigation/alignment" random stream, so that x0 ~ N(x0_hat, P0) as a
    Monte Carlo consistency (NEES) test assumes. With none, the first seconds of every run
    are underconfident by construction (error 0 against a 3 m claim)."""
    meas_sigma: MeasurementSigmas = MeasurementSigmas()
    gate_probability: float = pydantic.Field(0.999, gt=0.5, le=1.0)
    cov_interval_s: float = pydantic.Field(0.05, ge=0.0, le=1.0)
    baro_bias_rw_m_sqrt_s: float = pydantic.Field(0.008, ge=0.0)
    """Random walk of the barometer's bias (m/sqrt(s)): the barometer sensor's default drift,
    5 Pa/sqrt(h) = 0.083 Pa/sqrt(s), over dp/dh = 10.4 Pa/m at 1.3 km (12 Pa/m at sea level:
    0.007). 0.01 left the height 1.6-2x conservative once GNSS was gone (20-run batch)."""
    use_gnss: bool = True
    use_gnss_velocity: bool = True
    gnss_min_interval_s: float = pydantic.Field(1.0, ge=0.0)
    """GNSS fixes closer than this to the last one used are skipped (cost: the receiver's
    correlated error is modelled, so the skipped fixes carry little information)."""
    gnss_monitor: GnssMonitorParams | None = None
    """Spoofing monitor (gnss_monitor.py; None: off): each fix's velocity change over a window
    against the INS's own; once it alarms, GNSS fixes are tested but not fused (kind
    "gnss:excluded"), and the navigator never resets to them, until the monitor and the gate
    have both passed for release_s. For a vehicle with no other absolute aid, which a spoofer
    otherwise carries away (the gate follows a slow drag, and gnss_reset_after_s resets to it)."""
    gnss_error_sigma_m: float = pydantic.Field(1.0, ge=0.0)
    gnss_error_tau_s: float = pydantic.Field(60.0, gt=0.0)
    """The receiver's position error that is correlated over tens of seconds (ionosphere,
    orbit/clock, multipath): steady-state sigma per axis and correlation time of the three
    Gauss-Markov EKF states that carry it. The defaults are the gnss sensor's defaults
    (pos_corr_sigma_m, pos_corr_s). A fix's claimed sigma is split into this part and a
    white remainder; without these states, fusing fix after fix would average the
    correlated error away and leave the covariance several times too small."""
    fix_error_sigma_m: float = pydantic.Field(0.3, ge=0.0)
    fix_error_tau_s: float = pydantic.Field(60.0, gt=0.0)
    """The same for position fixes (scene matching): the part of a fix's error that
    successive fixes share, because overlapping frames meet the same disagreement between
    the scene and the map (season, map georeference, relief). It is taken out of each
    fix's claimed covariance and carried by three Gauss-Markov states. Default: the ISMN
    pipeline's default sigma_floor_m (0.3 m, the error its fixes cannot average) over 60 s
    (about the time to fly one 800 m-altitude footprint); a scenario that raises the
    matcher's floor (another year of real imagery) raises this with it."""
    fix_error_turn_deg: float | None = pydantic.Field(None, gt=0.0)
    """Heading change (deg) over which the fixes' shared error also decorrelates (None: time
    alone): a turn rotates the camera's view over the ground, so the tiles meet other ground
    in another geometry (ErrorStateEKF fix_error_turn_rad)."""
    fix_error_sigma_down_m: float | None = pydantic.Field(None, ge=0.0)
    """The shared error of the fixes' down axis, when it differs from the horizontal one
    (None: fix_error_sigma_m). A fix's height comes from the pose solve's scale against the
    reference elevation, so what fixes share vertically is that elevation model's error,
    not the map's misregistration: over an exact reference elevation (a procedural world's
    own heights) it is a few centimetres, over a real DEM its vertical accuracy."""
    fix_appearance_sigma_m: float = pydantic.Field(0.0, ge=0.0)
    """A second shared error of the position fixes, the appearance error (m, steady-state sigma
    per axis; 0: none): what the map's date and the image's disagree on over a region (shadows
    that moved, fields ploughed) moves every tile alike, so the pose solve's scatter cannot see
    it, and it lasts as long as the region stays in view. A fix shows it the more, the fewer of
    its tiles agree: with quality q, a fix holds g(q) b_app, g = min(max_gain, ((1 - q) / (1 -
    ref_quality)) ** exponent), b_app three Gauss-Markov states with fix_error_tau_s and
    fix_error_turn_deg. Unlike a white claim that grows as q falls, the filter then expects a
    run of poor fixes to err together (a world under another sun: 1.4 m low for 40 s at q 0.6),
    and unlike scaling b_fix, a poor fix does not make the good ones after it carry its error."""
    fix_appearance_ref_quality: float = pydantic.Field(0.6, ge=0.0, lt=1.0)
    """Quality (the fix's own figure, in [0, 1]) at which g = 1."""
    fix_appearance_exponent: float = pydantic.Field(3.0, gt=0.0)
    """How steeply g grows as the quality falls."""
    fix_appearance_max_gain: float = pydantic.Field(3.0, gt=0.0)
    """Cap on g: a fix of very low quality is mostly gated out, and one that passes must not
    pin the appearance states with a gain of 10."""
    mag_bias: MagBias | None = None
    camera_boresight: CameraBoresight | None = None
    """The scene-matching camera's boresight error as filter states (see CameraBoresight);
    None: the camera's calibrated mounting is taken as exact. Needs fixes that carry the
    image-only pose (the ismn aid's pipeline.pose_from_image); fixes without it are fused
    as before, their attitude coupling extended by the boresight."""
    """The magnetic heading's bias as a filter state (see MagBias); None: none, every
    magnetometer sample's error taken as white."""
    fix_reset_after_s: float = pydantic.Field(5.0, ge=0.0)
    """Position fixes that keep arriving and keep failing the gate for this long (s) mean
    the filter, not the fixes, has lost the position (a streak of biased fixes it accepted
    left it confident and wrong): the next fix resets the position to it, as PX4's EKF2
    resets to GNSS after a fusion timeout (EKF.reset_position). 0 disables the reset. A
    matcher that is consistently wrong for this long is followed: the price of never
    diverging for good on an overconfident covariance. No reset while GNSS fixes are being
    accepted (then the fixes are what is wrong)."""
    fix_reset_min_refusals: int = pydantic.Field(1, ge=1)
    """...and at least this many position fixes in a row must have failed the gate, the one
    the filter would reset to included. 1: the time alone decides (a fix after a gap in the
    fixes resets at once). A source whose fixes come seldom and sometimes not at all, such as
    terrain-aided navigation's one per window, needs more: after a few windows without a fix,
    a single false one would otherwise become the filter's position."""
    gnss_reset_after_s: float = pydantic.Field(5.0, ge=0.0)
    """GNSS fixes that keep arriving and keep failing the gate for this long (s): the filter
    has diverged (a consumer IMU's unmodelled errors in a hard manoeuvre, a long outage);
    the next fix resets position and velocity to it and widens the tilt (see
    ErrorStateEKF.reset_position), as PX4's EKF2 does after a GNSS fusion timeout. 0
    disables the reset. No reset while position fixes (scene matching) are being accepted:
    then the filter agrees with them and GNSS is what is wrong (spoofed)."""
    gyro_scale_error: float | None = pydantic.Field(None, ge=0.0)
    """1-sigma gyro scale-factor and cross-axis error (rad of attitude error per rad turned);
    None: the IMU preset's sqrt(scale_factor^2 + misalignment^2) (consumer_mems: 0.0135,
    1.2 deg after a 90 deg corner; paper: 1.4e-4). The filter has no states for it: it
    widens the attitude covariance per angle turned (ErrorStateEKF), so that after a corner
    the filter expects the tilt error the corner left. 0: off."""
    scale_error_angle_deg: float = pydantic.Field(90.0, gt=0.0)
    """The turn over which the scale-factor error is modelled as one constant (a corner)."""
    baro_reset_after_s: float = pydantic.Field(5.0, ge=0.0)
    """Barometer samples that keep failing the gate for this long (s): the filter's height
    has diverged (a barometer does not jump); the next sample resets the height to it
    (ErrorStateEKF.reset_height), as PX4's EKF2 resets its height after a height fusion
    timeout. Without it a filter that lost its attitude rejected the baro for good and flew
    the vehicle into the ground (lowalt_ismn_150m, t = 150-212 s). 0 disables the reset."""
    use_baro: bool = True
    use_mag: bool = True
    mag_mode: Literal["heading", "vector"] = "heading"
    use_position_fix: bool = True
    camera_time_offset: CameraTimeOffsetParams | None = None
    """The scene-matching camera's time offset as a filter state (None: the frames' stamps are
    taken as their exposure times). The ismn aid then asks the pipeline for the fix of the pose
    at stamp - offset (its estimate), and the navigator fuses the fix as a position of that time.
    Needs exactly one ismn aid and no camera_boresight states."""
    camera_intrinsics: CameraIntrinsicsParams | None = None
    """The scene-matching camera's intrinsics error (principal point, focal length) as three
    filter states (None: the calibrated intrinsics are taken as exact). The ismn pipeline then
    solves each frame with the intrinsics corrected by the estimate, and the navigator fuses
    each fix with its sensitivity to the error left. Needs exactly one ismn aid and no
    camera_boresight states."""
    map_error: MapErrorParams | None = None
    """The map's georeference error as filter states (None: the map placed exactly; needs an ismn aid)."""
    delayed_fixes: Literal["replay", "carry", "as_current"] = "replay"
    """How a position fix that reaches the filter after its time is fused (an aid's onboard
    processing time, IsmnAid latency_s; delayed.py): replay (exact: back to the state at the
    fix's time, fuse, replay the IMU and the other measurements since), carry (first order: the
    fix's innovation at its time fused now, with the lag term of the velocity error), or
    as_current (unchanged, as a measurement of now: the naive filter, for contrast)."""
    fix_attitude_coupling: bool = True
    """Fuse a position fix that leaned on this filter's attitude (PositionFix.
    att_sensitivity_m_per_rad: the scene matcher's pose solve takes the INS attitude as its
    prior) with that coupling, H_phi = -M, and its covariance given the attitude. Off, such a
    fix is fused as an independent measurement of position, which counts the filter's own
    attitude information twice (paper_ismn_800m: M is 50-100 m/rad in tilt, i.e. 0.05-0.1 m
    of fix error per mrad of the filter's tilt error)."""
    use_fix_heading: bool = True
    """Fuse the heading a position fix carries (PositionFix.heading_rad: the image-only heading of
    the scene matcher's pose solve, ismn `heading_from_image`) as a measurement of the filter's
    yaw, gated like any other."""
    drag_aiding: DragAiding | None = None
    """Rotor-drag velocity aiding (multirotors in calm air; see DragAiding); None: off."""
    airspeed_aiding: AirspeedAiding | None = None
    """True airspeed and zero-sideslip velocity aiding with wind states (fixed wings with an
    airspeed sensor; see AirspeedAiding); None: off (the airspeed is only passed on to the
    controller)."""
    optical_flow: OpticalFlowAiding | None = None
    """Optical-flow velocity over the ground from a downward flow sensor and a rangefinder
    (see OpticalFlowAiding); None: off."""
