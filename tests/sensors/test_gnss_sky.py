"""GNSS satellites in view: the constellation's geometry, DOP, obstructions and the receiver."""

from __future__ import annotations

import math

import numpy as np
import pytest

from testbench.core.interfaces import BuildContext
from testbench.core.obstacles import Obstacle
from testbench.sensors.fakes import ORIGIN, FakeWorld, make_truth
from testbench.sensors.gnss import Gnss, GnssParams
from testbench.sensors.gnss_sky import GPS_ORBIT_RADIUS_M, SkyModel, dop, satellites_ecef_m, walker_constellation


def test_walker_orbits_repeat_their_ground_track_each_sidereal_day():
    raan, u0 = walker_constellation(30, 5, 2)
    assert len(raan) == 30 and len(set(np.round(raan, 9))) == 5
    a = satellites_ecef_m(raan, u0, math.radians(55.0), 1000.0)
    assert np.allclose(np.linalg.norm(a, axis=1), GPS_ORBIT_RADIUS_M)
    assert np.allclose(np.abs(a[:, 2]).max() / GPS_ORBIT_RADIUS_M, math.sin(math.radians(55.0)), atol=0.02)
    b = satellites_ecef_m(raan, u0, math.radians(55.0), 1000.0 + 86164.1)  # two orbits, one turn of the Earth
    assert np.abs(a - b).max() < 1e-3 * GPS_ORBIT_RADIUS_M
    with pytest.raises(ValueError):
        walker_constellation(25, 6, 1)
    # The default pattern's satellites never meet (two in one place make the geometry singular).
    from scipy.spatial.distance import pdist

    gaps = [pdist(satellites_ecef_m(raan, u0, math.radians(55.0), t)).min() for t in np.arange(0.0, 43082.0, 120.0)]
    assert min(gaps) > 1e6


def test_dop_of_a_known_geometry():
    """Zenith plus three satellites on the horizon 120 deg apart: by symmetry north and east
    DOP are equal; one more satellite never weakens the geometry; three are not a fix."""
    el0 = [np.array([math.cos(a), math.sin(a), 0.0]) for a in np.radians([0.0, 120.0, 240.0])]
    los = np.array([[0.0, 0.0, -1.0], *el0])
    d = dop(los)
    assert d.ned[0] == pytest.approx(d.ned[1]) and d.hdop == pytest.approx(math.sqrt(2) * d.ned[0])
    # With a clock unknown, the zenith and horizon geometry gives ned = (sqrt(2/3), sqrt(2/3), sqrt(4/3)).
    assert d.ned == pytest.approx((math.sqrt(2 / 3), math.sqrt(2 / 3), math.sqrt(4 / 3)), rel=1e-9)
    more = dop(np.vstack([los, [[0.5, 0.5, -math.sqrt(0.5)]]]))
    assert more.pdop <= d.pdop + 1e-12
    assert dop(los[:3]) is None


def test_open_sky_satellite_counts_and_dop():
    sky = SkyModel()
    counts, hdops = [], []
    for t in np.arange(0.0, 86164.0, 1800.0):
        los = sky.lines_of_sight(t, ORIGIN.lat_rad, ORIGIN.lon_rad, ORIGIN.alt_m + 100.0)
        assert np.all(-los[:, 2] >= math.sin(math.radians(10.0)) - 1e-12)  # above the mask
        counts.append(len(los))
        hdops.append(dop(los).hdop)
    assert 6 <= min(counts) and max(counts) <= 12 and 0.6 < np.median(hdops) < 1.5


def _gnss(**sky):
    return Gnss(GnssParams(sky=sky), ctx=BuildContext("a", ("a",), ORIGIN))


def test_open_sky_fixes_are_those_without_the_sky_model():
    plain, sky = Gnss(GnssParams(), ctx=BuildContext("a", ("a",), ORIGIN)), _gnss()
    rng_a, rng_b = np.random.default_rng(4), np.random.default_rng(4)
    for k in range(20):
        t = make_truth(0.2 * k, pos_ned_m=(0.0, 0.0, -20.0))
        a, b = plain.measure(t, FakeWorld(t.t_s), rng_a), sky.measure(t, FakeWorld(t.t_s), rng_b)
        assert (a.lat_rad, a.lon_rad, a.alt_m) == (b.lat_rad, b.lon_rad, b.alt_m)
        assert np.array_equal(a.pos_sigma_m, b.pos_sigma_m)
    assert sky.last_satellites[0] == sky.last_satellites[1] >= 6


def test_a_wall_to_the_east_weakens_the_east_and_four_walls_deny_the_fix():
    """5 m west of a 200 m wall running north-south, 20 m up: the eastern sky below 88 deg is
    hidden, fewer satellites remain, and the east error and claim grow more than the north;
    at the bottom of a 10 m shaft between four such walls no fix at all."""
    wall = Obstacle((-2000.0, 5.0, -200.0), (2000.0, 15.0, 0.0), "east wall")
    gnss = _gnss()
    truth = make_truth(0.0, pos_ned_m=(0.0, 0.0, -20.0))
    fix = gnss.measure(truth, FakeWorld(0.0, obstacles=(wall,)), np.random.default_rng(1))
    seen, above = gnss.last_satellites
    assert 4 <= seen < above
    open_fix = _gnss().measure(truth, FakeWorld(0.0), np.random.default_rng(1))
    ratio = fix.pos_sigma_m / open_fix.pos_sigma_m
    assert ratio[1] > 1.3 and ratio[1] > ratio[0]
    shaft = (wall, Obstacle((-2000.0, -15.0, -200.0), (2000.0, -5.0, 0.0), "west wall"),
             Obstacle((5.0, -15.0, -200.0), (15.0, 15.0, 0.0), "north wall"),
             Obstacle((-15.0, -15.0, -200.0), (-5.0, 15.0, 0.0), "south wall"))
    gnss = _gnss()
    assert gnss.measure(truth, FakeWorld(0.0, obstacles=shaft), np.random.default_rng(1)) is None
    assert gnss.last_satellites[0] < 4


def test_terrain_hides_the_low_sky():
    """At the floor of a 300 m deep trench 100 m wide (terrain), only a strip of sky along it
    remains."""
    trench = lambda n, e: np.where(np.abs(np.asarray(e)) < 50.0, 0.0, 300.0) + 0.0 * np.asarray(n)
    gnss = _gnss(terrain_step_m=5.0)
    truth = make_truth(0.0, pos_ned_m=(0.0, 0.0, -10.0))
    gnss.measure(truth, FakeWorld(0.0, terrain=trench), np.random.default_rng(1))
    seen, above = gnss.last_satellites
    assert seen < above


def test_a_pattern_that_does_not_split_into_its_planes_is_refused():
    import pydantic

    with pytest.raises(pydantic.ValidationError, match="do not split evenly into 5 planes"):
        GnssParams(sky={"n_sats": 24})
    with pytest.raises(pydantic.ValidationError, match="min_satellites"):
        GnssParams(sky={"min_satellites": 3})


def test_the_record_gets_one_sky_row_per_sample_and_the_pdop_mask_refuses_a_flat_geometry():
    """event_rows gives the sample's row once (then nothing until the next sample); a tight
    PDOP mask turns a fix with a weakened geometry into none, and says so in the row."""
    wall = Obstacle((-2000.0, 5.0, -200.0), (2000.0, 15.0, 0.0), "east wall")
    truth = make_truth(0.0, pos_ned_m=(0.0, 0.0, -20.0))
    gnss = _gnss()
    assert gnss.measure(truth, FakeWorld(0.0, obstacles=(wall,)), np.random.default_rng(1)) is not None
    (table, row), = gnss.event_rows("a")
    assert table == "gnss_sky" and row["vehicle_id"] == "a" and row["fix"]
    assert (row["satellites_visible"], row["satellites_above_mask"]) == gnss.last_satellites
    assert row["hdop"] > row["hdop_open_sky"] > 0
    assert gnss.event_rows("a") == []
    strict = _gnss(max_pdop=1.5)
    assert strict.measure(truth, FakeWorld(0.0, obstacles=(wall,)), np.random.default_rng(1)) is None
    (_, row), = strict.event_rows("a")
    assert not row["fix"] and row["satellites_visible"] >= 4 and np.isnan(row["hdop"])
    # Without a sky model the sensor records nothing.
    plain = Gnss(GnssParams(), ctx=BuildContext("a", ("a",), ORIGIN))
    plain.measure(truth, FakeWorld(0.0), np.random.default_rng(1))
    assert plain.event_rows("a") == []


def test_sky_statistics_in_the_metrics():
    import pandas as pd

    from testbench.scoring.metrics_nav import gnss_sky_stats
    from testbench.scoring.record_io import RunRecord

    rows = pd.DataFrame({"t_s": [0.0, 0.2, 0.4, 0.6], "vehicle_id": ["a"] * 4, "satellites_visible": [8, 5, 3, 6],
                         "satellites_above_mask": [8, 8, 8, 8], "hdop": [1.0, 2.0, np.nan, 3.0],
                         "vdop": [1.5, 2.5, np.nan, 4.0], "hdop_open_sky": [1.0, 1.0, 1.1, 1.1],
                         "fix": [True, True, False, True]})
    stats = gnss_sky_stats(RunRecord(pd.DataFrame({"t_s": [0.0]}), {}, {"gnss_sky": rows}))
    assert stats.satellites_visible_mean == pytest.approx(5.5) and stats.satellites_visible_min == 3
    assert stats.fix_share == pytest.approx(0.75) and stats.hdop.max == pytest.approx(3.0)
    assert stats.hdop_open_sky_median == pytest.approx(1.05) and stats.samples == 4
    assert gnss_sky_stats(RunRecord(pd.DataFrame({"t_s": [0.0]}), {}, {})) is None
