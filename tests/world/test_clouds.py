"""The cloud layer's field (world/clouds.py): its coverage, its drift, its windows, its seed,
and the scenario keys that make it."""

from __future__ import annotations

import numpy as np
import pydantic
import pytest

from testbench.config.schema import Clouds
from testbench.world.clouds import CloudLayer, CoverageWindow


def _layer(coverage=0.4, windows=(), drift=(0.0, 0.0), seed=3, cell_m=300.0):
    return CloudLayer(500.0, coverage, windows, cell_m, 1.0, drift, np.random.default_rng(seed))


def _tile_grid(layer, step_m=4.0):
    """North / east grids over one period of the field (9.6 km for 300 m cells)."""
    period = 512 * layer.px_m
    n, e = np.meshgrid(np.arange(0.0, period, step_m), np.arange(0.0, period, step_m), indexing="ij")
    return n, e


@pytest.mark.parametrize("coverage", [0.1, 0.4, 0.8])
def test_the_share_of_sky_under_cloud_is_the_coverage(coverage):
    layer = _layer(coverage)
    d = layer.at(0.0).density(*_tile_grid(layer))
    # (to about 1 %: interpolating the field between its samples rounds its peaks)
    assert abs(float(np.mean(d >= 0.5)) - coverage) < 0.02
    # Sharp-edged clouds: most of the sky is clear or opaque, not haze.
    assert float(np.mean((d > 0.02) & (d < 0.98))) < 0.15


def test_clear_and_overcast_are_exact():
    n, e = np.array([0.0, 1234.5, -9e4]), np.array([7.0, -55.0, 3e5])
    assert not _layer(0.0).at(0.0).density(n, e).any() and _layer(0.0).at(0.0).clear
    assert np.all(_layer(1.0).at(0.0).density(n, e) == 1.0)


def test_the_field_repeats_at_its_period_and_holds_its_detail_far_out():
    layer = _layer()
    view = layer.at(0.0)
    period = 512 * layer.px_m
    n = np.linspace(0.0, 3000.0, 301)
    e = np.full_like(n, 40.0)
    near = view.density(n, e)
    assert np.allclose(view.density(n + 40 * period, e - 25 * period), near, atol=1e-4)
    assert 0.0 < near.mean() < 1.0 and np.ptp(near) == 1.0
    # Any number of points (OpenCV's maps stop at 32767 a side), any shape, the same values.
    many = np.linspace(0.0, 3000.0, 70001)
    assert np.array_equal(view.density(many, np.full_like(many, 40.0))[::233], view.density(many[::233], np.full(301, 40.0)))
    assert view.density(np.array(5.0), np.array(6.0)).shape == ()


def test_the_clouds_move_with_their_drift():
    layer = _layer(drift=(3.0, -4.0))
    n, e = np.linspace(-500.0, 500.0, 201), np.linspace(200.0, -300.0, 201)
    t = 37.5
    assert np.allclose(layer.at(t).density(n + 3.0 * t, e - 4.0 * t), layer.at(0.0).density(n, e), atol=1e-4)
    assert not np.allclose(layer.at(t).density(n, e), layer.at(0.0).density(n, e), atol=0.05)


def test_windows_set_the_coverage_for_their_time():
    layer = _layer(0.3, windows=[CoverageWindow(100.0, 200.0, 1.0), CoverageWindow(200.0, 250.0, 0.0)])
    assert [layer.coverage_at(t) for t in (99.9, 100.0, 199.9, 200.0, 249.9, 250.0)] == [0.3, 1.0, 1.0, 0.0, 0.0, 0.3]


def test_one_seed_one_field_another_seed_another():
    n, e = _tile_grid(_layer(), step_m=97.0)
    a, b, c = (_layer(seed=s).at(0.0).density(n, e) for s in (5, 5, 6))
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_the_sheet_hides_what_lies_across_it_where_it_is_cloud():
    view = _layer(1.0).at(0.0)
    above, below, also_above = np.array([0.0, 0.0, -800.0]), np.array([50.0, 0.0, -100.0]), np.array([90.0, 0.0, -600.0])
    assert view.hides(above, below) and view.hides(below, above)
    assert not view.hides(above, also_above)  # both above the sheet (down -500 m)
    assert np.allclose(view.crossing_ne(above, below), [50.0 * 300.0 / 700.0, 0.0])
    assert not _layer(0.0).at(0.0).hides(above, below)


def test_the_scenario_keys_refuse_what_they_cannot_mean():
    ok = Clouds(base_m=500.0, coverage=0.3, windows=[{"start_s": 10, "end_s": 20, "coverage": 1.0}])
    assert ok.windows[0].coverage == 1.0 and ok.drift_ne_mps is None
    with pytest.raises(pydantic.ValidationError, match="windows overlap"):
        Clouds(base_m=500.0, windows=[{"start_s": 10, "end_s": 30, "coverage": 1.0}, {"start_s": 20, "coverage": 0.0}])
    with pytest.raises(pydantic.ValidationError, match="not after start_s"):
        Clouds(base_m=500.0, windows=[{"start_s": 30, "end_s": 10, "coverage": 1.0}])
    with pytest.raises(pydantic.ValidationError):
        Clouds(base_m=500.0, coverage=1.5)
    with pytest.raises(pydantic.ValidationError, match="extra"):
        Clouds(base_m=500.0, thickness_m=100.0)
    with pytest.raises(pydantic.ValidationError, match="both sun_azimuth_deg and sun_elevation_deg"):
        Clouds(base_m=500.0, sun_azimuth_deg=120.0)
    with pytest.raises(pydantic.ValidationError):
        Clouds(base_m=500.0, sun_azimuth_deg=120.0, sun_elevation_deg=-5.0)  # below the horizon
    with pytest.raises(pydantic.ValidationError):
        Clouds(base_m=500.0, shadow_light=1.2)


def _sunlit(coverage, sun=(0.5, 0.3, -0.8), light=0.3, seed=3):
    return CloudLayer(500.0, coverage, (), 300.0, 1.0, (0.0, 0.0), np.random.default_rng(seed),
                      sun_ned=sun, shadow_light=light)


def test_a_shadow_falls_where_the_ray_to_the_sun_crosses_a_cloud():
    layer = _sunlit(0.4)
    view = layer.at(0.0)
    rng = np.random.default_rng(1)
    n, e = rng.uniform(-3000, 3000, 400), rng.uniform(-3000, 3000, 400)
    down = rng.uniform(-100.0, 50.0, 400)  # relief: ground 100 m up to 50 m down
    s = layer.sun_ned
    lam = (-500.0 - down) / s[2]
    expected = 0.3 + 0.7 * (1.0 - view.alpha(n + lam * s[0], e + lam * s[1]))
    light = view.ground_light(n, e, down)
    assert np.allclose(light, expected, atol=1e-6)
    # The shadow is not the cloud right above (the sun is not at the zenith).
    above = 0.3 + 0.7 * (1.0 - view.alpha(n, e))
    assert np.mean(np.abs(light - above) > 0.5) > 0.1
    assert np.all((light >= 0.3 - 1e-6) & (light <= 1.0)) and np.mean(np.isclose(light, 0.3)) > 0.2


def test_no_shadow_without_a_sun_or_clouds_or_above_the_sheet():
    n, e = np.linspace(-2000, 2000, 50), np.zeros(50)
    assert np.all(_layer(1.0).at(0.0).ground_light(n, e, np.zeros(50)) == 1.0)  # no sun
    assert np.all(_sunlit(0.0).at(0.0).ground_light(n, e, np.zeros(50)) == 1.0)  # clear sky
    overcast = _sunlit(1.0).at(0.0)
    assert np.allclose(overcast.ground_light(n, e, np.zeros(50)), 0.3)  # the skylight alone
    assert np.all(overcast.ground_light(n, e, np.full(50, -600.0)) == 1.0)  # a summit above the sheet
    assert _sunlit(0.5, light=1.0).sun_ned is None  # shadow_light 1: no shadows at all
    with pytest.raises(ValueError, match="above the horizon"):
        _sunlit(0.5, sun=(1.0, 0.0, 0.2))


def test_the_run_lights_its_clouds_with_the_worlds_sun():
    """A procedural imagery's clouds cast their shadows from the season's own sun, a real map's
    from the noon sun of the scenario's date; the scenario's sun overrides both."""
    import math

    from testbench.config.schema import World
    from testbench.core.errors import InputError
    from testbench.core.interfaces import GeodeticOrigin
    from testbench.core.rng import RngStreams
    from testbench.sensors.fakes import ORIGIN
    from testbench.sim.world_runtime import RunWorld
    from testbench.world.procedural import season_from
    from testbench.world.sun import noon_sun_deg, sun_ned

    def layer(imagery, epoch_year=2025.5, **clouds):
        world = World(origin={"lat_deg": math.degrees(ORIGIN.lat_rad), "lon_deg": 7.0, "alt_m": 300.0},
                      imagery=imagery, clouds=Clouds(base_m=500.0, **clouds))
        return RunWorld(world, ORIGIN, streams=RngStreams(1), epoch_year=epoch_year).cloud_layer()

    summer = season_from("summer")
    expected = sun_ned(math.degrees(summer.sun_azimuth_rad), math.degrees(summer.sun_elevation_rad))
    assert np.allclose(layer("procedural:farmland?seed=7&season=summer").sun_ned, expected)
    noon = noon_sun_deg(math.degrees(ORIGIN.lat_rad), 2025.5)
    assert np.allclose(layer("/maps/naip_2018.tif").sun_ned, sun_ned(*noon))  # not opened: no file needed
    assert np.allclose(layer("/maps/naip_2018.tif", sun_azimuth_deg=250.0, sun_elevation_deg=30.0).sun_ned,
                       sun_ned(250.0, 30.0))
    assert layer("/maps/naip_2018.tif", shadow_light=1.0).sun_ned is None
    polar = GeodeticOrigin(math.radians(80.0), math.radians(7.0), 0.0)
    world = World(origin={"lat_deg": 80.0, "lon_deg": 7.0, "alt_m": 0.0}, imagery="/maps/svalbard.tif",
                  clouds=Clouds(base_m=500.0))
    with pytest.raises(InputError, match="does not rise.*sun_elevation_deg"):
        RunWorld(world, polar, streams=RngStreams(1), epoch_year=2025.97).cloud_layer()  # December
