"""Wind and turbulence through JSBSim's own air mass (JSBSimDynamics with an AirMass)."""

from __future__ import annotations

import math

import numpy as np
import pydantic
import pytest

from testbench.config.schema import Wind
from testbench.core.interfaces import GeodeticOrigin
from testbench.core.messages import RotorCommand
from testbench.dynamics.catalog import aircraft_meta
from testbench.dynamics.jsbsim_adapter import AirMass, InitialCondition, JSBSimDynamics

ORIGIN = GeodeticOrigin(math.radians(47.0), math.radians(-99.0), 500.0)
WESTERLY_6 = (0.0, 6.0, 0.0)  # 6 m/s from 270 deg: the air moves east


def test_wind_from_is_meteorological():
    np.testing.assert_allclose(Wind(speed_mps=6.0, from_deg=270.0).velocity_ned_mps(), WESTERLY_6, atol=1e-12)
    np.testing.assert_allclose(Wind(speed_mps=5.0, from_deg=0.0).velocity_ned_mps(), (-5.0, 0.0, 0.0), atol=1e-12)
    for bad in ({"speed_mps": 6.0, "from_deg": 360.0}, {"speed_mps": -1.0, "from_deg": 0.0},
                {"speed_mps": 6.0, "from_deg": 10.0, "gust_mps": 2.0},
                {"speed_mps": 6.0, "from_deg": 10.0, "turbulence": {"severity": "strong"}}):
        with pytest.raises(pydantic.ValidationError):
            Wind(**bad)


def test_fixed_wing_starts_through_the_air_along_its_heading():
    """Heading north at 25 m/s through a westerly: no sideslip, the ground velocity adds the
    wind, and the trimmed wing keeps it (a crab: heading north, track east of north)."""
    dyn = JSBSimDynamics("tb_fixedwing", ORIGIN, 120.0, air=AirMass(wind_ned_mps=WESTERLY_6))
    truth = dyn.reset(InitialCondition(pos_ned_m=(0.0, 0.0, -300.0), heading_rad=0.0, airspeed_mps=25.0))
    np.testing.assert_allclose(truth.wind_ned_mps, WESTERLY_6, atol=1e-9)
    np.testing.assert_allclose(truth.vel_ned_mps[:2], (25.0, 6.0), atol=0.05)
    assert truth.airspeed_mps == pytest.approx(25.0, abs=0.05)
    assert abs(dyn.fdm["aero/beta-deg"]) < 0.05
    dyn.advance(None, 240)  # 2 s with the trim's commands
    truth = dyn.truth()
    air_velocity = truth.vel_ned_mps - truth.wind_ned_mps
    assert np.linalg.norm(air_velocity) == pytest.approx(truth.airspeed_mps, abs=1e-3)
    assert truth.vel_ned_mps[1] == pytest.approx(6.0, abs=0.3)


def test_multirotor_starts_trimmed_into_the_wind():
    """A multirotor's initial velocity is over the ground: at 0 it hovers with the wind for
    airspeed, tilted against the rotors' drag (c sum(omega) v_air, ~0.36 m/s^2 per m/s) so
    that it stays put with its start command."""
    dyn = JSBSimDynamics("tb_quad", ORIGIN, 200.0, air=AirMass(wind_ned_mps=WESTERLY_6))
    truth = dyn.reset(InitialCondition(pos_ned_m=(0.0, 0.0, -100.0), heading_rad=0.0, airspeed_mps=0.0))
    np.testing.assert_allclose(truth.vel_ned_mps, 0.0, atol=1e-9)
    assert truth.airspeed_mps == pytest.approx(6.0, abs=1e-6)
    # Heading north, the air moving east: the thrust leans west, a roll to the left of
    # atan(2.2 / 9.8) ~ 12 deg.
    assert math.degrees(truth.rpy_rad[0]) == pytest.approx(-12.4, abs=0.5)
    assert abs(truth.rpy_rad[1]) < 1e-3
    dyn.advance(None, 400)  # 2 s on the start command
    v = dyn.truth().vel_ned_mps
    assert np.hypot(v[0], v[1]) < 0.1  # untrimmed (level, hover command): 1.8 m/s^2 downwind


@pytest.mark.parametrize("air", [None, AirMass(wind_ned_mps=WESTERLY_6)], ids=["calm", "wind"])
def test_multirotor_motors_start_at_the_start_command(air):
    """The motors' lag starts at the start command, so the rotors hold the quad from the very
    first physics step: thrust against weight (specific force ~ -g along body z) and, in wind,
    the full trimmed rotor drag. Before, the command was written after run_ic, the lag started
    at zero thrust, and the quad fell freely for its first 50 ms."""
    dyn = JSBSimDynamics("tb_quad", ORIGIN, 200.0, air=air)
    dyn.reset(InitialCondition(pos_ned_m=(0.0, 0.0, -100.0), heading_rad=0.0, airspeed_mps=0.0))
    f_first = []
    for _ in range(4):  # the first 20 ms
        dyn.advance(None, 1)
        f_first.append(dyn.truth().f_b_mps2)
    f_first = np.array(f_first)
    assert f_first[:, 2].max() < -9.0  # measured -9.6 to -9.8 (before: 0 at 5 ms, -4.5 at 20 ms)
    if air is not None:  # 2.2 m/s^2 of drag to the east in 6 m/s, in the rolled body's y
        assert np.hypot(f_first[:, 0], f_first[:, 1]).min() > 2.0


def test_calm_air_reports_no_wind():
    dyn = JSBSimDynamics("tb_quad", ORIGIN, 200.0)
    truth = dyn.reset(InitialCondition(pos_ned_m=(0.0, 0.0, -100.0)))
    assert not truth.wind_ned_mps.any() and not truth.wind_ned_mps.flags.writeable


def _turbulent_wind(seed: int, seconds: float = 20.0) -> np.ndarray:
    air = AirMass(wind_ned_mps=WESTERLY_6, turbulence_type=3, severity_index=3, windspeed_at_20ft_mps=6.0, seed=seed)
    dyn = JSBSimDynamics("tb_fixedwing", ORIGIN, 120.0, air=air)
    # High enough that the untended wing (trim commands held) never meets the ground.
    dyn.reset(InitialCondition(pos_ned_m=(0.0, 0.0, -2000.0), heading_rad=0.0, airspeed_mps=25.0))
    out = []
    for _ in range(int(seconds * 10)):
        dyn.advance(None, 12)
        out.append(dyn.truth().wind_ned_mps)
    return np.array(out)


def test_turbulence_is_seeded_and_of_the_milspec_size():
    a, b, c = _turbulent_wind(7), _turbulent_wind(7), _turbulent_wind(8)
    assert np.array_equal(a, b)  # the same seed: bit-identical gusts
    assert not np.allclose(a, c)
    gust = a - np.array(WESTERLY_6)
    # Light turbulence above 2000 ft (MIL-F-8785C fig. 7, probability of exceedance 1e-2):
    # sigma 2.3 m/s per axis at 2500 m above sea level, scale length 533 m; 20 s at 25 m/s is
    # one scale length, so only the order of magnitude is tested.
    rms = np.sqrt((gust**2).mean(axis=0))
    assert np.all(rms > 0.1) and np.all(rms < 5.0)
