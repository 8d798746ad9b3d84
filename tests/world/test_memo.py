"""The process-wide memo of map reads (batch workers) and the ISMN map cache's whole-map reads."""

import numpy as np
import pytest
from rasterio.transform import from_origin

from testbench.navigation.ismn.mapcache import MapWindowCache
from testbench.world import memo
from testbench.world.georef import LocalFrame
from testbench.world.imagery import MapSource
from tests.world.test_geotiff import write_tif


@pytest.fixture
def memo_on():
    memo.enable(64 * 2**20)
    yield
    memo.disable()


@pytest.fixture
def small_map(tmp_path, origin):
    """A 300 x 400 px, 2 m UTM map of random texture centred near the origin."""
    frame = LocalFrame(origin, "EPSG:32614")
    x0, y0 = frame.ne_to_xy(0.0, 0.0)
    data = np.random.default_rng(1).integers(0, 255, (3, 300, 400), dtype=np.uint8)
    return write_tif(tmp_path / "m.tif", data, "EPSG:32614", from_origin(float(x0) - 400.0, float(y0) + 300.0, 2.0, 2.0))


def test_memo_off_computes_every_time():
    calls = []
    for _ in range(2):
        memo.cached("k", lambda: calls.append(1) or np.zeros(3))
    assert len(calls) == 2 and not memo.enabled()


def test_memo_keeps_values_read_only_and_evicts_least_recently_used(memo_on):
    a = memo.cached("a", lambda: np.zeros(4 * 2**20, np.uint8))  # 4 MiB each
    assert memo.cached("a", lambda: pytest.fail("recomputed")) is a
    with pytest.raises(ValueError):
        a[0] = 1  # a run cannot alter what the next one gets
    for i in range(20):
        memo.cached(("b", i), lambda: np.zeros(4 * 2**20, np.uint8))
    assert memo.held_bytes() <= 64 * 2**20
    fresh = memo.cached("a", lambda: np.ones(1))  # evicted by the 20 newer ones
    assert fresh[0] == 1


def test_a_second_source_of_the_same_file_gets_the_memoised_read(small_map, origin, memo_on):
    box = (-200.0, 200.0, -300.0, 300.0, 2.0)
    first = MapSource(small_map, origin).read_local(*box)
    second = MapSource(small_map, origin).read_local(*box)
    assert second is first
    memo.disable()
    fresh = MapSource(small_map, origin).read_local(*box)
    np.testing.assert_array_equal(fresh.data, first.data)
    np.testing.assert_array_equal(fresh.valid, first.valid)


def test_map_cache_reads_a_small_map_whole_and_pads_past_its_edge(small_map, origin):
    src = MapSource(small_map, origin)
    cache = MapWindowCache(src)
    inside = cache.read(-100.0, 50.0, -200.0, 0.0, 2.0)
    fp = src.footprint
    whole = cache._cache[2.0]
    assert whole.shape[0] * 2.0 >= fp.north_max_m - fp.north_min_m - 1e-6
    # A request reaching 100 m past the map's east edge: no-data there, the map elsewhere.
    edge = cache.read(-100.0, 50.0, fp.east_max_m - 150.0, fp.east_max_m + 100.0, 2.0)
    assert len(cache._cache) == 1  # both served from the one read
    assert edge.valid[:, :60].all() and not edge.valid[:, -45:].any()
    assert (edge.data[:, -45:] == 0).all()
    assert edge.east0_m <= fp.east_max_m - 150.0 + 1e-9 and edge.east0_m + edge.shape[1] * 2.0 >= fp.east_max_m + 100.0 - 1e-9
    # The map part of the padded window is the same pixels as an inside crop of the read.
    r, c = round((whole.north0_m - edge.north0_m) / 2.0), round((edge.east0_m - whole.east0_m) / 2.0)
    np.testing.assert_array_equal(edge.data[:, :60], whole.data[r:r + edge.shape[0], c:c + 60])
    assert inside.valid.all()
    # Feature images are cut from the whole read's for crops, and not offered for padded windows.
    assert cache.features(inside, "gradmag").shape == inside.shape
    assert cache.features(edge, "gradmag") is None
