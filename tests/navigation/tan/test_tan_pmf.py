"""navigation.tan: the point-mass filter finds a known offset of a track over a synthetic DEM,
and says so when the terrain cannot tell."""

from __future__ import annotations

import math

import numpy as np

from testbench.core.radar_beam import beam_rays_b, first_return_m
from testbench.navigation.tan import TerrainPmf
from testbench.world.raster import LocalRaster, sample_bilinear

GSD_M = 10.0


def _dem(flat: bool = False) -> LocalRaster:
    """A 4 km square of hills (three crossing waves, 10 m grid), or flat ground."""
    n = 400
    north = 2000.0 - (np.arange(n) + 0.5) * GSD_M
    east = -2000.0 + (np.arange(n) + 0.5) * GSD_M
    N, E = np.meshgrid(north, east, indexing="ij")
    z = np.zeros_like(N) if flat else (25.0 * np.sin(N / 230.0 + 0.4) * np.cos(E / 310.0)
                                        + 12.0 * np.sin((N + 0.6 * E) / 97.0) + 6.0 * np.cos((E - 0.3 * N) / 53.0))
    return LocalRaster(z.astype(np.float32), np.ones(z.shape, bool), 2000.0, -2000.0, GSD_M)


def _height_fn(dem: LocalRaster):
    def height_m(north_m, east_m):
        v, ok = sample_bilinear(dem, north_m, east_m)
        return np.where(ok, v, np.nan)
    return height_m


def _fly(dem: LocalRaster, offset_ne_m, dh_m: float, seed: int = 1, sigma_m: float = 1.0, outliers: bool = False):
    """A pmf fed 100 ranges along a northbound dead-reckoned track; the truth runs offset_ne_m
    beside it and dh_m above it; outliers: every 17th range 60 m short (a tree line, a mast)."""
    rng = np.random.default_rng(seed)
    rays = beam_rays_b(math.radians(20.0))
    R_nb = np.eye(3)
    height = _height_fn(dem)
    pmf = TerrainPmf(half_width_m=80.0, cells=41, dem_sigma_m=0.5, dem_correlation_m=0.0)
    for k in range(100):
        dr = np.array([-1000.0 + 5.0 * k, 100.0, -300.0])
        truth = dr + np.array([offset_ne_m[0], offset_ne_m[1], -dh_m])
        r = float(first_return_m(truth, R_nb, rays, height)) + sigma_m * rng.standard_normal()
        if outliers and k % 17 == 5:
            r -= 60.0
        pmf.update(dr, R_nb, rays, r, sigma_m, height)
    return pmf


def test_pmf_finds_a_known_offset_over_hills():
    post = _fly(_dem(), (23.0, -31.0), 2.5).posterior()
    np.testing.assert_allclose(post.mean_ne_m, [23.0, -31.0], atol=2.0)
    assert abs(post.mean_dh_m - 2.5) < 0.6
    sig = np.sqrt(np.diag(post.cov_ne_m2))
    assert np.all(sig < 4.0)  # the 4 m grid step alone gives 1.2 m
    # the truth lies within what the density claims
    e = post.mean_ne_m - np.array([23.0, -31.0])
    assert float(e @ np.linalg.solve(post.cov_ne_m2, e)) < 13.8  # chi-square 2 dof, 99.9 %
    assert post.mass_in_ellipse > 0.95 and post.edge_mass < 0.01


def test_pmf_over_flat_ground_learns_nothing_horizontally():
    post = _fly(_dem(flat=True), (23.0, -31.0), 2.5).posterior()
    # a flat density over the 160 m grid: sigma of a uniform over it, about 46 m per axis
    assert np.all(np.sqrt(np.diag(post.cov_ne_m2)) > 40.0)
    assert post.edge_mass > 0.05  # the grid's edge holds as much as anywhere: no fix from this
    assert abs(post.mean_dh_m - 2.5) < 0.6  # the height still comes through


def test_range_outliers_do_not_move_the_fix():
    dem = _dem()
    clean = _fly(dem, (10.0, 15.0), 0.0, seed=4).posterior()
    spoilt = _fly(dem, (10.0, 15.0), 0.0, seed=4, outliers=True).posterior()
    np.testing.assert_allclose(spoilt.mean_ne_m, clean.mean_ne_m, atol=1.0)
    np.testing.assert_allclose(clean.mean_ne_m, [10.0, 15.0], atol=2.0)


def test_ranges_echoed_by_one_hilltop_share_its_dem_error():
    # A lone round hill (150 m high, 100 m Gaussian radius) under a track 800 m up that runs
    # 300 m either side of it: every echo comes from the hill's crown (within 60 m of its top:
    # the beam's rays), so the ranges share the error the DEM has there. The height offset, which
    # the ranges' mean error sets, is then known little better than that error (var 7.2 m^2 of
    # sigma_dem^2 = 9), although the track's ends lie two correlation lengths apart: the DEM errs
    # where the echo comes from, not below the antenna.
    n = 200
    north = 1000.0 - (np.arange(n) + 0.5) * GSD_M
    east = -1000.0 + (np.arange(n) + 0.5) * GSD_M
    N, E = np.meshgrid(north, east, indexing="ij")
    z = 150.0 * np.exp(-0.5 * (N**2 + E**2) / 100.0**2)
    dem = LocalRaster(z.astype(np.float32), np.ones(z.shape, bool), 1000.0, -1000.0, GSD_M)
    height = _height_fn(dem)
    rays, R_nb = beam_rays_b(math.radians(20.0)), np.eye(3)
    sigma_dem, L = 3.0, 300.0
    pmf = TerrainPmf(half_width_m=20.0, cells=5, dem_sigma_m=sigma_dem, dem_correlation_m=L)
    for k in range(61):
        antenna = np.array([-300.0 + 10.0 * k, 0.0, -800.0])
        pmf.update(antenna, R_nb, rays, float(first_return_m(antenna, R_nb, rays, height)), 0.3, height)
    post = pmf.posterior()
    assert post.var_dh_m2 > 0.75 * sigma_dem**2
    # Taken below the antenna instead, the ends' errors would correlate by exp(-2) only, and the
    # sixty-one ranges would claim the height to 4.8 m^2.


def _half_flat_dem() -> LocalRaster:
    """The hills of _dem() north of -750 m, flat ground south of it."""
    hills = _dem()
    north = hills.north0_m - (np.arange(hills.data.shape[0]) + 0.5) * GSD_M
    z = np.where((north >= -750.0)[:, None], hills.data, 0.0).astype(np.float32)
    return LocalRaster(z, hills.valid, hills.north0_m, hills.east0_m, GSD_M)


def test_the_offset_found_follows_a_drift_where_the_terrain_spoke():
    # A 20 s track, its first half over flat ground and its second over hills; the dead
    # reckoning drifts off the truth by 0.6 m/s north and -0.4 m/s east (a velocity error), so
    # the true offset changes by 12 m and 8 m over the window. The flat half says nothing, and
    # each axis holds where the slopes along it were: the offset found is sum_k W_k o(t_k)
    # (within the linearisation), not the offset at the ranges' mean epoch.
    dem = _half_flat_dem()
    height = _height_fn(dem)
    rays, R_nb = beam_rays_b(math.radians(20.0)), np.eye(3)
    rng = np.random.default_rng(4)
    v_err = np.array([0.6, -0.4])
    t = np.arange(101) * 0.2
    pmf = TerrainPmf(half_width_m=40.0, cells=81, dem_sigma_m=0.0, dem_correlation_m=0.0)
    offsets = np.array([20.0, -10.0]) + np.outer(t - t.mean(), v_err)  # truth - dead reckoning
    for k in range(len(t)):
        dr = np.array([-1000.0 + 5.0 * k, 100.0, -300.0])
        truth = dr + np.r_[offsets[k], 0.0]
        r = float(first_return_m(truth, R_nb, rays, height)) + 0.3 * rng.standard_normal()
        pmf.update(dr, R_nb, rays, r, 0.3, height)
    post = pmf.posterior()
    W = post.lag_weights
    assert W is not None and W.shape == (101, 2, 2)
    np.testing.assert_allclose(W.sum(axis=0), np.eye(2), atol=1e-9)
    assert np.abs(W[t < 9.0].sum(axis=0)).max() < 0.02  # the flat half (its last beams reach the hills)
    predicted = np.einsum("kij,kj->i", W, offsets)
    assert np.hypot(*(post.mean_ne_m - predicted)) < 1.0  # measured 0.7 m
    assert np.hypot(*(post.mean_ne_m - offsets[50])) > 2.5  # the mean epoch's offset: 3.9 m off
