"""The ideal full-state sensor: hands the truth to the truth pass-through navigator
(control studies without navigation error)."""

from __future__ import annotations

import numpy as np
from pydantic import Field

from testbench.core.interfaces import BuildContext, WorldView
from testbench.core.messages import StateObservation, TruthState
from testbench.core.registry import ParamsModel, register
from testbench.sensors.base import CachedSensor, check_rate


class IdealStateParams(ParamsModel):
    rate_hz: float = Field(100.0, gt=0)


@register("sensor", "ideal_state")
class IdealState(CachedSensor):
    """Returns StateObservation(t_s, truth); draws no random numbers."""

    Params = IdealStateParams

    def __init__(self, params: IdealStateParams, *, ctx: BuildContext):
        super().__init__()
        self.name = "ideal_state"
        self.rate_hz = check_rate(params.rate_hz, ctx, "ideal_state")

    def _sample(self, truth: TruthState, world: WorldView, rng: np.random.Generator) -> StateObservation:
        return StateObservation(truth.t_s, truth)
