"""What every sensor model shares: rate checks and the once-per-sample-time cache."""

from __future__ import annotations

import abc
import math
from typing import Any

import numpy as np

from testbench.core.errors import InputError
from testbench.core.interfaces import BuildContext, Sensor, WorldView
from testbench.core.messages import TruthState


def check_rate(rate_hz: float, ctx: BuildContext, where: str) -> float:
    """Validate that `rate_hz` divides the physics rate; returns it as a float."""
    rate = float(rate_hz)
    ratio = ctx.physics_rate_hz / rate
    if rate <= 0 or abs(ratio - round(ratio)) > 1e-9 * max(1.0, ratio) or round(ratio) < 1:
        raise InputError(
            f"{where}.rate_hz: {rate:g} Hz must divide the physics rate {ctx.physics_rate_hz:g} Hz"
        )
    return rate


class CachedSensor(Sensor):
    """A Sensor whose noise state advances only in `_sample`, once per sample time.

    `measure` returns the cached message when asked again for the same truth.t_s, so that a
    second caller (recorder, scorer) never walks a bias twice.
    """

    name: str = "sensor"
    rate_hz: float = 1.0

    def __init__(self) -> None:
        self._last_t_s = -math.inf
        self._last_msg: Any = None

    def measure(self, truth: TruthState, world: WorldView, rng: np.random.Generator) -> Any | None:
        if truth.t_s == self._last_t_s:
            return self._last_msg
        msg = self._sample(truth, world, rng)
        self._last_t_s = truth.t_s
        self._last_msg = msg
        return msg

    @abc.abstractmethod
    def _sample(self, truth: TruthState, world: WorldView, rng: np.random.Generator) -> Any | None:
        """Draw the measurement at truth.t_s (advances the noise state by one sample)."""
