"""world.map_error (DisplacedMap, MapDisplacement): a carried map off its georeference shows the
ground displaced by the field it is given (a shift exactly, a random field pixel by pixel), the
field has its sigma and is the same for the same seed, and a read through the scene matcher's
window cache is the same."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

from testbench.world.georef import local_tmerc_crs
from testbench.world.imagery import MapSource
from testbench.world.map_error import DisplacedMap, MapDisplacement
from testbench.world.raster import sample_bilinear


@pytest.fixture
def smooth_map(tmp_path, origin):
    """A 1 m GeoTIFF, 1200 x 1200 px about the origin, in the origin's transverse Mercator
    (x = east, y = north): smooth bands of texture, so that bilinear samples are near exact."""
    n = 1200
    yy, xx = np.mgrid[0:n, 0:n].astype(float)
    r = 128 + 90 * np.sin(xx / 17.0) * np.cos(yy / 29.0)
    g = 128 + 90 * np.cos((xx + yy) / 41.0)
    b = 128 + 60 * np.sin(yy / 13.0)
    data = np.clip(np.stack([r, g, b]), 0, 255).astype(np.uint8)
    path = tmp_path / "smooth.tif"
    with rasterio.open(path, "w", driver="GTiff", width=n, height=n, count=3, dtype="uint8",
                       crs=local_tmerc_crs(origin).to_wkt(), transform=from_origin(-600.0, 600.0, 1.0, 1.0)) as dst:
        dst.write(data)
    return MapSource(str(path), origin)


def test_a_shifted_map_shows_the_ground_shift_further_on(smooth_map):
    """Ground truly at g appears at g + shift: the displaced map's window is the true map's
    window shift back, to a grey level (the remap's fixed-point weights)."""
    carried = DisplacedMap(smooth_map, MapDisplacement((6.0, -3.0), 0.0, 1000.0, None, np.random.default_rng(0)))
    got = carried.read_local(-200.0, 200.0, -150.0, 250.0, 1.0, memoise=False)
    want = smooth_map.read_local(-206.0, 194.0, -147.0, 253.0, 1.0, memoise=False)
    assert got.shape == want.shape == (400, 400) and got.valid.all()
    assert (got.north0_m, got.east0_m) == (200.0, -150.0)
    assert np.abs(got.data.astype(int) - want.data.astype(int)).max() <= 1
    # Not the map read as it lies: the same window without the shift differs.
    plain = smooth_map.read_local(-200.0, 200.0, -150.0, 250.0, 1.0, memoise=False)
    assert np.abs(plain.data.astype(int) - got.data.astype(int)).mean() > 5


def test_a_random_field_displaces_each_pixel_by_its_own_value(smooth_map):
    """The carried map at x is the true map at x - d(x), pixel by pixel, where d varies over the
    window by metres (the field is evaluated every few pixels and interpolated between)."""
    disp = MapDisplacement((0.0, 0.0), 4.0, 250.0, (-800.0, 800.0, -800.0, 800.0), np.random.default_rng(5))
    carried = DisplacedMap(smooth_map, disp)
    r = carried.read_local(-300.0, 300.0, -300.0, 300.0, 1.0, memoise=False)
    rng = np.random.default_rng(1)
    rows, cols = rng.integers(0, 600, 200), rng.integers(0, 600, 200)
    north, east = r.rowcol_to_ne(rows, cols)
    d_n, d_e = disp.at(north, east)
    assert np.ptp(d_n) > 4.0 and np.ptp(d_e) > 4.0
    want, ok = sample_bilinear(smooth_map.read_local(-400.0, 400.0, -400.0, 400.0, 1.0, memoise=False),
                               north - d_n, east - d_e)
    assert ok.all()
    assert np.abs(r.data[rows, cols].astype(float) - want).max() <= 2.0


def test_the_field_has_its_sigma_and_its_seed():
    bounds = (-6000.0, 6000.0, -6000.0, 6000.0)
    a = MapDisplacement((1.0, -2.0), 2.5, 1500.0, bounds, np.random.default_rng(3))
    pts = np.random.default_rng(0).uniform(-5000.0, 5000.0, (2, 20000))
    d_n, d_e = a.at(*pts)
    assert abs(np.mean(d_n) - 1.0) < 1.0 and abs(np.mean(d_e) + 2.0) < 1.0  # the shift, plus the field's own mean
    assert 2.0 < np.std(d_n) < 3.0 and 2.0 < np.std(d_e) < 3.0
    assert np.corrcoef(d_n, d_e)[0, 1] ** 2 < 0.1  # two fields, not one
    assert a.max_abs_m >= max(np.abs(d_n).max(), np.abs(d_e).max())
    b = MapDisplacement((1.0, -2.0), 2.5, 1500.0, bounds, np.random.default_rng(3))
    np.testing.assert_array_equal(b.at(*pts)[0], d_n)
    assert a.key == b.key
    assert MapDisplacement((1.0, -2.0), 2.5, 1500.0, bounds, np.random.default_rng(4)).key != a.key


def test_the_scene_matchers_cache_serves_the_displaced_map(smooth_map):
    """MapWindowCache reads through the wrapper (and memoises under its own key, never the
    true map's)."""
    from testbench.navigation.ismn.mapcache import MapWindowCache

    carried = DisplacedMap(smooth_map, MapDisplacement((5.0, 0.0), 0.0, 1000.0, None, np.random.default_rng(0)))
    assert carried.memo_key(-1.0, 1.0, -1.0, 1.0, 1.0) != smooth_map.memo_key(-1.0, 1.0, -1.0, 1.0, 1.0)
    crop = MapWindowCache(carried).read(-100.0, 100.0, -100.0, 100.0, 1.0)
    true = MapWindowCache(smooth_map).read(-105.0, 95.0, -100.0, 100.0, 1.0)
    n, e = crop.rowcol_to_ne(np.array([50, 120]), np.array([60, 130]))
    a, _ = sample_bilinear(crop, n, e)
    b, _ = sample_bilinear(true, n - 5.0, e)
    assert np.abs(a - b).max() <= 1.0
