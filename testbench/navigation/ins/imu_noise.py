"""IMU noise parameters for the filter: datasheet units at the edge, SI inside.

The filter models each inertial sensor as white noise (angle / velocity random walk) plus a
first-order Gauss-Markov bias with standard deviation `bias instability` and correlation time
tau (the usual stand-in for the flicker floor of an Allan plot). A tau of 0 or infinity is not
allowed: use a long tau (e.g. 3600 s) for a nearly constant bias.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from testbench.core.units import DEG_TO_RAD, STANDARD_GRAVITY_MPS2

_DEG_PER_SQRT_H = DEG_TO_RAD / 60.0  # deg/sqrt(h) -> rad/sqrt(s)
_MPS_PER_SQRT_H = 1.0 / 60.0  # m/s/sqrt(h) -> m/s/sqrt(s)
_DEG_PER_H = DEG_TO_RAD / 3600.0  # deg/h -> rad/s
_MICRO_G = 1e-6 * STANDARD_GRAVITY_MPS2  # ug -> m/s^2


@dataclass(frozen=True, slots=True)
class ImuNoiseSI:
    """IMU noise in SI units.

    gyro_arw_rad_sqrt_s: angle random walk (rad/sqrt(s)) = white rate noise PSD sqrt;
    gyro_bias_sigma_rps, gyro_bias_tau_s: Gauss-Markov gyro bias (rad/s, s);
    accel_vrw_mps_sqrt_s: velocity random walk (m/s/sqrt(s));
    accel_bias_sigma_mps2, accel_bias_tau_s: Gauss-Markov accelerometer bias (m/s^2, s);
    *_rrw_*: rate random walks, added to the bias driving noise (rad/s/sqrt(s), m/s^2/sqrt(s)).
    """

    gyro_arw_rad_sqrt_s: float
    gyro_bias_sigma_rps: float
    gyro_bias_tau_s: float
    accel_vrw_mps_sqrt_s: float
    accel_bias_sigma_mps2: float
    accel_bias_tau_s: float
    gyro_rrw_rps_sqrt_s: float = 0.0
    accel_rrw_mps2_sqrt_s: float = 0.0


def imu_noise_from_datasheet(
    gyro_arw_deg_sqrt_h: float,
    gyro_bias_instability_deg_h: float,
    accel_vrw_mps_sqrt_h: float,
    accel_bias_instability_ug: float,
    gyro_bias_tau_s: float = 300.0,
    accel_bias_tau_s: float = 300.0,
    gyro_rrw_deg_h_sqrt_h: float = 0.0,
    accel_rrw_ug_sqrt_h: float = 0.0,
) -> ImuNoiseSI:
    """Datasheet units (deg/sqrt(h), deg/h, m/s/sqrt(h), micro-g; rate random walks in
    deg/h/sqrt(h) and ug/sqrt(h)) -> ImuNoiseSI."""
    if not (math.isfinite(gyro_bias_tau_s) and gyro_bias_tau_s > 0.0):
        raise ValueError(f"gyro_bias_tau_s must be finite and > 0, got {gyro_bias_tau_s}")
    if not (math.isfinite(accel_bias_tau_s) and accel_bias_tau_s > 0.0):
        raise ValueError(f"accel_bias_tau_s must be finite and > 0, got {accel_bias_tau_s}")
    return ImuNoiseSI(
        gyro_arw_rad_sqrt_s=gyro_arw_deg_sqrt_h * _DEG_PER_SQRT_H,
        gyro_bias_sigma_rps=gyro_bias_instability_deg_h * _DEG_PER_H,
        gyro_bias_tau_s=float(gyro_bias_tau_s),
        accel_vrw_mps_sqrt_s=accel_vrw_mps_sqrt_h * _MPS_PER_SQRT_H,
        accel_bias_sigma_mps2=accel_bias_instability_ug * _MICRO_G,
        accel_bias_tau_s=float(accel_bias_tau_s),
        gyro_rrw_rps_sqrt_s=gyro_rrw_deg_h_sqrt_h * _DEG_PER_H / 60.0,
        accel_rrw_mps2_sqrt_s=accel_rrw_ug_sqrt_h * _MICRO_G / 60.0,
    )


def preset_datasheet(name: str) -> dict[str, float]:
    """Filter-relevant datasheet values of a sensor preset (testbench.sensors.imu_params):
    the keys of `imu_noise_from_datasheet` plus the turn-on biases (gyro_turn_on_bias_deg_h,
    accel_turn_on_bias_ug) used as default initial bias uncertainties. KeyError if unknown."""
    from testbench.sensors.imu_params import PRESETS  # noqa: PLC0415 (sensors own the presets)

    d = PRESETS[name]
    return dict(
        gyro_arw_deg_sqrt_h=d["gyro_arw_deg_rth"],
        gyro_bias_instability_deg_h=d["gyro_bias_instability_deg_h"],
        accel_vrw_mps_sqrt_h=d["accel_vrw_mps_rth"],
        accel_bias_instability_ug=d["accel_bias_instability_ug"],
        gyro_rrw_deg_h_sqrt_h=d["gyro_rrw_deg_h_rth"],
        accel_rrw_ug_sqrt_h=d["accel_rrw_ug_rth"],
        gyro_turn_on_bias_deg_h=d["gyro_turn_on_bias_deg_h"],
        accel_turn_on_bias_ug=d["accel_turn_on_bias_mg"] * 1e3,
    )


def preset_scale_error(name: str) -> float:
    """1-sigma gyro rate error per unit rate of a sensor preset, sqrt(scale factor^2 +
    misalignment^2) (unitless: rad of attitude error per rad turned, about one axis). KeyError
    if unknown."""
    from testbench.sensors.imu_params import PRESETS  # noqa: PLC0415 (sensors own the presets)

    d = PRESETS[name]
    return math.hypot(d["gyro_scale_factor_ppm"] * 1e-6, d["gyro_misalignment_mrad"] * 1e-3)


def preset_names() -> list[str]:
    from testbench.sensors.imu_params import PRESETS  # noqa: PLC0415

    return sorted(PRESETS)
