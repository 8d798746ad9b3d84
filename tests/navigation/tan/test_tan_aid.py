"""navigation.tan_aid: a window of radar altimeter ranges over a real (procedural GeoTIFF) DEM
becomes one position fix near the truth; flat ground gives none; bad configuration is named."""

from __future__ import annotations

import math

import numpy as np
import pytest

from testbench.core import registry
from testbench.core.errors import InputError
from testbench.core.interfaces import BuildContext
from testbench.core.messages import NavEstimate
from testbench.sensors.fakes import ORIGIN, FakeWorld, make_truth
from testbench.world.raster import sample_bilinear
from testbench.world.spec import open_elevation

CTX = BuildContext("uav0", ("uav0",), ORIGIN, physics_rate_hz=120.0)
OFFSET_NE_M = np.array([35.0, -20.0])  # the estimate's error (estimate - truth)


@pytest.fixture(scope="module")
def desert(tmp_path_factory):
    return open_elevation("procedural:desert?seed=5&size_km=4&gsd_m=10", ORIGIN, tmp_path_factory.mktemp("worlds"))


def _radar():
    return registry.build("sensor", "radar_altimeter", {"rate_hz": 10}, "test.radar", ctx=CTX)


def _aid(radar, dem, **params):
    return registry.build("aid", "tan", {"sensor": "radar", "window_s": 20.0, **params}, "test.tan", ctx=CTX,
                          sensors={"radar": radar}, onboard={"reference_elevation": lambda: dem})


def _estimate(truth, sigma_m: float, offset_ne_m=OFFSET_NE_M) -> NavEstimate:
    pos = truth.pos_ned_m + np.r_[offset_ne_m, 0.0]
    return NavEstimate(truth.t_s, pos, truth.vel_ned_mps.copy(), truth.q_nb_wxyz, truth.rpy_rad, np.zeros(3),
                       np.diag([sigma_m**2, sigma_m**2, 1.0]), np.eye(3) * 0.01, np.eye(3) * 1e-6)


def _fly(aid, radar, world, seconds: float = 20.0, sigma_m: float = 20.0, offset_ne_m=OFFSET_NE_M):
    """Truth flying north at 25 m/s, 300 m up, the estimate offset_ne_m off claiming sigma_m;
    returns (fixes, attempts, last truth)."""
    rng = np.random.default_rng(2)
    fixes, attempts, truth = [], [], None
    for k in range(int(seconds * 10) + 1):
        t = k / 10.0
        truth = make_truth(t, pos_ned_m=(-800.0 + 25.0 * t, 100.0, -300.0), vel_ned_mps=(25.0, 0.0, 0.0))
        m = radar.measure(truth, world, rng)
        if m is not None and aid.accepts(m):
            out, attempt = aid.process(m, _estimate(truth, sigma_m, offset_ne_m))
            fixes += out
            attempts += [attempt] if attempt is not None else []
    return fixes, attempts, truth


def test_a_window_over_relief_gives_a_fix_near_the_truth(desert):
    radar = _radar()
    world = FakeWorld(terrain=desert.height_m)
    fixes, attempts, truth = _fly(_aid(radar, desert), radar, world)
    assert len(fixes) == 1 and len(attempts) == 1
    fix = fixes[0]
    err = fix.pos_ned_m - truth.pos_ned_m
    sigma = np.sqrt(np.diag(fix.cov_ned_m2))
    assert np.all(np.abs(err[:2]) < 3.0 * sigma[:2]), (err, sigma)
    assert np.hypot(*err[:2]) < 6.0  # the estimate it started from was 40 m off
    assert abs(err[2]) < 3.0 * sigma[2]
    # The velocity lag: a 2 x 2 horizontal matrix (the match weighs each range by the slopes it
    # saw: here 8.4 / 10.0 s on the diagonal, 2.5-3.8 s across), none in the vertical (the heights
    # are the navigator's own); about the window's half length, 10 s, for terrain alike throughout.
    lag = np.asarray(fix.vel_lag_s)
    assert fix.source == "tan" and lag.shape == (3, 3) and np.all(lag[2] == 0.0) and np.all(lag[:, 2] == 0.0)
    assert 6.0 < lag[0, 0] < 14.0 and 6.0 < lag[1, 1] < 14.0
    (table, row), = attempts[0].event_rows("uav0")
    assert table == "tan" and row["fix"] and row["reason"] == "" and np.isnan(row["truth_north_m"])
    assert row["vel_lag_s"] == pytest.approx(0.5 * (lag[0, 0] + lag[1, 1]))
    assert (row["lag_nn_s"], row["lag_ne_s"], row["lag_en_s"], row["lag_ee_s"]) == pytest.approx(lag[:2, :2].ravel())
    assert row["window_start_s"] == pytest.approx(0.0)


def test_flat_ground_gives_no_fix(desert):
    radar = _radar()
    flat = open_elevation(None, ORIGIN)
    fixes, attempts, _ = _fly(_aid(radar, flat), radar, FakeWorld())
    assert fixes == [] and len(attempts) == 1
    (_, row), = attempts[0].event_rows("uav0")
    assert not row["fix"] and row["reason"] == "flat"


def test_the_onboard_dem_need_not_be_the_truth(desert):
    """Ranged over the truth terrain, matched on that terrain plus a 2 m error field: the fix
    still lands near the truth and claims what it errs by."""
    from testbench.world.dem_error import ErroredElevation

    radar = _radar()
    onboard = ErroredElevation(desert, 2.0, 300.0, np.random.default_rng(4))
    fixes, _, truth = _fly(_aid(radar, onboard, dem_sigma_m=2.0, dem_correlation_m=300.0), radar,
                           FakeWorld(terrain=desert.height_m))
    assert len(fixes) == 1
    err = fixes[0].pos_ned_m - truth.pos_ned_m
    e = err[:2]
    assert float(e @ np.linalg.solve(fixes[0].cov_ned_m2[:2, :2], e)) < 13.8  # chi-square 2 dof, 99.9 %


def test_bad_configuration_is_named(desert):
    radar = _radar()
    with pytest.raises(InputError, match=r"vehicles\[uav0\]\.aids\[tan\]: terrain-aided navigation needs a DEM onboard: world\.reference_elevation"):
        registry.build("aid", "tan", {"sensor": "radar"}, "test.tan", ctx=CTX, sensors={"radar": radar},
                       onboard={"reference_elevation": lambda: None})
    with pytest.raises(InputError, match=r"params\.sensor: no sensor named 'radar_altimeter' on this vehicle \(have: radar\)"):
        registry.build("aid", "tan", {}, "test.tan", ctx=CTX, sensors={"radar": radar},
                       onboard={"reference_elevation": lambda: desert})
    baro = registry.build("sensor", "barometer", {"rate_hz": 20}, "test.baro", ctx=CTX)
    with pytest.raises(InputError, match=r"sensor 'baro' is not a radar altimeter"):
        registry.build("aid", "tan", {"sensor": "baro"}, "test.tan", ctx=CTX, sensors={"baro": baro},
                       onboard={"reference_elevation": lambda: desert})
    with pytest.raises(InputError, match=r"cells.*must be odd"):
        _aid(radar, desert, cells=60)


def test_no_return_beyond_the_altimeter_range():
    radar = registry.build("sensor", "radar_altimeter", {"max_range_m": 200.0}, "test.radar", ctx=CTX)
    rng = np.random.default_rng(0)
    assert radar.measure(make_truth(0.0, pos_ned_m=(0.0, 0.0, -150.0)), FakeWorld(), rng) is not None
    assert radar.measure(make_truth(0.1, pos_ned_m=(0.0, 0.0, -250.0)), FakeWorld(), rng) is None
    r = radar.measure(make_truth(0.2, pos_ned_m=(0.0, 0.0, -150.0), rpy_rad=(math.radians(10.0), 0.0, 0.0)),
                      FakeWorld(), rng)
    assert r.range_m == pytest.approx(150.0, abs=2.0)  # a 20 deg beam still sees straight down at 10 deg of bank


def test_ground_the_dem_does_not_hold_gives_no_fix(desert):
    """A town the DEM does not hold (40 m blocks over a third of the ground): the wide beam finds
    a roof in most ranges, so the ground reads 40 m higher than the DEM and the navigator's
    height allow, and the window gives no fix."""
    def town(north_m, east_m):
        blocks = ((np.floor(np.asarray(north_m) / 60.0) + np.floor(np.asarray(east_m) / 60.0)) % 3 == 0)
        return desert.height_m(north_m, east_m) + 40.0 * blocks

    radar = _radar()
    fixes, attempts, _ = _fly(_aid(radar, desert), radar, FakeWorld(terrain=town))
    (_, row), = attempts[0].event_rows("uav0")
    assert fixes == [] and row["reason"] == "height", row


def test_a_navigator_further_off_than_it_claims_is_found_on_a_wider_grid(desert):
    """The estimate 150 m off while claiming 5 m: the first grid (+-60 m) holds the density
    against its edge, and the window's own ranges searched on grids twice and four times as
    wide find the truth."""
    radar = _radar()
    fixes, attempts, truth = _fly(_aid(radar, desert), radar, FakeWorld(terrain=desert.height_m), sigma_m=5.0,
                                  offset_ne_m=np.array([-120.0, 90.0]))
    assert len(fixes) == 1, attempts[0].reason
    assert np.hypot(*(fixes[0].pos_ned_m - truth.pos_ned_m)[:2]) < 10.0
    _, narrow_attempts, _ = _fly(_aid(radar, desert, max_widen=1.0), _radar(), FakeWorld(terrain=desert.height_m),
                                 sigma_m=5.0, offset_ne_m=np.array([-120.0, 90.0]))
    assert narrow_attempts[0].reason == "at grid edge"


def test_the_onboard_dem_is_read_on_its_own_posting(desert):
    # A window starting anywhere reads the DEM on its own samples, not resampled onto a grid cut
    # at the window's start: where it carries the very DEM the radar sees, the two agree exactly.
    # (Cut at the start, resampling smoothed this desert's ridges by 0.2-0.35 m RMS, up to 3.7 m:
    # an error of the onboard DEM that its error model does not hold.)
    aid = _aid(_radar(), desert)
    _, raster = aid._grid(60.0, np.array([-1234.567, 321.89]), 400.0)
    g = desert.native_gsd_m
    assert raster.gsd_m == g
    for edge in (raster.north0_m, raster.east0_m):
        assert abs(edge / g - round(edge / g)) < 1e-9
    rng = np.random.default_rng(0)
    pn, pe = -1234.567 + rng.uniform(-400, 400, 2000), 321.89 + rng.uniform(-400, 400, 2000)
    onboard, ok = sample_bilinear(raster, pn, pe)
    assert ok.all()
    np.testing.assert_allclose(onboard, desert.height_m(pn, pe), atol=1e-3)


def test_velocity_lag_inflate_claims_the_lag_instead_of_handing_it_over(desert):
    # For a navigator that ignores PositionFix.vel_lag_s: no lag on the fix, and its claim grown
    # by the lag times the navigator's velocity sigma (0.1 m/s here) and the track's bend.
    radar = _radar()
    world = FakeWorld(terrain=desert.height_m)
    (modelled,), _, _ = _fly(_aid(radar, desert), radar, world)
    (inflated,), _, _ = _fly(_aid(_radar(), desert, velocity_lag="inflate"), _radar(), world)
    assert inflated.vel_lag_s is None and np.asarray(modelled.vel_lag_s).shape == (3, 3)
    np.testing.assert_allclose(inflated.pos_ned_m, modelled.pos_ned_m)
    grown = np.diag(inflated.cov_ned_m2)[:2] - np.diag(modelled.cov_ned_m2)[:2]
    lag_norm = np.linalg.norm(np.asarray(modelled.vel_lag_s)[:2, :2], 2)
    np.testing.assert_allclose(grown, 0.01 * (lag_norm**2 + 20.0**2 / 12.0), rtol=0.05)
