"""Pitot-static airspeed: noise and bias on the differential (dynamic) pressure.

    q = rho V^2 / 2,  rho = p / (R T);  q_meas = q + b + n;  V_meas = sqrt(2 max(q_meas, 0) / rho)
So the speed error grows at low speed, as with a real pitot.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from testbench.core.interfaces import BuildContext, WorldView
from testbench.core.messages import AirspeedSample, TruthState
from testbench.core.registry import ParamsModel, register
from testbench.sensors.base import CachedSensor, check_rate

R_AIR = 287.05287  # J/(kg K)


class AirspeedParams(ParamsModel):
    """noise_pa: 1-sigma white noise of the differential pressure; bias_pa: 1-sigma turn-on bias
    (e.g. an MS4525DO-class sensor: a few Pa)."""

    rate_hz: float = Field(20.0, gt=0)
    noise_pa: float = Field(2.0, ge=0)
    bias_pa: float = Field(1.0, ge=0)


@register("sensor", "airspeed")
class Airspeed(CachedSensor):
    """Returns AirspeedSample (true airspeed, m/s)."""

    Params = AirspeedParams

    def __init__(self, params: AirspeedParams, *, ctx: BuildContext):
        super().__init__()
        self.params = params
        self.name = "airspeed"
        self.rate_hz = check_rate(params.rate_hz, ctx, "airspeed")
        self._bias: float | None = None

    def _sample(self, truth: TruthState, world: WorldView, rng: np.random.Generator) -> AirspeedSample:
        z = rng.standard_normal(2)
        if self._bias is None:
            self._bias = self.params.bias_pa * z[0]
        rho = truth.pressure_pa / (R_AIR * truth.temperature_k)
        q = 0.5 * rho * truth.airspeed_mps**2 + self._bias + self.params.noise_pa * z[1]
        return AirspeedSample(truth.t_s, math.sqrt(2.0 * max(q, 0.0) / rho))
