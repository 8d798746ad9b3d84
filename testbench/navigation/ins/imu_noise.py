"""IMU noise parameters for the filter: datasheet units at the edge, SI inside.

The filter models each inertial sensor as white noise (angle / velocity random walk) plus a
first-order Gauss-Markov bias with standard deviation `bias instability` and correlation time
tau (the usual stand-in for the flicker floor of an Allan plot). A tau of 0 or infinity is not
allowed: use a long tau (e.g. 3600 s) for a nearly constant bias.

That stand-in drifts less than the flicker floor it stands for over tens of seconds (about half
its 1-sigma drift at 10-60 s for sigma = B, tau = 300 s). `fit_to_flicker` refits the white
noise and the bias random walk a filter carries so that its drift follows the sensor's over the
coasting times that matter to it (`ImuNoiseParams.flicker_fit_band_s`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

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


def _gm_drift_var(sigma: float, tau_s: float, horizon_s: np.ndarray) -> np.ndarray:
    """Variance of the integral over horizon_s (s, any shape) of a first-order Gauss-Markov
    process of sigma (q) and correlation time tau_s whose state at the start is known:
    sigma^2 tau^2 (2x - 3 + 4 e^-x - e^-2x), x = T / tau (q^2 s^2). Written with expm1, whose
    terms are O(x), so that the x^3 it leaves for T << tau is not lost to cancellation."""
    x = np.asarray(horizon_s, float) / tau_s
    return sigma**2 * tau_s**2 * (2.0 * x + 4.0 * np.expm1(-x) - np.expm1(-2.0 * x))


def flicker_drift_sigma(white_density: float, bias_instability: float, rate_random_walk: float,
                        horizon_s: np.ndarray) -> np.ndarray:
    """How far a sensor's error integrates over horizon_s from a start at which every part of
    its state is known: the 1-sigma drift (q s) of an axis with white noise (q sqrt(s)),
    flicker bias instability B (q) and rate random walk (q / sqrt(s)), as the sensor model
    builds them (testbench.sensors.noise: the flicker floor as a bank of Gauss-Markov
    processes a decade apart). For a gyro in rad/s it is the attitude drift in rad; for an
    accelerometer in m/s^2 the velocity drift in m/s. Shape of horizon_s."""
    from testbench.sensors.noise import FLICKER_CORR_TIMES_S, flicker_sigma  # noqa: PLC0415 (sensors own the model)

    t = np.asarray(horizon_s, float)
    sigma = flicker_sigma(bias_instability)
    var = white_density**2 * t + rate_random_walk**2 * t**3 / 3.0
    for tau_s in FLICKER_CORR_TIMES_S:
        var = var + _gm_drift_var(sigma, float(tau_s), t)
    return np.sqrt(var)


def fit_to_flicker(noise: ImuNoiseSI, band_s: tuple[float, float]) -> ImuNoiseSI:
    """The filter's white noise and bias random walk refitted so that the drift the filter
    expects between aids follows the sensor's over coasting times band_s (s).

    Why: a datasheet's bias instability B is the flat floor of an Allan plot, flicker (1/f)
    noise, which drifts at every time scale. One Gauss-Markov state of sigma B and tau 100-300
    s (imu_noise_from_datasheet) drifts far less over tens of seconds: integrated from a known
    start, the paper gyro's flicker drifts 0.49 mrad in 20 s and 0.95 mrad in 40 s, the filter's
    default model 0.24 and 0.47 mrad, so a filter coasting between aids claimed a quarter of
    the attitude variance it gathered. A filter carrying the bias error as a random walk
    (ErrorStateEKF, bias_model random_walk) expects the drift variance N'^2 T + q' T^3 / 3 over
    T; the fit is the least squares of that against the sensor's variance, relative (each T
    weighted by the sensor's variance), over 24 horizons spaced evenly in log T across band_s,
    with N'^2 and q' kept non-negative (scipy nnls). The white density becomes N'; the random
    walk the Gauss-Markov's 2 sigma^2 / tau leaves short of q' goes into the rate random walk
    (sigma and tau are kept: the filter's initial bias uncertainty and its gauss_markov mode
    use them). Gyro and accelerometer alike. ValueError for a band that is not 0 < t1 < t2."""
    from scipy.optimize import nnls  # noqa: PLC0415 (only the fit needs it)

    t1, t2 = (float(b) for b in band_s)
    if not (0.0 < t1 < t2 and math.isfinite(t2)):
        raise ValueError(f"flicker fit band {band_s!r}: expected 0 < t1 < t2 (s)")
    t = np.geomspace(t1, t2, 24)

    def refit(white: float, sigma: float, tau_s: float, rrw: float) -> tuple[float, float]:
        var = flicker_drift_sigma(white, sigma, rrw, t) ** 2
        design = np.column_stack([t, t**3 / 3.0]) / var[:, None]
        (white2, q), _ = nnls(design, np.ones_like(t))
        return math.sqrt(white2), math.sqrt(max(q - 2.0 * sigma**2 / tau_s, 0.0))

    arw, gyro_rrw = refit(noise.gyro_arw_rad_sqrt_s, noise.gyro_bias_sigma_rps, noise.gyro_bias_tau_s,
                          noise.gyro_rrw_rps_sqrt_s)
    vrw, accel_rrw = refit(noise.accel_vrw_mps_sqrt_s, noise.accel_bias_sigma_mps2, noise.accel_bias_tau_s,
                           noise.accel_rrw_mps2_sqrt_s)
    return ImuNoiseSI(
        gyro_arw_rad_sqrt_s=arw, gyro_bias_sigma_rps=noise.gyro_bias_sigma_rps,
        gyro_bias_tau_s=noise.gyro_bias_tau_s, accel_vrw_mps_sqrt_s=vrw,
        accel_bias_sigma_mps2=noise.accel_bias_sigma_mps2, accel_bias_tau_s=noise.accel_bias_tau_s,
        gyro_rrw_rps_sqrt_s=gyro_rrw, accel_rrw_mps2_sqrt_s=accel_rrw,
    )
