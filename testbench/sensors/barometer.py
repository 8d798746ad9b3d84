"""Barometric altimeter: JSBSim's static pressure with sensor errors, converted to altitude
with the International Standard Atmosphere.

    p_meas = Q(lag(p_true) + b0 + b_rw(t) + n),  altitude = ISA^-1(p_meas)
lag: first-order low-pass of time constant lag_s (the port and sensor response); b0 turn-on
bias (1 sigma); b_rw random walk of bias_drift_pa_rth (Pa/sqrt(h)); n white (1 sigma);
Q rounding to lsb_pa.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from testbench.core.interfaces import BuildContext, WorldView
from testbench.core.messages import BaroSample, TruthState
from testbench.core.registry import ParamsModel, register
from testbench.sensors.base import CachedSensor, check_rate

# ISA troposphere (ICAO Doc 7488): sea-level pressure, temperature, lapse rate, R/(g M).
P0_PA = 101325.0
T0_K = 288.15
LAPSE_K_PER_M = 0.0065
_EXP = 8.31446 * LAPSE_K_PER_M / (9.80665 * 0.0289644)  # ~0.190263


def isa_altitude_m(pressure_pa):
    """ISA pressure altitude (m) of static pressure (Pa), troposphere formula (valid < 11 km)."""
    return T0_K / LAPSE_K_PER_M * (1.0 - (np.asarray(pressure_pa, float) / P0_PA) ** _EXP)


def isa_pressure_pa(altitude_m):
    """ISA static pressure (Pa) at pressure altitude (m), the inverse of isa_altitude_m."""
    base = np.maximum(1.0 - LAPSE_K_PER_M * np.asarray(altitude_m, float) / T0_K, 0.0)
    return P0_PA * base ** (1.0 / _EXP)


class BarometerParams(ParamsModel):
    """Defaults are of the order of a Bosch BMP388 (0.03 Pa RMS noise in high resolution;
    +-50 Pa absolute accuracy as the turn-on bias)."""

    rate_hz: float = Field(50.0, gt=0)
    noise_pa: float = Field(1.0, ge=0)
    bias_pa: float = Field(50.0, ge=0)
    bias_drift_pa_rth: float = Field(5.0, ge=0)
    lag_s: float = Field(0.05, ge=0)
    lsb_pa: float = Field(0.0, ge=0)


@register("sensor", "barometer")
class Barometer(CachedSensor):
    """Returns BaroSample(pressure_pa, altitude_m)."""

    Params = BarometerParams

    def __init__(self, params: BarometerParams, *, ctx: BuildContext):
        super().__init__()
        self.params = params
        self.name = "barometer"
        self.rate_hz = check_rate(params.rate_hz, ctx, "barometer")
        self.dt_s = 1.0 / self.rate_hz
        self._bias: float | None = None
        self._lagged: float | None = None

    def _sample(self, truth: TruthState, world: WorldView, rng: np.random.Generator) -> BaroSample:
        p = self.params
        z = rng.standard_normal(3)
        if self._bias is None:
            self._bias = p.bias_pa * z[0]
            self._lagged = float(truth.pressure_pa)
        else:
            self._bias += p.bias_drift_pa_rth / 60.0 * math.sqrt(self.dt_s) * z[0]
            # Exact discretisation of dx/dt = (p - x) / lag for a held input.
            a = math.exp(-self.dt_s / p.lag_s) if p.lag_s > 0 else 0.0
            self._lagged = a * self._lagged + (1.0 - a) * float(truth.pressure_pa)
        meas = self._lagged + self._bias + p.noise_pa * z[1]
        if p.lsb_pa > 0:
            meas = round(meas / p.lsb_pa) * p.lsb_pa
        return BaroSample(truth.t_s, float(meas), float(isa_altitude_m(meas)))
