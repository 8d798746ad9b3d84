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
