"""Where the sun stands: a direction in the local NED frame, for the clouds' shadows.

A procedural world is lit by its season's sun (world/procedural/appearance.py, or the sun its
spec gives), so its clouds' shadows fall the way its own shadows do. A real map carries its
acquisition's shadows but no sun; there the sun is the one at local solar noon on the
scenario's date (aerial surveys such as NAIP fly around midday), with the declination of the
day from Cooper's formula:

    delta = 23.44 deg * sin(2 pi (284 + N) / 365),   N the day of the year (1-365),
    elevation = 90 deg - |latitude - delta|, azimuth 180 deg where the sun culminates south of
    the zenith (latitude > delta), else 0 deg.

Cooper's declination errs by up to about 1 deg, which moves a shadow cast from 300 m by a few
metres: well under the size of a cloud.
"""

from __future__ import annotations

import math

import numpy as np


def sun_ned(azimuth_deg: float, elevation_deg: float) -> np.ndarray:
    """(3,) unit vector toward the sun in NED: azimuth from north, clockwise (east 90 deg);
    elevation above the horizon (deg, > 0)."""
    if not 0.0 < elevation_deg <= 90.0:
        raise ValueError(f"sun elevation {elevation_deg:g} deg is not above the horizon (expected (0, 90] deg)")
    az, el = math.radians(azimuth_deg), math.radians(elevation_deg)
    return np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), -math.sin(el)])


def solar_declination_deg(epoch_year: float) -> float:
    """The sun's declination (deg) on the day of a decimal year (Cooper 1969)."""
    day = int((epoch_year % 1.0) * 365.0) + 1  # 1-365
    return 23.44 * math.sin(2.0 * math.pi * (284 + day) / 365.0)


def noon_sun_deg(lat_deg: float, epoch_year: float) -> tuple[float, float]:
    """(azimuth_deg, elevation_deg) of the sun at local solar noon at latitude lat_deg on the
    day of epoch_year. Raises ValueError where the sun does not rise (polar night)."""
    delta = solar_declination_deg(epoch_year)
    elevation = 90.0 - abs(lat_deg - delta)
    if elevation <= 0.0:
        raise ValueError(f"the sun does not rise at latitude {lat_deg:g} deg on {epoch_year:.3f} (decimal year; "
                         f"noon elevation {elevation:.1f} deg): give world.clouds.sun_azimuth_deg and "
                         f"sun_elevation_deg, or shadow_light: 1 for no shadows")
    return (180.0 if lat_deg > delta else 0.0), elevation
