"""The INS/EKF navigator component: `{type: ins_ekf, params: {...}}` in a scenario."""

from __future__ import annotations

import logging
import math

import numpy as np

from testbench.core import geodesy
from testbench.core.errors import InputError
from testbench.core.interfaces import BuildContext, Navigator
from testbench.core.messages import (
    AirspeedSample,
    BaroSample,
    CorrectionInfo,
    GnssFix,
    ImuSample,
    MagSample,
    NavEstimate,
    OpticalFlowSample,
    PositionFix,
    RadarAltSample,
    TruthState,
)
from testbench.core.registry import register
from testbench.core.rotations import quat_to_dcm, quat_to_euler
from testbench.core.units import DEG_TO_RAD, STANDARD_GRAVITY_MPS2
from testbench.navigation.ins import measurements as meas
from testbench.navigation.ins.air_aiding import AirRelativeAiding, wind_settings
from testbench.navigation.ins.consistency import error_state
from testbench.navigation.ins.delayed import DelayedFixes
from testbench.navigation.ins.fix_fusion import PositionFixFusion
from testbench.navigation.ins.build import build_ekf, optional_state_sigmas
from testbench.navigation.ins.error_model import IA, IBA, IBB, IBG, IDS, IFX, IGN, IP, IV, IW
from testbench.navigation.ins.flow_aiding import FlowVelocityAiding
from testbench.navigation.ins.gnss_guard import GnssSpoofGuard
from testbench.navigation.ins.imu_noise import (
    fit_to_flicker, imu_noise_from_datasheet, preset_datasheet, preset_names,
)
from testbench.navigation.ins.magnetic import OnboardMagneticModel
from testbench.navigation.ins.reacquire import update_or_reset
from testbench.navigation.ins.settings import InsEkfParams

log = logging.getLogger(__name__)


@register("navigator", "ins_ekf")
class InsEkfNavigator(PositionFixFusion, Navigator):
    """Strapdown INS in WGS-84 with a 23-state error-state EKF (position, velocity, attitude,
    gyro and accelerometer biases, barometer bias, the GNSS receiver's and the position fixes'
    shared errors, the rotor-drag scale; with airspeed aiding 25, the horizontal wind as well:
    error_model), aided by barometer, magnetometer, GNSS (while it has a fix), absolute
    position fixes (scene matching), rotor drag (multirotors), airspeed with zero sideslip
    (fixed wings) and optical flow with a rangefinder. Params: settings.InsEkfParams."""

    Params = InsEkfParams

    def __init__(self, params: InsEkfParams, *, ctx: BuildContext, aircraft: dict | None = None,
                 rng: np.random.Generator | None = None, **_: object):
        self.params = params
        self.ctx = ctx
        if params.initial_error == "sampled" and rng is None:
            raise ValueError("InsEkfNavigator: initial_error 'sampled' needs a random stream (rng=...)")
        self._alignment_rng = rng
        """The stream the alignment error is drawn from (initial_error sampled); nothing else uses it."""
        try:
            sheet = preset_datasheet(params.imu_preset)
        except KeyError:
            raise InputError(
                f"navigator.params.imu_preset: unknown preset {params.imu_preset!r}; "
                f"expected one of: {', '.join(preset_names())}"
            ) from None
        self.turn_on = (sheet.pop("gyro_turn_on_bias_deg_h"), sheet.pop("accel_turn_on_bias_ug"))
        for key in sheet:
            override = getattr(params.imu, key)
            if override is not None:
                sheet[key] = override
        self.noise = imu_noise_from_datasheet(
            **sheet, gyro_bias_tau_s=params.imu.gyro_bias_tau_s,
            accel_bias_tau_s=params.imu.accel_bias_tau_s,
        )
        if params.imu.flicker_fit_band_s is not None:
            self.noise = fit_to_flicker(self.noise, params.imu.flicker_fit_band_s)
        down = params.fix_error_sigma_m if params.fix_error_sigma_down_m is None else params.fix_error_sigma_down_m
        self.fix_error_sigma_ned_m = np.array([params.fix_error_sigma_m, params.fix_error_sigma_m, down])
        """(3,) m: steady-state sigma of the shared fix error per axis (north, east, down)."""
        self.drag_scale_sigma = 0.0 if params.drag_aiding is None else params.drag_aiding.scale_sigma
        """Steady-state sigma of the drag model's scale error (0 without drag aiding)."""
        self.ekf = build_ekf(params, self.noise, self.fix_error_sigma_ned_m, self.drag_scale_sigma, ctx.vehicle_id)
        self._mag_model: OnboardMagneticModel | None = None
        self._airspeed: float | None = None
        self._initialized = False
        self._last_gnss_t = -math.inf
        self._last_fix_ok_t_s: float | None = None  # last accepted position fix (None: none yet)
        self._fix_refusals = 0  # position fixes refused by the gate since the last accepted one
        self._last_gnss_ok_t_s: float | None = None  # last accepted GNSS fix (None: none yet)
        self._last_baro_ok_t_s: float | None = None  # last accepted barometer sample
        self._gnss_guard = None if params.gnss_monitor is None else GnssSpoofGuard(params.gnss_monitor)
        self.gnss_monitor = None if self._gnss_guard is None else self._gnss_guard.monitor
        self.estimates_wind = self.ekf.wind_states
        self.estimates_camera_boresight = self.ekf.i_cam is not None
        self.boresight_camera: str | None = None
        """The camera whose boresight the states are (check_aids: the ismn aid's), for scoring."""
        self.time_offset_camera: str | None = None
        """The camera whose time offset the state is (check_aids: the ismn aid's), for scoring."""
        self.intrinsics_camera: str | None = None
        """The camera whose intrinsics error the states are (check_aids: the ismn aid's), for scoring."""
        self.air = AirRelativeAiding(params, aircraft, ctx.vehicle_id)
        """Rotor-drag and airspeed aiding (air_aiding.py)."""
        self.flow = None if params.optical_flow is None else FlowVelocityAiding(params.optical_flow)
        """Optical-flow aiding (flow_aiding.py); None: off."""
        self.delayed = DelayedFixes(params.delayed_fixes, self.ROLLBACK_ATTRS + ("_fix_refusals",))
        """How fixes that come late are fused (delayed.py)."""
        # The last estimate() (None: the filter moved since). Aids, the controller and the
        # recorder all ask for it at a tick; in a ten-vehicle swarm building it each time was
        # a tenth of the run.
        self._estimate: NavEstimate | None = None

    # ----------------------------------------------------------- Navigator API
    def initialize(self, t_s: float, initial: NavEstimate) -> None:
        o = self.ctx.origin
        lat, lon, h = geodesy.ned_to_geodetic(np.asarray(initial.pos_ned_m, float),
                                              o.lat_rad, o.lon_rad, o.alt_m)
        P0 = self.initial_covariance()
        # The initial estimate's own covariances win where it has them (e.g. a GNSS alignment).
        R_no = meas.origin_rotation(float(lat), float(lon), o).T
        for sl, cov, rot in ((IP, initial.cov_pos_ned_m2, R_no), (IV, initial.cov_vel_ned_m2s2, None),
                             (IA, initial.cov_att_rad2, None)):
            c = np.asarray(cov, float)
            if c.shape == (3, 3) and np.all(np.isfinite(c)) and np.all(np.linalg.eigvalsh(0.5 * (c + c.T)) > 0):
                P0[sl, sl] = rot @ c @ rot.T if rot is not None else c
        self.ekf.initialize(t_s, float(lat), float(lon), float(h), initial.vel_ned_mps,
                            initial.q_nb_wxyz, P0)
        if self.params.initial_error == "sampled":
            self.ekf.inject(self.alignment_error(P0))
        self._initialized = True
        self._estimate = None

    def alignment_error(self, P0: np.ndarray) -> np.ndarray:
        """A draw of the alignment's error state (ekf.n,): position (NED m), velocity (NED
        m/s) and attitude (rad) from their block of P0, jointly; the other states zero (their
        true values are drawn by the sensors themselves: IMU and barometer turn-on biases, the
        GNSS receiver's correlated error)."""
        dx = np.zeros(self.ekf.n)
        nav = np.r_[IP, IV, IA]
        dx[nav] = self._alignment_rng.multivariate_normal(np.zeros(len(nav)), P0[np.ix_(nav, nav)], method="cholesky")
        return dx

    def initial_covariance(self) -> np.ndarray:
        """P0 (ekf.n, ekf.n) from Params.initial_sigma (GNSS and fix error states, the drag scale,
        the magnetic bias and the flow's slow error: their steady state; the wind, with wind
        states: their aiding's wind_sigma_mps; the camera's boresight: its sigma_deg; its time
        offset: its sigma_s)."""
        s = self.params.initial_sigma
        d = np.empty(self.ekf.n)
        d[IP] = s.pos_m
        d[IV] = s.vel_mps
        tilt_rad = s.tilt_deg * DEG_TO_RAD if s.tilt_deg else max(self.turn_on[1] * 1e-6, 0.05 * DEG_TO_RAD)
        d[IA] = [tilt_rad] * 2 + [s.heading_deg * DEG_TO_RAD]
        # A zero turn-on bias in a preset still leaves the in-run instability to cover.
        gyro_deg_h = s.gyro_bias_deg_h or max(self.turn_on[0], self.noise.gyro_bias_sigma_rps * 3600.0 / DEG_TO_RAD)
        accel_ug = s.accel_bias_ug or max(self.turn_on[1], self.noise.accel_bias_sigma_mps2 / 1e-6 / STANDARD_GRAVITY_MPS2)
        d[IBG] = gyro_deg_h * DEG_TO_RAD / 3600.0
        d[IBA] = accel_ug * 1e-6 * STANDARD_GRAVITY_MPS2
        d[IBB] = s.baro_bias_m
        d[IGN] = self.params.gnss_error_sigma_m
        d[IFX] = self.fix_error_sigma_ned_m
        d[IDS] = self.drag_scale_sigma
        if wind_settings(self.params) is not None:
            d[IW] = wind_settings(self.params).wind_sigma_mps
        for idx, sigma in optional_state_sigmas(self.ekf, self.params):
            d[idx] = sigma
        return np.diag(d**2)

    def predict(self, imu: ImuSample) -> None:
        self._require_init()
        self._estimate = None
        t_prev_s = self.ekf.t_s
        if self._gnss_guard is None:
            self.ekf.propagate(float(imu.t_s), imu.omega_ib_b_rps, imu.f_ib_b_mps2)
        else:  # the spoofing monitor's bookkeeping around the same propagation
            self._gnss_guard.propagate(self, imu)
        if self.flow is not None:
            self.flow.accumulate(self.ekf, t_prev_s)
        if self.air.drag_mu_per_s is not None:
            self.air.accumulate_drag(self.ekf, float(imu.t_s), imu.f_ib_b_mps2)
        self.delayed.record(imu)

    def expect(self, t_s: float) -> None:
        """A position fix stamped t_s (s; the present tick) will come later, once processed:
        keep what its fusion then needs (Params.delayed_fixes; delayed.py)."""
        self._require_init()
        self.delayed.expect(self, t_s)

    def correct(self, measurement) -> CorrectionInfo | None:
        self._require_init()
        self._estimate = None
        p, ekf = self.params, self.ekf
        t = float(getattr(measurement, "t_s", ekf.t_s))
        late = isinstance(measurement, PositionFix) and self.delayed.is_late(self, measurement)
        if self._gnss_guard is not None:
            self._gnss_guard.record(measurement)
        if not late:
            self.delayed.record(measurement)
        if isinstance(measurement, PositionFix):
            if not p.use_position_fix:
                return None
            return self.delayed.fuse(self, measurement) if late else self.fuse_fix_now(measurement)
        if isinstance(measurement, BaroSample):
            if not p.use_baro:
                return None
            return self._correct_baro(measurement, t)
        if isinstance(measurement, MagSample):
            return self._correct_mag(measurement, t) if p.use_mag else None
        if isinstance(measurement, GnssFix):
            return self._correct_gnss(measurement, t) if p.use_gnss else None
        if isinstance(measurement, OpticalFlowSample):
            return self.flow.correct(self.ekf, measurement) if self.flow is not None else None
        if isinstance(measurement, RadarAltSample):
            if self.flow is not None:  # the rangefinder scales the flow; TAN takes ranges as an aid
                self.flow.take_range(measurement)
            return None
        if isinstance(measurement, AirspeedSample):
            # Kept for the estimate (controllers fly airspeed); fused only with airspeed aiding
            # (its wind states make it a constraint on the velocity over the ground).
            self._airspeed = float(measurement.airspeed_mps)
            return self.air.correct_airspeed(self.ekf, self._airspeed, t) if p.airspeed_aiding is not None else None
        return None

    def estimate(self) -> NavEstimate:
        """Position in NED at the scenario origin (ctx.origin); velocity, attitude and their
        covariances in the NED frame at the vehicle (as an INS and the JSBSim truth report
        them; the two NED frames differ by ~1.6e-4 rad per km from the origin).

        The same object is returned until the next predict or correct; its arrays are
        read-only, so that no consumer can change what the others see."""
        if self._estimate is not None:
            return self._estimate
        self._require_init()
        ekf, o = self.ekf, self.ctx.origin
        ekf.flush()
        ins = ekf.ins
        q = np.array(ins.q)
        C = quat_to_dcm(q)
        wie = geodesy.earth_rate_ned_rps(ins.lat_rad)
        omega_b = np.asarray(ekf.omega_ib_b_rps, float) - C.T @ wie
        R_on = meas.origin_rotation(ins.lat_rad, ins.lon_rad, o)
        P = ekf.P
        est = NavEstimate(
            t_s=ekf.t_s,
            pos_ned_m=meas.nominal_pos_ned(ekf, o),
            vel_ned_mps=np.array(ins.vel),
            q_nb_wxyz=q,
            rpy_rad=quat_to_euler(q),
            omega_b_rps=omega_b,
            cov_pos_ned_m2=R_on @ P[IP, IP] @ R_on.T,
            cov_vel_ned_m2s2=P[IV, IV].copy(),
            cov_att_rad2=P[IA, IA].copy(),
            airspeed_mps=self._airspeed,
            wind_ne_mps=np.array(ekf.wind_ne_mps, float) if ekf.wind_states else None,
            cov_wind_ne_m2s2=P[IW, IW].copy() if ekf.wind_states else None,
            camera_boresight_b_rad=None if ekf.i_cam is None else ekf.b_cam_rad.copy(),
            cov_camera_boresight_rad2=None if ekf.i_cam is None else P[ekf.i_cam, ekf.i_cam].copy(),
            camera_time_offset_s=None if ekf.i_td is None else float(ekf.td_s),
            var_camera_time_offset_s2=None if ekf.i_td is None else float(P[ekf.i_td, ekf.i_td]),
            camera_intrinsics_error=None if ekf.i_ci is None else ekf.intrinsics_error.copy(),
            cov_camera_intrinsics_error=None if ekf.i_ci is None else P[ekf.i_ci, ekf.i_ci].copy(),
            map_error_ne_m=None if ekf.i_map is None else ekf.b_map.copy(),
            cov_map_error_ne_m2=None if ekf.i_map is None else P[ekf.i_map, ekf.i_map].copy(),
        )
        for a in (est.pos_ned_m, est.vel_ned_mps, est.q_nb_wxyz, est.rpy_rad, est.omega_b_rps,
                  est.cov_pos_ned_m2, est.cov_vel_ned_m2s2, est.cov_att_rad2, est.wind_ne_mps, est.cov_wind_ne_m2s2,
                  est.camera_boresight_b_rad, est.cov_camera_boresight_rad2, est.camera_intrinsics_error,
                  est.cov_camera_intrinsics_error, est.map_error_ne_m, est.cov_map_error_ne_m2):
            if a is not None:
                a.flags.writeable = False
        self._estimate = est
        return est

    def check_sensors(self, sensors: dict, where: str) -> None:
        """Raise InputError when an aiding the params turn on lacks its sensors on the vehicle
        (sensors: name -> sensor; where: the navigator's scenario path)."""
        if self.flow is None:
            return
        from testbench.sensors.optical_flow import OpticalFlowSensor
        from testbench.sensors.radar_altimeter import RadarAltimeter

        limit = math.radians(self.params.optical_flow.max_beam_half_angle_deg)
        if not any(isinstance(x, OpticalFlowSensor) for x in sensors.values()):
            raise InputError(f"{where}.params.optical_flow: the vehicle has no optical_flow sensor "
                             f"(have: {', '.join(sensors) or 'none'})")
        if not any(isinstance(x, RadarAltimeter) and x.beam_half_angle_rad <= limit + 1e-12 for x in sensors.values()):
            raise InputError(f"{where}.params.optical_flow: the flow needs a downward rangefinder: a radar_altimeter "
                             f"sensor with beam_half_angle_deg <= {self.params.optical_flow.max_beam_half_angle_deg:g} "
                             "(a pencil beam along body z)")

    def check_aids(self, aids: list, where: str) -> None:
        """Raise InputError when the boresight states (Params.camera_boresight) have no scene
        matcher to learn them from (exactly one aid whose fixes carry the image-only pose), or
        when fixes that come late would be replayed over the spoofing monitor's own rewinds."""
        if self.ekf.i_td is not None:
            self.time_offset_camera = self._one_matcher_camera(
                aids, f"{where}.params.camera_time_offset: the time offset",
                "the image pose's attitude rows do not model the offset")
        if self.ekf.i_ci is not None:
            self.intrinsics_camera = self._one_matcher_camera(
                aids, f"{where}.params.camera_intrinsics: the intrinsics error",
                "the image pose's rows do not model the intrinsics")
        if self.ekf.i_map is not None:
            from testbench.navigation.ismn_aid import IsmnAid

            if not any(isinstance(a, IsmnAid) for a in aids):
                raise InputError(f"{where}.params.map_error: the map error states are seen only by scene-matching "
                                 "fixes: the vehicle needs an ismn aid (has none); expected map_error left out")
        late = [a for a in aids if getattr(getattr(a, "params", None), "latency_s", 0.0) > 0.0]
        if late and self._gnss_guard is not None and self.params.delayed_fixes == "replay":
            raise InputError(
                f"{where}.params.delayed_fixes: 'replay' cannot run beside the GNSS spoofing monitor (gnss_monitor), "
                "whose rewinds replay the same inputs; with an aid's latency_s > 0 expected delayed_fixes 'carry' or "
                "'as_current'")
        if self.ekf.i_cam is None:
            return
        offering = [a for a in aids if getattr(a, "offers_image_pose", False)]
        if len(offering) != 1:
            raise InputError(
                f"{where}.params.camera_boresight: the boresight states are one camera's and are learnt from its fixes' "
                f"image-only pose: the vehicle needs exactly one ismn aid with pipeline.pose_from_image: true "
                f"(has {len(offering)})")
        self.boresight_camera = offering[0].params.camera

    def _one_matcher_camera(self, aids: list, what: str, why_no_boresight: str) -> str:
        """The camera of the only ismn aid, whose fixes teach camera states (InputError naming `what` if not one)."""
        from testbench.navigation.ismn_aid import IsmnAid

        matchers = [a for a in aids if isinstance(a, IsmnAid)]
        if len(matchers) != 1 or self.ekf.i_cam is not None:
            raise InputError(
                f"{what} is one scene-matching camera's, learnt from its fixes: the vehicle needs exactly one ismn aid "
                f"(has {len(matchers)}), and no camera_boresight states beside it ({why_no_boresight})")
        return matchers[0].params.camera

    # ------------------------------------------------------------------ extras
    def covariance(self) -> np.ndarray:
        """Full error covariance (ekf.n, ekf.n) in the filter's own frames (error_model layout)."""
        return self.ekf.covariance()

    def error_state(self, truth: TruthState, gyro_bias_rps=None, accel_bias_mps2=None) -> np.ndarray:
        """True error (15,) of the current estimate (truth (-) estimate, error_model layout)."""
        return error_state(self.ekf, truth, gyro_bias_rps, accel_bias_mps2)

    def _correct_mag(self, m: MagSample, t: float) -> CorrectionInfo:
        ekf, p = self.ekf, self.params
        ins = ekf.ins
        if self._mag_model is None:
            self._mag_model = OnboardMagneticModel(self.ctx.epoch_utc_year)
        B_n = self._mag_model.field_ned_T(ins.lat_rad, ins.lon_rad, ins.h_m)
        if p.mag_mode == "vector":
            return ekf.update("mag", t, *meas.mag_vector(ekf, m.field_b_T, B_n, p.meas_sigma.mag_T))
        sigma = p.meas_sigma.mag_heading_deg * DEG_TO_RAD
        return ekf.update("mag_heading", t, *meas.mag_heading(ekf, m.field_b_T, B_n, sigma))

    def _correct_gnss(self, fix: GnssFix, t: float) -> CorrectionInfo | None:
        if t - self._last_gnss_t < self.params.gnss_min_interval_s - 1e-9:
            return None
        self._last_gnss_t = t
        vel = np.asarray(fix.vel_ned_mps, float)
        y, H, R = self._gnss_residual(fix, vel)
        if self._gnss_guard is not None:
            excluded = self._gnss_guard.screen(self, fix, t, vel, y, H, R)
            if excluded is not None:
                return excluded
        info, self._last_gnss_ok_t_s = self._update_or_reset(
            "gnss", t, y, H, R, self._last_gnss_ok_t_s, self._last_fix_ok_t_s, self.params.gnss_reset_after_s)
        return info

    def _gnss_residual(self, fix: GnssFix, vel: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """y, H, R of a GNSS fix against the filter: position, and velocity when used."""
        ekf, s = self.ekf, self.params.meas_sigma
        if s.gnss_pos_m:  # an override is the white part alone
            pos_sigma = np.full(3, s.gnss_pos_m)
        else:
            # The receiver claims its total error; the correlated part is in the b_gnss states.
            # Keep at least a tenth of the claim as white noise (a receiver claiming less than
            # the modelled correlated error must not become an exact measurement).
            claim2 = np.square(np.asarray(fix.pos_sigma_m, float))
            pos_sigma = np.sqrt(np.maximum(claim2 - self.params.gnss_error_sigma_m**2, 0.01 * claim2))
        y, H, R = meas.gnss_position(ekf, fix.lat_rad, fix.lon_rad, fix.alt_m, pos_sigma)
        if self.params.use_gnss_velocity and vel.shape == (3,) and np.all(np.isfinite(vel)):
            vel_sigma = np.full(3, s.gnss_vel_mps) if s.gnss_vel_mps else np.asarray(fix.vel_sigma_mps, float)
            yv, Hv, Rv = meas.gnss_velocity(ekf, vel, vel_sigma)
            y, H = np.concatenate([y, yv]), np.vstack([H, Hv])
            R = np.block([[R, np.zeros((3, 3))], [np.zeros((3, 3)), Rv]])
        return y, H, R

    # The navigator's state a rewind of the spoofing monitor restores (gnss_guard.py): the
    # filter and the bookkeeping of its aids.
    ROLLBACK_ATTRS = ("ekf", "air", "flow", "_airspeed", "_last_gnss_t", "_last_fix_ok_t_s", "_last_gnss_ok_t_s",
                      "_last_baro_ok_t_s")

    def _correct_baro(self, baro: BaroSample, t: float) -> CorrectionInfo:
        """Fuse a barometric altitude through the gate; after baro_reset_after_s of rejections
        reset the height to it (Params.baro_reset_after_s)."""
        y, H, R = meas.baro_altitude(self.ekf, baro.altitude_m, self.params.meas_sigma.baro_m)
        info, self._last_baro_ok_t_s = self._update_or_reset(
            "baro", t, y, H, R, self._last_baro_ok_t_s, None, self.params.baro_reset_after_s, self.ekf.reset_height)
        return info

    def _update_or_reset(self, kind: str, t: float, y, H, R, last_ok_t_s: float | None,
                         other_ok_t_s: float | None, reset_after_s: float,
                         reset=None) -> tuple[CorrectionInfo, float | None]:
        """An absolute fix (GNSS, position fix, barometric height) through the gate, or the
        filter reset to it (`reset`: ErrorStateEKF.reset_position by default, reset_height for
        the barometer) after reset_after_s of refusals unless the OTHER absolute aid agrees
        (reacquire.update_or_reset). Returns (info, this source's new last-accepted time)."""
        return update_or_reset(self.ekf, kind, t, y, H, R, last_ok_t_s, reset_after_s,
                               reset or self.ekf.reset_position, other_ok_t_s)

    def _require_init(self) -> None:
        if not self._initialized:
            raise RuntimeError("InsEkfNavigator used before initialize()")

