"""The truth pass-through navigator: for control studies without navigation error.

It never reads truth directly: it consumes `StateObservation` messages from the `ideal_state`
sensor (a perfect full-state sensor), so the data flow stays truth -> sensor -> navigator ->
controller like every other navigator. Covariances are zero.
"""

from __future__ import annotations

import numpy as np

from testbench.core.interfaces import BuildContext, Navigator
from testbench.core.messages import CorrectionInfo, NavEstimate, StateObservation
from testbench.core.registry import ParamsModel, register

_ZERO3 = np.zeros((3, 3))
_ZERO3.setflags(write=False)


@register("navigator", "truth_passthrough")
class TruthPassThrough(Navigator):
    """Estimate = the latest ideal state observation (needs an `ideal_state` sensor)."""

    class Params(ParamsModel):
        pass

    def __init__(self, params: Params | None = None, *, ctx: BuildContext | None = None, **_: object):
        self._est: NavEstimate | None = None

    def initialize(self, t_s: float, initial: NavEstimate) -> None:
        self._est = initial

    def predict(self, imu) -> None:  # no propagation: the next observation replaces the state
        return None

    def correct(self, measurement) -> CorrectionInfo | None:
        if not isinstance(measurement, StateObservation):
            return None
        tr = measurement.truth
        self._est = NavEstimate(
            t_s=tr.t_s,
            pos_ned_m=tr.pos_ned_m,
            vel_ned_mps=tr.vel_ned_mps,
            q_nb_wxyz=tr.q_nb_wxyz,
            rpy_rad=tr.rpy_rad,
            omega_b_rps=tr.omega_eb_b_rps,
            cov_pos_ned_m2=_ZERO3,
            cov_vel_ned_m2s2=_ZERO3,
            cov_att_rad2=_ZERO3,
            airspeed_mps=tr.airspeed_mps,
        )
        return None

    def estimate(self) -> NavEstimate:
        if self._est is None:
            raise RuntimeError("TruthPassThrough.estimate() before initialize() or any observation")
        return self._est
