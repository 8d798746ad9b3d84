"""world.dem_error: the onboard DEM's error field has the RMS and patch size it is given, is the
same for the same seed, and reads the same through every access path."""

from __future__ import annotations

import numpy as np

from testbench.world.dem_error import DemErrorField, ErroredElevation
from testbench.world.elevation import FlatElevation

BOUNDS = (-5000.0, 5000.0, -5000.0, 5000.0)


def _field(seed=1, rms=2.0, corr=300.0):
    return DemErrorField(rms, corr, BOUNDS, np.random.default_rng(seed))


def test_rms_and_patch_size():
    f = _field()
    rng = np.random.default_rng(0)
    n, e = rng.uniform(-4500, 4500, 20000), rng.uniform(-4500, 4500, 20000)
    v = f.at(n, e)
    assert abs(np.sqrt(np.mean(v**2)) - 2.0) < 0.15
    # correlation_m is a Gaussian correlation's length: exp(-1/2) = 0.61 at that lag, 0.88 at
    # half of it; the splines' tail falls faster than a Gaussian's (0.14 at twice the length)
    th = rng.uniform(0.0, 2.0 * np.pi, n.size)

    def rho(lag_m):
        w = f.at(n + lag_m * np.cos(th), e + lag_m * np.sin(th))
        return np.mean(v * w) / np.mean(v * v)

    assert abs(rho(150.0) - 0.88) < 0.05 and abs(rho(300.0) - 0.61) < 0.05
    assert rho(600.0) < 0.16 and abs(rho(3000.0)) < 0.05


def test_same_seed_same_field_other_seed_other_field():
    pts = (np.linspace(-4000, 4000, 50), np.linspace(3000, -3000, 50))
    np.testing.assert_array_equal(_field(7).at(*pts), _field(7).at(*pts))
    assert np.corrcoef(_field(7).at(*pts), _field(8).at(*pts))[0, 1] < 0.5


def test_errored_elevation_reads_alike_by_point_and_by_window():
    dem = ErroredElevation(FlatElevation(12.0), 2.0, 300.0, np.random.default_rng(3))
    r = dem.read_local(-1000.0, 1000.0, -500.0, 1500.0, 10.0)
    rows, cols = np.array([0, 57, 199]), np.array([3, 120, 199])
    north = r.north0_m - (rows + 0.5) * r.gsd_m
    east = r.east0_m + (cols + 0.5) * r.gsd_m
    np.testing.assert_allclose(r.data[rows, cols], dem.height_m(north, east), atol=1e-4)
    h, ok = dem.height_and_valid(north, east)
    np.testing.assert_allclose(h, dem.height_m(north, east))
    assert ok.all() and abs(float(np.mean(r.data)) - 12.0) < 2.0
