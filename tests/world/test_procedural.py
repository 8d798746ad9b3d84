"""Procedural worlds: determinism, seasons share the layout, canyon relief, spec cache, GeoTIFF
georeference at the origin."""

import hashlib
import os

import cv2
import numpy as np
import pytest
from scipy import ndimage

from testbench.core.errors import InputError
from testbench.world.procedural import TERRAINS, make_world
from testbench.world.spec import open_elevation, open_world_imagery, parse_spec


def _grad(img):
    g = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY).astype(np.float32)
    g = cv2.GaussianBlur(g, (0, 0), 2.0)
    return np.hypot(cv2.Sobel(g, cv2.CV_32F, 1, 0), cv2.Sobel(g, cv2.CV_32F, 0, 1))


@pytest.mark.parametrize("terrain", TERRAINS)
def test_same_seed_same_world_and_shapes(terrain):
    a = make_world(terrain, 0.6, 3.0, 5, "summer")
    b = make_world(terrain, 0.6, 3.0, 5, "summer")
    assert a[0].shape == (200, 200, 3) and a[0].dtype == np.uint8
    assert a[1].shape == (200, 200) and a[1].dtype == np.float32 and a[2].all()
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    c = make_world(terrain, 0.6, 3.0, 6, "summer")
    assert not np.array_equal(a[0], c[0])
    assert a[0].std() > 8  # not a flat colour


@pytest.mark.parametrize("terrain", ["farmland", "urban", "desert"])
def test_seasons_share_layout_but_differ(terrain):
    s, w = make_world(terrain, 1.0, 4.0, 3, "summer"), make_world(terrain, 1.0, 4.0, 3, "autumn")
    assert np.array_equal(s[1], w[1])  # same relief
    ga, gb = _grad(s[0]), _grad(w[0])
    corr = np.corrcoef(ga.ravel(), gb.ravel())[0, 1]
    assert corr > 0.5, corr
    mad = np.abs(s[0].astype(float) - w[0].astype(float)).mean()
    assert mad > 8.0, mad


def test_canyon_has_a_connected_valley():
    _, z, _ = make_world("canyon", 2.0, 8.0, 11, "summer")
    relief = float(z.max() - z.min())
    assert relief > 150.0
    low = z < np.percentile(z, 3)
    lab, n = ndimage.label(low)
    biggest = np.bincount(lab.ravel())[1:].max()
    assert biggest > 0.6 * low.sum()  # one channel, not scattered pits
    rows, cols = np.nonzero(lab == 1 + np.bincount(lab.ravel())[1:].argmax())
    assert max(np.ptp(rows), np.ptp(cols)) > 0.5 * z.shape[0]  # it runs across the map


def test_spec_cache_and_georeference(tmp_path, origin):
    spec = "procedural:grassland?seed=4&season=spring&size_km=0.5&gsd_m=2"
    m = open_world_imagery(spec, origin, cache_dir=tmp_path)
    d = os.path.dirname(m.path)
    first = hashlib.sha256(open(m.path, "rb").read()).hexdigest()
    mt = os.path.getmtime(m.path)
    m2 = open_world_imagery(spec, origin, cache_dir=tmp_path)
    assert m2.path == m.path and os.path.getmtime(m.path) == mt  # reused, not regenerated
    fp = m.footprint
    assert abs(fp.north_max_m - 250.0) < 0.01 and abs(fp.east_min_m + 250.0) < 0.01
    rgb, _, _ = make_world("grassland", 0.5, 2.0, 4, "spring")
    r = m.read_local(-250, 250, -250, 250, 2.0)  # same grid as the generator
    assert r.valid[2:-2, 2:-2].all()
    assert np.abs(r.data[2:-2, 2:-2].astype(int) - rgb[2:-2, 2:-2]).max() <= 1
    dem = open_elevation(spec, origin, cache_dir=tmp_path)
    _, z, _ = make_world("grassland", 0.5, 2.0, 4, "spring")
    assert abs(dem.height_m(0.0, 0.0) - z[124:126, 124:126].mean()) < 1.0
    # regenerating elsewhere gives identical bytes
    other = tmp_path / "again"
    m3 = open_world_imagery(spec, origin, cache_dir=other)
    assert hashlib.sha256(open(m3.path, "rb").read()).hexdigest() == first
    assert not [f for f in os.listdir(d) if f.startswith(".tmp-")]


def test_spec_errors():
    with pytest.raises(InputError, match="unknown terrain"):
        parse_spec("procedural:moon")
    with pytest.raises(InputError, match="unknown key"):
        parse_spec("procedural:farmland?colour=red")
    with pytest.raises(InputError, match="season"):
        parse_spec("procedural:farmland?season=monsoon")
    assert parse_spec("procedural:desert?season=2&seed=9").season == "winter"


def test_fields_do_not_depend_on_the_band_split():
    """A noise/coarse/path field's rows are the same whichever band asks for them."""
    from testbench.world.procedural.linework import PathDistance
    from testbench.world.procedural.noise import CoarseGrid, Fbm, ValueNoise, stream

    shape = (300, 120)
    g = CoarseGrid(shape, 1.0, 4, 32)
    fields = [ValueNoise(stream(1, "a"), shape, 2.7), ValueNoise(stream(1, "b"), shape, 1.0),
              Fbm(stream(1, "c"), g, shape, 80.0, 5),
              PathDistance(g, shape, [np.array([[-5.0, 20.0], [60.0, 140.0], [130.0, 290.0]])], 20)]
    for f in fields:
        whole = f.rows(-20, 320)
        parts = np.concatenate([f.rows(a, min(a + 37, 320)) for a in range(-20, 320, 37)])
        assert whole.shape == (340, 120)
        np.testing.assert_allclose(parts, whole, atol=1e-5)
    fb = fields[2].rows(0, 300)
    assert abs(fb.mean()) < 0.5 and 0.4 < fb.std() < 2.0  # ~zero mean, ~unit std
    d = fields[3].rows(0, 300)
    assert d.min() < 1.0 and (d >= 0).all()


@pytest.mark.parametrize("terrain", TERRAINS)
def test_bands_join_seamlessly(terrain, monkeypatch):
    """The same world in small bands (many seams) and in one band: the joins do not show."""
    from testbench.world.procedural import bands

    one = make_world(terrain, 0.9, 3.0, 2, "summer")  # 300 px: one band
    monkeypatch.setattr(bands, "band_rows", lambda h, w, halo: [(r, min(h, r + 64)) for r in range(0, h, 64)])
    many = make_world(terrain, 0.9, 3.0, 2, "summer")
    assert np.allclose(one[1], many[1], atol=1e-3)  # relief: identical up to rounding
    diff = np.abs(one[0].astype(np.int16) - many[0].astype(np.int16))
    # only the sensor grain (keyed per band) differs; no seam rows stand out
    assert diff.mean() < 6.0
    per_row = diff.mean(axis=(1, 2))
    assert per_row.max() < 3.0 * np.median(per_row) + 2.0


@pytest.mark.parametrize("terrain", TERRAINS)
def test_bands_painted_in_threads_are_the_bands_painted_in_turn(terrain, monkeypatch):
    """Five bands painted by three threads at once: the same bands, in order, bit for bit."""
    from testbench.world.procedural import bands

    monkeypatch.setattr(bands, "band_rows", lambda h, w, halo: [(r, min(h, r + 64)) for r in range(0, h, 64)])
    monkeypatch.setenv("TESTBENCH_WORLD_THREADS", "1")
    alone = make_world(terrain, 0.9, 3.0, 4, "autumn")
    monkeypatch.setenv("TESTBENCH_WORLD_THREADS", "3")
    threaded = make_world(terrain, 0.9, 3.0, 4, "autumn")
    assert alone[0].tobytes() == threaded[0].tobytes() and alone[1].tobytes() == threaded[1].tobytes()


def test_a_caller_that_stops_early_stops_the_painting(monkeypatch):
    """Bands are painted only a few ahead of the caller, and not after it stops."""
    from testbench.world.procedural import bands
    from testbench.world.procedural.appearance import season_from
    from testbench.world.procedural.natural import Desert

    monkeypatch.setattr(bands, "band_rows", lambda h, w, halo: [(r, min(h, r + 16)) for r in range(0, h, 16)])
    gen = Desert(1, (320, 320), 3.0, season_from("summer"))  # 20 bands
    painted = []
    rows = gen.rows
    monkeypatch.setattr(gen, "rows", lambda a, b: painted.append(a) or rows(a, b))
    it = bands.generate(gen, threads=2)
    next(it)
    it.close()
    assert 2 <= len(painted) <= 4  # the first, and at most the two painted meanwhile and one more


@pytest.mark.parametrize("value", ["0", "two", "-1"])
def test_world_threads_from_the_environment_are_checked(value, monkeypatch):
    from testbench.world.procedural.bands import generation_threads

    monkeypatch.setenv("TESTBENCH_WORLD_THREADS", value)
    with pytest.raises(InputError, match="TESTBENCH_WORLD_THREADS.*whole number of threads >= 1"):
        generation_threads()
    monkeypatch.setenv("TESTBENCH_WORLD_THREADS", "2")
    assert generation_threads() == 2


def test_streamed_files_match_make_world(tmp_path, origin):
    import rasterio

    from testbench.world.procedural.writer import write_world, write_world_streamed

    rgb, z, v = make_world("farmland", 1.2, 2.0, 3, "autumn")
    a_img, a_dem = write_world(tmp_path / "a", rgb, z, v, origin, 2.0)
    b_img, b_dem, prev, zr = write_world_streamed(tmp_path / "b", "farmland", 1.2, 2.0, 3, "autumn",
                                                  origin, preview_px=100)
    for pa, pb in ((a_img, b_img), (a_dem, b_dem)):
        with rasterio.open(pa) as ra, rasterio.open(pb) as rb:
            assert ra.transform == rb.transform and ra.crs == rb.crs and ra.shape == rb.shape
            assert np.array_equal(ra.read(), rb.read())
    assert prev.shape == (100, 100, 3) and abs(zr[0] - float(z.min())) < 1e-4
    c_img, _, _, _ = write_world_streamed(tmp_path / "c", "farmland", 1.2, 2.0, 3, "autumn", origin)
    assert hashlib.sha256(open(b_img, "rb").read()).digest() == hashlib.sha256(open(c_img, "rb").read()).digest()


def test_elevation_window_is_clipped_to_the_dem(tmp_path, origin):
    """A horizontal camera asks for terrain out to its far clip (tens of km); the run's world
    reads only what the DEM covers, once, and serves later requests from that window."""
    from testbench.config.schema import Origin, World
    from testbench.sim.world_runtime import RunWorld

    spec = "procedural:canyon?seed=2&size_km=0.5&gsd_m=4"
    world = World(origin=Origin(lat_deg=float(np.degrees(origin.lat_rad)), lon_deg=float(np.degrees(origin.lon_rad)),
                                alt_m=origin.alt_m), imagery=spec, elevation=spec)
    run_world = RunWorld(world, origin, cache_dir=tmp_path)
    first = run_world.elevation_for((-20_000.0, 20_000.0, -20_000.0, 20_000.0))
    assert first.shape[0] <= 500 / 4 + 4 and first.shape[1] <= 500 / 4 + 4
    assert run_world.elevation_for((-15_000.0, 30_000.0, -1_000.0, 1_000.0)) is first


def test_imagery_window_is_clipped_to_the_map(tmp_path, origin, monkeypatch):
    """A banked camera's footprint reaches kilometres past the map: the window read for it
    stops a few pixels past the map's edge (a run on a 10 km map read 16856 x 18571 px
    windows before), later requests inside are served from it, a request wholly off the map
    reads only a thin strip of no-data, and margins keep a window within the size cap."""
    from testbench.config.schema import Origin, World
    from testbench.sim.world_runtime import RunWorld

    monkeypatch.setattr(RunWorld, "_WHOLE_MAP_MAX_PX", 50)  # take the windowed path on a small map
    spec = "procedural:farmland?seed=2&size_km=0.5&gsd_m=4"
    world = World(origin=Origin(lat_deg=float(np.degrees(origin.lat_rad)), lon_deg=float(np.degrees(origin.lon_rad)),
                                alt_m=origin.alt_m), imagery=spec)
    run_world = RunWorld(world, origin, cache_dir=tmp_path)
    first = run_world.imagery_for((-150.0, 20_000.0, -100.0, 100.0), 4.0)
    assert first.shape[0] <= 500 / 4 + 2 * 4 + 2 and first.shape[1] <= 500 / 4 + 2 * 4 + 2, first.shape
    assert first.valid.mean() > 0.8
    assert run_world.imagery_for((-100.0, 30_000.0, -50.0, 50.0), 4.0) is first
    off = RunWorld(world, origin, cache_dir=tmp_path).imagery_for((5_000.0, 9_000.0, 5_000.0, 9_000.0), 4.0)
    assert off.shape[0] * off.shape[1] <= 4 and not off.valid.any()
    # A small footprint gets a margin, but the window stays within _WHOLE_MAP_MAX_PX a side.
    small = RunWorld(world, origin, cache_dir=tmp_path).imagery_for((-20.0, 20.0, -20.0, 20.0), 4.0)
    assert max(small.shape) <= 50 + 1 and min(small.shape) > 40 / 4, small.shape


def test_spec_sun_moves_the_shadows_only(tmp_path, origin):
    """sun_azimuth_deg / sun_elevation_deg: the same world under another sun (same relief, the
    layout's edges kept, the shading changed); the season's own world keeps its cache name;
    an elevation outside (0, 90] is an input error naming the key."""
    base = "procedural:farmland?seed=4&season=autumn&size_km=0.5&gsd_m=2"
    spec = parse_spec(base + "&sun_azimuth_deg=150&sun_elevation_deg=62")
    assert spec.canonical().endswith("&sun_azimuth_deg=150&sun_elevation_deg=62")
    assert parse_spec(base).canonical() == base and "sun" not in parse_spec(base).canonical()
    own = open_world_imagery(base, origin, cache_dir=tmp_path)
    moved = open_world_imagery(spec.canonical(), origin, cache_dir=tmp_path)
    assert own.path != moved.path
    a = own.read_local(-250, 250, -250, 250, 2.0).data
    b = moved.read_local(-250, 250, -250, 250, 2.0).data
    assert np.abs(a.astype(int) - b.astype(int)).mean() > 0.5  # the shading moved
    corr = np.corrcoef(_grad(a).ravel(), _grad(b).ravel())[0, 1]
    assert corr > 0.7, corr  # the layout did not
    z0 = open_elevation(base, origin, cache_dir=tmp_path).height_m(10.0, -20.0)
    assert open_elevation(spec.canonical(), origin, cache_dir=tmp_path).height_m(10.0, -20.0) == z0
    with pytest.raises(InputError, match="sun_elevation_deg"):
        parse_spec(base + "&sun_elevation_deg=95")


def test_flat_elevation_specs(tmp_path, origin):
    """'flat' and 'flat:H' are flat ground H m above the origin; anything else after 'flat:'
    is one clear error naming the key; a file named flat... is a file."""
    assert open_elevation("flat", origin).height_at(10.0, 20.0) == 0.0
    assert open_elevation(" FLAT:-12.5 ", origin).height_m([0.0, 5.0], 1.0).tolist() == [-12.5, -12.5]
    for bad in ("flat:abc", "flat:nan", "flat:inf"):
        with pytest.raises(InputError, match=rf"world.reference_elevation '{bad}': expected 'flat' or 'flat:HEIGHT_M'"):
            open_elevation(bad, origin, what="world.reference_elevation")
    with pytest.raises(InputError, match=r"world.elevation '.*flat_dem.tif': no such file"):
        open_elevation(str(tmp_path / "flat_dem.tif"), origin, what="world.elevation")
    with pytest.raises(InputError, match=r"^elevation 'flatdem.tif': no such file"):
        open_elevation("flatdem.tif", origin)
