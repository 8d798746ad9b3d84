"""The sun's direction (world/sun.py): the NED vector and the noon sun of a date and latitude."""

from __future__ import annotations

import numpy as np
import pytest

from testbench.world.sun import noon_sun_deg, solar_declination_deg, sun_ned


def test_the_vector_points_to_the_sun():
    v = sun_ned(90.0, 30.0)  # east, 30 deg up
    assert np.allclose(v, [0.0, np.cos(np.radians(30.0)), -0.5], atol=1e-12)
    assert np.isclose(np.linalg.norm(sun_ned(217.0, 61.0)), 1.0)
    with pytest.raises(ValueError, match="not above the horizon"):
        sun_ned(0.0, 0.0)


def test_the_declination_follows_the_seasons():
    # Solstices about 21 June (day 172) and 21 December (day 355), equinox about 20 March (day 79).
    assert solar_declination_deg(2025 + 171 / 365) == pytest.approx(23.44, abs=0.1)
    assert solar_declination_deg(2025 + 354 / 365) == pytest.approx(-23.44, abs=0.1)
    assert abs(solar_declination_deg(2025 + 80 / 365)) < 1.0


def test_the_noon_sun_stands_south_in_the_north_and_north_in_the_south():
    az, el = noon_sun_deg(47.0, 2025 + 171 / 365)  # North Dakota at midsummer
    assert az == 180.0 and el == pytest.approx(90.0 - 47.0 + 23.44, abs=0.2)
    az, el = noon_sun_deg(-33.9, 2025 + 171 / 365)  # Sydney in June: winter, the sun in the north
    assert az == 0.0 and el == pytest.approx(90.0 - 33.9 - 23.44, abs=0.2)
    with pytest.raises(ValueError, match="does not rise"):
        noon_sun_deg(80.0, 2025 + 354 / 365)  # polar night
