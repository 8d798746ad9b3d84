"""The INS/EKF navigator's filter from its settings: settings.InsEkfParams -> ErrorStateEKF
arguments, and the prior sigmas of the optional states (those a filter carries only when its
settings ask: appearance, magnetic bias, flow error, camera boresight, time offset and
intrinsics, the map's error)."""

from __future__ import annotations

import math
from typing import Iterator

import numpy as np

from testbench.core.units import DEG_TO_RAD
from testbench.navigation.ins.air_aiding import wind_settings
from testbench.navigation.ins.ekf import ErrorStateEKF
from testbench.navigation.ins.imu_noise import ImuNoiseSI, preset_scale_error
from testbench.navigation.ins.settings import InsEkfParams


def build_ekf(params: InsEkfParams, noise: ImuNoiseSI, fix_error_sigma_ned_m: np.ndarray, drag_scale_sigma: float,
              vehicle_id: str | None) -> ErrorStateEKF:
    """The navigator's ErrorStateEKF. fix_error_sigma_ned_m (3,) m: the shared fix error's
    steady-state sigma per NED axis; drag_scale_sigma: the drag scale's (0 without drag aiding)."""
    p = params
    wind = wind_settings(p)
    return ErrorStateEKF(
        noise, gate_probability=p.gate_probability,
        cov_interval_s=p.cov_interval_s,
        baro_bias_rw_m_sqrt_s=p.baro_bias_rw_m_sqrt_s,
        gnss_error_sigma_m=p.gnss_error_sigma_m, gnss_error_tau_s=p.gnss_error_tau_s,
        fix_error_sigma_m=fix_error_sigma_ned_m, fix_error_tau_s=p.fix_error_tau_s,
        fix_error_turn_rad=math.radians(p.fix_error_turn_deg) if p.fix_error_turn_deg else math.inf,
        bias_model=p.imu_bias_model, vehicle_id=vehicle_id,
        gyro_scale_sigma=preset_scale_error(p.imu_preset) if p.gyro_scale_error is None else p.gyro_scale_error,
        scale_corr_angle_rad=math.radians(p.scale_error_angle_deg),
        drag_scale_sigma=drag_scale_sigma,
        drag_scale_tau_s=math.inf if p.drag_aiding is None else p.drag_aiding.scale_tau_s,
        wind_states=wind is not None,
        wind_rw_mps_sqrt_s=0.0 if wind is None else wind.wind_rw_mps_sqrt_s,
        appearance_sigma_m=p.fix_appearance_sigma_m,
        mag_bias_sigma_rad=0.0 if p.mag_bias is None else p.mag_bias.sigma_deg * DEG_TO_RAD,
        mag_bias_correlation_m=math.inf if p.mag_bias is None else p.mag_bias.correlation_m,
        flow_bias_sigma_rps=0.0 if p.optical_flow is None else p.optical_flow.bias_sigma_rps,
        flow_bias_tau_s=math.inf if p.optical_flow is None else p.optical_flow.bias_tau_s,
        flow_bias_correlation_rad=math.inf if p.optical_flow is None else p.optical_flow.bias_correlation_rad,
        camera_boresight_sigma_rad=0.0 if p.camera_boresight is None else p.camera_boresight.sigma_deg * DEG_TO_RAD,
        camera_time_offset_sigma_s=0.0 if p.camera_time_offset is None else p.camera_time_offset.sigma_s,
        camera_intrinsics_sigma=(0.0, 0.0, 0.0) if p.camera_intrinsics is None else p.camera_intrinsics.sigmas(),
        map_error_sigma_m=0.0 if p.map_error is None else p.map_error.sigma_m,
        map_error_correlation_m=math.inf if p.map_error is None else p.map_error.correlation_m,
    )


def optional_state_sigmas(ekf: ErrorStateEKF, params: InsEkfParams) -> Iterator[tuple]:
    """(index or slice into the error state, prior 1-sigma) of each optional state the filter
    carries: the steady state of the Gauss-Markov ones, the settings' sigma of the constants."""
    p = params
    if ekf.i_app is not None:
        yield ekf.i_app, p.fix_appearance_sigma_m
    if ekf.i_mag is not None:
        yield ekf.i_mag, p.mag_bias.sigma_deg * DEG_TO_RAD
    if ekf.i_flow is not None:
        yield ekf.i_flow, p.optical_flow.bias_sigma_rps
    if ekf.i_cam is not None:
        yield ekf.i_cam, p.camera_boresight.sigma_deg * DEG_TO_RAD
    if ekf.i_td is not None:
        yield ekf.i_td, p.camera_time_offset.sigma_s
    if ekf.i_ci is not None:
        yield ekf.i_ci, p.camera_intrinsics.sigmas()
    if ekf.i_map is not None:
        yield ekf.i_map, p.map_error.sigma_m
