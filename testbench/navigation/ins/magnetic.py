"""The magnetic field model the vehicle carries onboard: WMM through pygeomag.

This is the navigator's own model of the Earth's field, not truth: the magnetometer sensor
samples whatever field the world defines, and any difference shows up as innovation.
"""

from __future__ import annotations

import math

import numpy as np
from pygeomag import GeoMag

from testbench.core.units import RAD_TO_DEG

_NT_TO_T = 1e-9


class OnboardMagneticModel:
    """WMM field in NED (tesla) with a cache: the field is re-evaluated only after the vehicle
    has moved more than `refresh_m` (the WMM varies over hundreds of kilometres)."""

    def __init__(self, epoch_year: float, refresh_m: float = 2000.0):
        # The WMM release current at the epoch (each one is valid for five years).
        base = 2025 if epoch_year >= 2025 else 2020 if epoch_year >= 2020 else 2015
        self._geomag = GeoMag(base_year=base)
        self._epoch = float(epoch_year)
        self._refresh_rad = refresh_m / 6.371e6
        self._key: tuple[float, float] | None = None
        self._field = np.zeros(3)

    def field_ned_T(self, lat_rad: float, lon_rad: float, h_m: float) -> np.ndarray:
        """Field (3,) in NED, tesla, at the geodetic position."""
        if self._key is None or max(abs(lat_rad - self._key[0]),
                                    abs(lon_rad - self._key[1]) * math.cos(lat_rad)) > self._refresh_rad:
            r = self._geomag.calculate(
                glat=lat_rad * RAD_TO_DEG,
                glon=math.remainder(lon_rad * RAD_TO_DEG, 360.0),
                alt=max(h_m, 0.0) / 1000.0,
                time=self._epoch,
                allow_date_outside_lifespan=True,
            )
            self._field = np.array([r.x, r.y, r.z]) * _NT_TO_T
            self._key = (lat_rad, lon_rad)
        return self._field
