"""How vehicles look to each other's cameras: shape, size, colour and LED markers.

Defaults per vehicle kind; a scenario may override them per vehicle (`appearance:`). The LED
layout matches what the relative-navigation aid expects (testbench.core.led_code): LED 0 is the
always-on anchor (green, on a mast above the body), the others show the current chip of the
vehicle's ID code (red).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from testbench.core import led_code
from testbench.sensors.camera.types import VehicleAppearance

ANCHOR_RGB = (40, 255, 40)
DATA_RGB = (255, 40, 40)

QUAD_LEDS_B_M = ((0.0, 0.0, -0.20), (0.165, 0.165, -0.03), (0.165, -0.165, -0.03), (-0.165, -0.165, -0.03), (-0.165, 0.165, -0.03))
FIXED_WING_LEDS_B_M = ((0.0, 0.0, -0.25), (0.0, 1.40, 0.0), (0.0, -1.40, 0.0), (-1.0, 0.0, -0.2), (0.9, 0.0, 0.0))


@dataclass(frozen=True)
class Look:
    """A vehicle's static appearance and its index in the LED code."""

    index: int
    shape: str
    size_m: float
    colour_rgb: tuple[int, int, int]
    led_positions_b_m: tuple[tuple[float, float, float], ...]
    led_rate_hz: float

    @property
    def led_colours(self) -> tuple[tuple[int, int, int], ...]:
        return (ANCHOR_RGB,) + (DATA_RGB,) * (len(self.led_positions_b_m) - 1)

    def appearance(self, vehicle_id: str, pos_ned_m: np.ndarray, R_nb: np.ndarray, t_s: float) -> VehicleAppearance:
        """The vehicle at t_s, its LEDs showing the chip of its ID code for this instant."""
        n = len(self.led_positions_b_m)
        on = led_code.led_states(self.index, led_code.frame_index(t_s, self.led_rate_hz), n) if n else ()
        return VehicleAppearance(
            vehicle_id, pos_ned_m, R_nb, self.shape, self.size_m, self.colour_rgb,
            self.led_positions_b_m, self.led_colours, tuple(on), 0.03,
        )


def default_look(index: int, kind: str, aircraft_meta: dict, colour_rgb: tuple[int, int, int], led_rate_hz: float) -> Look:
    """The look of vehicle number `index` of a kind ("multirotor" or "fixed_wing")."""
    if kind == "multirotor":
        return Look(index, "quad", 0.55, colour_rgb, QUAD_LEDS_B_M, led_rate_hz)
    span = float(aircraft_meta.get("span_m", 2.9))
    s = span / 2.9
    leds = tuple((x * s, y * s, z * s) for x, y, z in FIXED_WING_LEDS_B_M)
    return Look(index, "fixed_wing", span, colour_rgb, leds, led_rate_hz)
