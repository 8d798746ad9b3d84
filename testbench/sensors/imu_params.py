"""IMU parameters in datasheet units, the named presets, and their conversion to SI.

Presets (every figure a datasheet gives is taken from it; the others are marked ASSUMED):

- `paper`: Zhang et al. 2023 (Appl. Sci. 13, 11278), section 4: gyro range 450 deg/s, bias
  stability 7 deg/h; accelerometer range 20 g, bias stability 14 ug. The issue fixes the angle
  random walk 0.15 deg/sqrt(h) and velocity random walk 0.02 m/s/sqrt(h). Turn-on bias, scale
  factor, misalignment and resolution are ASSUMED (the paper gives none); rate random walk 0.
- `consumer_mems`: TDK InvenSense ICM-42688-P datasheet (DS-000347): gyro +-2000 dps,
  16.4 LSB/dps, rate noise 0.0028 dps/sqrt(Hz) (= 0.168 deg/sqrt(h)), zero-rate offset
  +-0.5 dps, sensitivity tolerance +-0.5 %, nonlinearity +-0.1 %, cross-axis +-1.25 %;
  accelerometer +-16 g, 2048 LSB/g, noise 70 ug/sqrt(Hz) (= 0.0412 m/s/sqrt(h)), zero-g offset
  +-20 mg, sensitivity +-0.5 %, nonlinearity +-0.1 %, cross-axis +-1 %. Gyro g-sensitivity
  0.1 dps/g as listed for the comparable Bosch BMI088 (BST-BMI088-DS001). Bias instability and
  rate random walk are not datasheet items: 10 deg/h, 100 ug and the random walks are ASSUMED,
  typical of published Allan plots of such parts.
- `tactical`: Analog Devices ADIS16495-1 datasheet (Rev. C): gyro +-125 deg/s, in-run bias
  stability 0.8 deg/h, angle random walk 0.09 deg/sqrt(h), axis-to-axis misalignment +-0.05 deg
  (0.87 mrad); accelerometer +-8 g, in-run bias stability 3.2 ug, velocity random walk
  0.008 m/s/sqrt(h); 32-bit outputs (resolution below the noise). Turn-on bias and scale factor
  residuals after factory calibration are ASSUMED.

Values are 1-sigma for randomly drawn constants (turn-on bias, scale factor, misalignment):
each run draws them once from N(0, value^2); non-linearity gets a random sign per axis.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import Field

from testbench.core.registry import ParamsModel
from testbench.core.units import DEG_TO_RAD, STANDARD_GRAVITY_MPS2 as G0

PRESETS: dict[str, dict[str, float]] = {
    "paper": dict(
        gyro_range_deg_s=450.0, gyro_arw_deg_rth=0.15, gyro_bias_instability_deg_h=7.0,
        gyro_rrw_deg_h_rth=0.0, gyro_turn_on_bias_deg_h=10.0, gyro_scale_factor_ppm=100.0,
        gyro_nonlinearity_ppm=0.0, gyro_misalignment_mrad=0.1, gyro_g_sensitivity_deg_h_g=0.0,
        gyro_lsb_deg_s=450.0 / 2**20,
        accel_range_g=20.0, accel_vrw_mps_rth=0.02, accel_bias_instability_ug=14.0,
        accel_rrw_ug_rth=0.0, accel_turn_on_bias_mg=0.1, accel_scale_factor_ppm=100.0,
        accel_nonlinearity_ppm=0.0, accel_misalignment_mrad=0.1, accel_lsb_mg=20000.0 / 2**20,
    ),
    "consumer_mems": dict(
        gyro_range_deg_s=2000.0, gyro_arw_deg_rth=0.0028 * 60.0, gyro_bias_instability_deg_h=10.0,
        gyro_rrw_deg_h_rth=30.0, gyro_turn_on_bias_deg_h=0.5 * 3600.0, gyro_scale_factor_ppm=5000.0,
        gyro_nonlinearity_ppm=1000.0, gyro_misalignment_mrad=12.5, gyro_g_sensitivity_deg_h_g=0.1 * 3600.0,
        gyro_lsb_deg_s=1.0 / 16.4,
        accel_range_g=16.0, accel_vrw_mps_rth=70e-6 * G0 * 60.0, accel_bias_instability_ug=100.0,
        accel_rrw_ug_rth=300.0, accel_turn_on_bias_mg=20.0, accel_scale_factor_ppm=5000.0,
        accel_nonlinearity_ppm=1000.0, accel_misalignment_mrad=10.0, accel_lsb_mg=1000.0 / 2048.0,
    ),
    "tactical": dict(
        gyro_range_deg_s=125.0, gyro_arw_deg_rth=0.09, gyro_bias_instability_deg_h=0.8,
        gyro_rrw_deg_h_rth=0.0, gyro_turn_on_bias_deg_h=3.0, gyro_scale_factor_ppm=200.0,
        gyro_nonlinearity_ppm=0.0, gyro_misalignment_mrad=0.87, gyro_g_sensitivity_deg_h_g=0.0,
        gyro_lsb_deg_s=125.0 / 2**31,
        accel_range_g=8.0, accel_vrw_mps_rth=0.008, accel_bias_instability_ug=3.2,
        accel_rrw_ug_rth=0.0, accel_turn_on_bias_mg=0.2, accel_scale_factor_ppm=200.0,
        accel_nonlinearity_ppm=0.0, accel_misalignment_mrad=0.87, accel_lsb_mg=8000.0 / 2**31,
    ),
}

_Opt = float | None


class ImuParams(ParamsModel):
    """Scenario parameters of the `imu` sensor: a preset plus any datasheet-unit overrides.

    Keys left out (None) take the preset's value. lever_arm_b_m: IMU position relative to the
    centre of gravity in body FRD (m).
    """

    preset: Literal["paper", "consumer_mems", "tactical"] = "paper"
    rate_hz: float = Field(100.0, gt=0)
    lever_arm_b_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gyro_range_deg_s: _Opt = Field(None, gt=0)
    gyro_arw_deg_rth: _Opt = Field(None, ge=0)
    gyro_bias_instability_deg_h: _Opt = Field(None, ge=0)
    gyro_rrw_deg_h_rth: _Opt = Field(None, ge=0)
    gyro_turn_on_bias_deg_h: _Opt = Field(None, ge=0)
    gyro_scale_factor_ppm: _Opt = Field(None, ge=0)
    gyro_nonlinearity_ppm: _Opt = Field(None, ge=0)
    gyro_misalignment_mrad: _Opt = Field(None, ge=0)
    gyro_g_sensitivity_deg_h_g: _Opt = Field(None, ge=0)
    gyro_lsb_deg_s: _Opt = Field(None, ge=0)
    accel_range_g: _Opt = Field(None, gt=0)
    accel_vrw_mps_rth: _Opt = Field(None, ge=0)
    accel_bias_instability_ug: _Opt = Field(None, ge=0)
    accel_rrw_ug_rth: _Opt = Field(None, ge=0)
    accel_turn_on_bias_mg: _Opt = Field(None, ge=0)
    accel_scale_factor_ppm: _Opt = Field(None, ge=0)
    accel_nonlinearity_ppm: _Opt = Field(None, ge=0)
    accel_misalignment_mrad: _Opt = Field(None, ge=0)
    accel_lsb_mg: _Opt = Field(None, ge=0)

    def datasheet(self) -> dict[str, float]:
        """The preset's datasheet values with this model's overrides applied."""
        values = dict(PRESETS[self.preset])
        for key in values:
            v = getattr(self, key)
            if v is not None:
                values[key] = float(v)
        return values

    def spec(self) -> "ImuSpec":
        """The SI specification these parameters describe."""
        return ImuSpec.from_datasheet(self.datasheet(), np.asarray(self.lever_arm_b_m, float))


@dataclass(frozen=True)
class TriadSpec:
    """One triad's error parameters in SI units of its quantity q (rad/s or m/s^2).

    range_q: saturation; white_density: q*sqrt(s); bias_instability: q; rate_random_walk:
    q/sqrt(s); turn_on_bias: q (1 sigma); scale_factor, nonlinearity, misalignment: unitless
    (1 sigma; nonlinearity as a fraction of full scale); lsb: quantisation step (0 = none).
    """

    range_q: float
    white_density: float
    bias_instability: float
    rate_random_walk: float
    turn_on_bias: float
    scale_factor: float
    nonlinearity: float
    misalignment: float
    lsb: float


@dataclass(frozen=True)
class ImuSpec:
    """Gyro and accelerometer specs in SI plus the gyro g-sensitivity (rad/s per m/s^2)."""

    gyro: TriadSpec
    accel: TriadSpec
    g_sensitivity: float
    lever_arm_b_m: np.ndarray

    @staticmethod
    def from_datasheet(d: dict[str, float], lever_arm_b_m: np.ndarray | None = None) -> "ImuSpec":
        deg_h = DEG_TO_RAD / 3600.0  # deg/h -> rad/s
        ug = 1e-6 * G0  # ug -> m/s^2
        gyro = TriadSpec(
            range_q=d["gyro_range_deg_s"] * DEG_TO_RAD,
            white_density=d["gyro_arw_deg_rth"] * DEG_TO_RAD / 60.0,  # deg/sqrt(h) -> rad/sqrt(s)
            bias_instability=d["gyro_bias_instability_deg_h"] * deg_h,
            rate_random_walk=d["gyro_rrw_deg_h_rth"] * deg_h / 60.0,  # deg/h/sqrt(h) -> rad/s/sqrt(s)
            turn_on_bias=d["gyro_turn_on_bias_deg_h"] * deg_h,
            scale_factor=d["gyro_scale_factor_ppm"] * 1e-6,
            nonlinearity=d["gyro_nonlinearity_ppm"] * 1e-6,
            misalignment=d["gyro_misalignment_mrad"] * 1e-3,
            lsb=d["gyro_lsb_deg_s"] * DEG_TO_RAD,
        )
        accel = TriadSpec(
            range_q=d["accel_range_g"] * G0,
            white_density=d["accel_vrw_mps_rth"] / 60.0,  # m/s/sqrt(h) -> m/s^2*sqrt(s)
            bias_instability=d["accel_bias_instability_ug"] * ug,
            rate_random_walk=d["accel_rrw_ug_rth"] * ug / 60.0,  # ug/sqrt(h) -> m/s^2/sqrt(s)
            turn_on_bias=d["accel_turn_on_bias_mg"] * 1e3 * ug,
            scale_factor=d["accel_scale_factor_ppm"] * 1e-6,
            nonlinearity=d["accel_nonlinearity_ppm"] * 1e-6,
            misalignment=d["accel_misalignment_mrad"] * 1e-3,
            lsb=d["accel_lsb_mg"] * 1e3 * ug,
        )
        arm = np.zeros(3) if lever_arm_b_m is None else np.asarray(lever_arm_b_m, float)
        return ImuSpec(gyro, accel, d["gyro_g_sensitivity_deg_h_g"] * deg_h / G0, arm)


def arw_deg_rth(white_density_rad_rts: float) -> float:
    """Angle random walk in deg/sqrt(h) from a white density in rad/sqrt(s)."""
    return white_density_rad_rts * 60.0 / DEG_TO_RAD
