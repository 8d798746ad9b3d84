"""Radar altimeter: the range to the nearest ground inside a downward beam, over the truth
terrain (world.elevation; flat ground at the origin altitude without one).

    r_meas = r_first_return(true pose, terrain) + b0 + n,  n ~ N(0, noise_m^2 + (noise_fraction r)^2)

r_first_return: core.radar_beam over the world's terrain, the antenna at lever_arm_b_m; b0 a
turn-on bias (1 sigma bias_m); no return beyond max_range_m (the sensor then reports nothing).
Defaults are of the order of a light-aircraft or UAV FMCW radar altimeter: a 20 deg beam
half angle (the usual 40 deg two-way beamwidth), 0.3 m + 0.5 % of range, 1500 m.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from testbench.core.interfaces import BuildContext, WorldView
from testbench.core.messages import RadarAltSample, TruthState
from testbench.core.radar_beam import beam_rays_b, first_return_m
from testbench.core.registry import ParamsModel, register
from testbench.core.rotations import quat_to_dcm
from testbench.sensors.base import CachedSensor, check_rate


class RadarAltimeterParams(ParamsModel):
    """rate_hz; beam_half_angle_deg (0: a pencil beam along the body's z axis); noise_m and
    noise_fraction (1 sigma: constant part, m, and part proportional to range); bias_m (1 sigma
    turn-on bias, m); max_range_m (no return beyond); lever_arm_b_m (antenna in body FRD, m)."""

    rate_hz: float = Field(10.0, gt=0)
    beam_half_angle_deg: float = Field(20.0, ge=0, lt=80)
    noise_m: float = Field(0.3, ge=0)
    noise_fraction: float = Field(0.005, ge=0)
    bias_m: float = Field(0.0, ge=0)
    max_range_m: float = Field(1500.0, gt=0)
    lever_arm_b_m: tuple[float, float, float] = (0.0, 0.0, 0.0)


@register("sensor", "radar_altimeter")
class RadarAltimeter(CachedSensor):
    """Returns RadarAltSample (range to the nearest ground in the beam, m), or None with no
    ground within max_range_m."""

    Params = RadarAltimeterParams

    def __init__(self, params: RadarAltimeterParams, *, ctx: BuildContext):
        super().__init__()
        self.params = params
        self.name = "radar_altimeter"
        self.rate_hz = check_rate(params.rate_hz, ctx, "radar_altimeter")
        self.beam_half_angle_rad = math.radians(params.beam_half_angle_deg)
        self.rays_b = beam_rays_b(self.beam_half_angle_rad)
        self._lever_b = np.asarray(params.lever_arm_b_m, float)
        self._bias: float | None = None

    def _sample(self, truth: TruthState, world: WorldView, rng: np.random.Generator) -> RadarAltSample | None:
        p = self.params
        z = rng.standard_normal(2)  # drawn every sample, so that a lost return shifts no later draw
        if self._bias is None:
            self._bias = p.bias_m * float(z[0])
        R_nb = quat_to_dcm(truth.q_nb_wxyz)
        antenna = np.asarray(truth.pos_ned_m, float) + R_nb @ self._lever_b
        r = float(first_return_m(antenna, R_nb, self.rays_b, world.terrain_height_m))
        if not r <= p.max_range_m:  # beyond range, or no ground in the beam (inf)
            return None
        sigma = math.hypot(p.noise_m, p.noise_fraction * r)
        return RadarAltSample(truth.t_s, r + self._bias + sigma * float(z[1]), self.beam_half_angle_rad)
