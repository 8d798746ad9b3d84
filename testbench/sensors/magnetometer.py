"""3-axis magnetometer: the world's magnetic field at the vehicle, rotated into body axes,
with hard-iron offset, soft-iron matrix, white noise and quantisation.

    B_b = S (R_nb^T B_ned) + h + n,   n ~ N(0, sigma^2 I)   (tesla)

B_ned = (X north, Y east, Z down) is the world's field (world/magnetic.py): pygeomag's WMM
(coefficients chosen by the scenario epoch) at the truth latitude, longitude and altitude, plus
the crust's anomaly where the scenario gives one (`world.magnetic_anomaly`). The WMM varies by
a few nT per km, so it is re-evaluated only after the vehicle has moved
`field_update_distance_m`; the anomaly, which varies over hundreds of metres, at every sample.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from testbench.core.interfaces import BuildContext, WorldView
from testbench.core.messages import MagSample, TruthState
from testbench.core.registry import ParamsModel, register
from testbench.core.rotations import quat_to_dcm
from testbench.sensors.base import CachedSensor, check_rate
from testbench.world.magnetic import NT_TO_T, wmm_field_ned_nT


class MagnetometerParams(ParamsModel):
    """noise_nT: 1-sigma white noise per axis; hard_iron_nT (3,): body-fixed offset;
    soft_iron: 3x3 matrix as 9 numbers (row-major), identity by default; lsb_nT: quantisation
    step (0 = none); field_update_distance_m: WMM re-evaluation distance."""

    rate_hz: float = Field(50.0, gt=0)
    noise_nT: float = Field(100.0, ge=0)
    hard_iron_nT: tuple[float, float, float] = (0.0, 0.0, 0.0)
    soft_iron: tuple[float, ...] = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    lsb_nT: float = Field(0.0, ge=0)
    field_update_distance_m: float = Field(100.0, ge=0)


@register("sensor", "magnetometer")
class Magnetometer(CachedSensor):
    """Returns MagSample (field_b_T, tesla, body FRD)."""

    Params = MagnetometerParams

    def __init__(self, params: MagnetometerParams, *, ctx: BuildContext):
        super().__init__()
        if len(params.soft_iron) != 9:
            from testbench.core.errors import InputError

            raise InputError("magnetometer.soft_iron: expected 9 numbers (3x3 row-major)")
        self.params = params
        self.name = "magnetometer"
        self.rate_hz = check_rate(params.rate_hz, ctx, "magnetometer")
        self.year = float(ctx.epoch_utc_year)
        self.soft_iron = np.asarray(params.soft_iron, float).reshape(3, 3)
        self.hard_iron_T = np.asarray(params.hard_iron_nT, float) * NT_TO_T
        self._field_ned_T: np.ndarray | None = None
        self._field_at_ned_m = np.zeros(3)

    def field_ned_T(self, truth: TruthState) -> np.ndarray:
        """WMM main field at the truth position (tesla, NED), cached over short moves."""
        pos = np.asarray(truth.pos_ned_m, float)
        if self._field_ned_T is None or np.linalg.norm(pos - self._field_at_ned_m) > self.params.field_update_distance_m:
            b = wmm_field_ned_nT(np.rad2deg(truth.lat_rad), np.rad2deg(truth.lon_rad), truth.alt_m, self.year)
            self._field_ned_T = b * NT_TO_T
            self._field_at_ned_m = pos.copy()
        return self._field_ned_T

    def _sample(self, truth: TruthState, world: WorldView, rng: np.random.Generator) -> MagSample:
        b_ned = self.field_ned_T(truth)
        anomaly = world.magnetic_anomaly_ned_T(truth)
        if anomaly is not None:
            b_ned = b_ned + anomaly
        b_b = quat_to_dcm(truth.q_nb_wxyz).T @ b_ned  # NED -> body: R_bn = R_nb^T
        b = self.soft_iron @ b_b + self.hard_iron_T + self.params.noise_nT * NT_TO_T * rng.standard_normal(3)
        if self.params.lsb_nT > 0:
            lsb = self.params.lsb_nT * NT_TO_T
            b = np.round(b / lsb) * lsb
        return MagSample(truth.t_s, b)
