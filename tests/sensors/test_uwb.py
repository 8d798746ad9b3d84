"""UWB: NLOS excess distribution (KS), TDMA schedule, range limit, blocking geometry."""

from collections import Counter

import numpy as np
import pytest
from scipy import stats

from testbench.core.interfaces import BuildContext
from testbench.sensors.fakes import ORIGIN, FakeWorld, make_truth
from testbench.core.obstacles import Obstacle
from testbench.sensors.uwb import Uwb, UwbParams
from testbench.sensors.uwb_channel import ChannelSpec, measure_ranges, nlos_error_cdf, nlos_mean_excess_m

IDS = ("a", "b", "c", "d")


def test_mean_excess_units():
    # T1 = 19 ns is the median delay spread at 1 km: c * 19 ns = 5.696 m at d = 1000 m.
    spec = ChannelSpec(eps=0.5)
    assert nlos_mean_excess_m(1000.0, spec) == pytest.approx(299792458.0 * 19e-9)
    assert nlos_mean_excess_m(100.0, spec) == pytest.approx(299792458.0 * 19e-9 * np.sqrt(0.1))


def test_nlos_excess_is_the_configured_exponential():
    # 1e5 NLOS ranges with no Gaussian part and xi = 1: r - d must be Exp(c T1 d_km^eps).
    spec = ChannelSpec(sigma_m=0.0, sigma_ln_xi=0.0, eps=0.7)
    d = np.full(100_000, 150.0)
    r, _, nlos = measure_ranges(d, np.ones(d.size, bool), spec, np.random.default_rng(42))
    assert nlos.all()
    scale = nlos_mean_excess_m(150.0, spec)
    assert stats.kstest(r - d, "expon", args=(0.0, scale)).pvalue > 0.01
    # A model using d in metres (or T1 as a mean, not a median) is rejected outright.
    assert stats.kstest(r - d, "expon", args=(0.0, 1.2 * scale)).pvalue < 1e-6


def test_full_nlos_error_matches_mixture_cdf():
    # With the Gaussian LOS noise and log-normal xi: r - d ~ E_xi[exponnorm].
    spec = ChannelSpec()
    d = np.full(100_000, 120.0)
    r, _, _ = measure_ranges(d, np.ones(d.size, bool), spec, np.random.default_rng(7))
    assert stats.kstest(r - d, lambda x: nlos_error_cdf(x, 120.0, spec)).pvalue > 0.01
    wrong = ChannelSpec(sigma_ln_xi=0.0)
    assert stats.kstest(r - d, lambda x: nlos_error_cdf(x, 120.0, wrong)).pvalue < 1e-6


def test_los_error_gaussian_10cm():
    spec = ChannelSpec()
    d = np.full(20_000, 80.0)
    r, rss, nlos = measure_ranges(d, np.zeros(d.size, bool), spec, np.random.default_rng(1))
    assert not nlos.any()
    assert np.std(r - d) == pytest.approx(0.10, rel=0.03)
    assert abs(np.mean(r - d)) < 0.005
    # Path loss: mean rss = Ptx - PL0 - 10 n log10(d).
    assert np.mean(rss) == pytest.approx(-14.3 - 40.0 - 20.0 * np.log10(80.0), abs=0.1)


def _swarm(t, spacing=50.0, n=4):
    return {vid: make_truth(t, pos_ned_m=(0.0, i * spacing, -100.0)) for i, vid in enumerate(IDS[:n])}


def test_tdma_each_pair_at_its_implied_rate():
    slot = 0.02
    params = UwbParams(slot_time_s=slot)
    sensors = {v: Uwb(params, ctx=BuildContext(v, IDS, ORIGIN, physics_rate_hz=100.0)) for v in IDS}
    assert all(s.rate_hz == pytest.approx(50.0) for s in sensors.values())
    rngs = {v: np.random.default_rng(i) for i, v in enumerate(IDS)}
    duration = 8.0  # 100 cycles of 4 slots
    counts, times = Counter(), {}
    for k in range(int(round(duration / slot))):
        t = k * slot
        vehicles = _swarm(t)
        for v, s in sensors.items():
            m = s.measure(vehicles[v], FakeWorld(t, v, vehicles), rngs[v])
            if m is not None:
                counts[(v, m.peer_id)] += 1
                times.setdefault((v, m.peer_id), []).append(t)
    assert len(counts) == 12  # every ordered pair, never oneself
    assert set(counts.values()) == {100}
    for ts in times.values():
        np.testing.assert_allclose(np.diff(ts), len(IDS) * slot)


def test_range_limit_and_lever_arm():
    ctx = BuildContext("a", ("a", "b"), ORIGIN)
    uwb = Uwb(UwbParams(slot_time_s=0.01, range_sigma_m=0.0, lever_arm_b_m=(0.0, 0.0, -1.0)), ctx=ctx)
    rng = np.random.default_rng(0)
    t = 0.01  # slot 1: b transmits
    near = {"a": make_truth(t, (0, 0, -100)), "b": make_truth(t, (0, 150, -100), rpy_rad=(np.pi / 2, 0, 0))}
    m = uwb.measure(near["a"], FakeWorld(t, "a", near), rng)
    # a's antenna 1 m above a; b is rolled 90 deg right, so its body -z arm points east
    # (R_nb maps body (0, 0, -1) to NED (0, 1, 0)): b's antenna at east 151 m.
    assert m.peer_id == "b" and m.range_m == pytest.approx(np.hypot(151.0, 1.0), abs=1e-9)
    far = {"a": make_truth(0.03, (0, 0, -100)), "b": make_truth(0.03, (0, 201, -100))}
    assert uwb.measure(far["a"], FakeWorld(0.03, "a", far), rng) is None
    own = {k: make_truth(0.02, tuple(v.pos_ned_m)) for k, v in near.items()}  # slot 2 = a's own
    assert uwb.measure(own["a"], FakeWorld(0.02, "a", own), rng) is None


def test_terrain_and_obstacles_make_nlos():
    ctx = BuildContext("a", ("a", "b"), ORIGIN)
    uwb = Uwb(UwbParams(), ctx=ctx)
    a, b = np.array([0.0, 0.0, -10.0]), np.array([0.0, 100.0, -10.0])
    ridge = lambda n, e: np.where(np.abs(np.asarray(e) - 50.0) < 5.0, 30.0, 0.0)  # 30 m high wall
    assert uwb.blocked(a, b, FakeWorld(terrain=ridge))
    assert not uwb.blocked(a, b, FakeWorld())
    box = Obstacle((-5.0, 40.0, -50.0), (5.0, 60.0, 0.0))
    assert uwb.blocked(a, b, FakeWorld(obstacles=(box,)))
    assert not uwb.blocked(a + [0, 0, -100], b + [0, 0, -100], FakeWorld(obstacles=(box,)))
    # Blocked links have the NLOS excess: mean error well above zero.
    rng = np.random.default_rng(3)
    errs = []
    for k in range(400):
        t = 0.01 * (2 * k + 1)
        veh = {"a": make_truth(t, tuple(a)), "b": make_truth(t, tuple(b))}
        m = uwb.measure(veh["a"], FakeWorld(t, "a", veh, terrain=ridge), rng)
        errs.append(m.range_m - 100.0)
    assert uwb.last_nlos
    assert np.mean(errs) == pytest.approx(nlos_mean_excess_m(100.0, uwb.spec) * np.exp(0.5**2 / 2), rel=0.2)


def test_the_scenarios_obstacles_reach_the_radio():
    """world.obstacles as a scenario gives them (validated boxes) become the run world's
    obstacles, named, and block the links they cut, through the tick's world view."""
    from testbench.config.schema import World
    from testbench.sim.world_runtime import RunWorld, TickWorldView

    spec = World.model_validate({"origin": {"lat_deg": 47.0, "lon_deg": -99.0, "alt_m": 500.0},
                                 "obstacles": [{"name": "hall", "min_ned_m": [-5, 40, -50], "max_ned_m": [5, 60, 0]},
                                               {"min_ned_m": [200, 0, -5], "max_ned_m": [201, 1, 0]}]})
    world = RunWorld(spec, ORIGIN)
    assert [o.name for o in world.obstacles] == ["hall", "obstacle 2"]
    uwb = Uwb(UwbParams(), ctx=BuildContext("a", ("a", "b"), ORIGIN))
    view = TickWorldView(world, 0.0, "a", {})
    a, b = np.array([0.0, 0.0, -10.0]), np.array([0.0, 100.0, -10.0])
    assert uwb.blocked(a, b, view) and not uwb.blocked(a - [0, 0, 60], b - [0, 0, 60], view)


def test_rate_must_match_slot():
    with pytest.raises(ValueError):
        UwbParams(slot_time_s=0.01, rate_hz=50.0)
