"""GeoTIFF maps on the local grid: georeference round trips in UTM and EPSG:4326, pixel-centre
conventions, nodata masks, window reads vs full reads, error messages."""

import math

import numpy as np
import pytest
from rasterio.transform import from_origin

from testbench.core.errors import InputError
from testbench.world.elevation import ElevationModel, FlatElevation
from testbench.world.imagery import MapSource
from testbench.world.georef import LocalFrame
import rasterio


def write_tif(path, data, crs, transform, nodata=None, dtype=None):
    """data (C, H, W) or (H, W)."""
    a = data if data.ndim == 3 else data[None]
    prof = dict(driver="GTiff", width=a.shape[2], height=a.shape[1], count=a.shape[0],
                dtype=dtype or a.dtype.name, transform=transform)
    if crs is not None:
        prof["crs"] = crs
    if nodata is not None:
        prof["nodata"] = nodata
    with rasterio.open(path, "w", **prof) as dst:
        dst.write(a)
    return str(path)



def _ramp(h, w):
    """3 bands whose values encode the pixel: R = col, G = row, B = 7."""
    r = np.tile(np.arange(w, dtype=np.uint8), (h, 1))
    g = np.tile(np.arange(h, dtype=np.uint8)[:, None], (1, w))
    return np.stack([r, g, np.full((h, w), 7, np.uint8)])


@pytest.mark.parametrize("crs", ["EPSG:32614", "EPSG:4326"])
def test_sample_known_pixel_centres(tmp_path, origin, crs):
    frame = LocalFrame(origin, crs)
    h, w = 120, 150
    if crs == "EPSG:4326":
        res = 2.0e-5  # deg (~1.5-2.2 m)
    else:
        res = 2.0
    x0, y0 = frame.ne_to_xy(0.0, 0.0)
    left, top = float(x0) - 40 * res, float(y0) + 50 * res
    path = write_tif(tmp_path / "m.tif", _ramp(h, w), crs, from_origin(left, top, res, res))
    m = MapSource(path, origin)
    rows = np.array([0, 10, 50, 77, 119])
    cols = np.array([0, 33, 40, 140, 149])
    x = left + (cols + 0.5) * res
    y = top - (rows + 0.5) * res
    n, e = frame.xy_to_ne(x, y)
    v, ok = m.sample(n, e)
    assert ok.all()
    np.testing.assert_allclose(v[:, 0], cols, atol=1e-6)
    np.testing.assert_allclose(v[:, 1], rows, atol=1e-6)
    # half a pixel inside, bilinear midway
    n2, e2 = frame.xy_to_ne(left + 11.0 * res, top - 21.0 * res)
    v2, ok2 = m.sample(n2, e2)
    np.testing.assert_allclose(v2[..., :2], [10.5, 20.5], atol=1e-6)
    # read_local puts the same values at the same local points (cv2.remap: 1/32 px)
    raster = m.read_local(float(n.min()) - 20, float(n.max()) + 20, float(e.min()) - 20,
                          float(e.max()) + 20, 1.0)
    from testbench.world.raster import sample_bilinear
    vv, okk = sample_bilinear(raster, n[1:4], e[1:4])
    assert okk.all()
    np.testing.assert_allclose(vv[:, 0], cols[1:4], atol=0.15)
    np.testing.assert_allclose(vv[:, 1], rows[1:4], atol=0.15)
    # the map's footprint contains the origin, and off-map points are invalid
    fp = m.footprint
    assert fp.north_min_m < 0 < fp.north_max_m and fp.east_min_m < 0 < fp.east_max_m
    _, ok3 = m.sample([fp.north_max_m + 10.0], [0.0])
    assert not ok3.any()


def test_local_frame_round_trip(origin):
    for crs in ("EPSG:32614", "EPSG:4326", "EPSG:3857"):
        f = LocalFrame(origin, crs)
        n = np.array([-4000.0, 0.0, 1234.5])
        e = np.array([2500.0, 0.0, -3000.0])
        n2, e2 = f.xy_to_ne(*f.ne_to_xy(n, e))
        np.testing.assert_allclose(n2, n, atol=5e-3)  # millimetres over 5 km
        np.testing.assert_allclose(e2, e, atol=5e-3)


def test_utm_north_is_local_north_near_origin(tmp_path, origin):
    # A UTM map: moving one pixel up the image moves north by ~res (grid convergence small).
    f = LocalFrame(origin, "EPSG:32614")
    x, y = f.ne_to_xy(0.0, 0.0)
    n, e = f.xy_to_ne(x, y + 100.0)
    assert abs(n - 100.0) < 1.5 and abs(e) < 3.0


def test_nodata_mask_and_window_vs_full(tmp_path, origin):
    f = LocalFrame(origin, "EPSG:32614")
    x0, y0 = f.ne_to_xy(0.0, 0.0)
    rng = np.random.default_rng(1)
    data = rng.integers(1, 255, (3, 200, 200)).astype(np.uint8)
    data[:, 50:60, 70:90] = 0
    path = write_tif(tmp_path / "n.tif", data, "EPSG:32614", from_origin(float(x0) - 200, float(y0) + 200, 2.0, 2.0), nodata=0)
    m = MapSource(path, origin)
    full = m.read_local(-220, 220, -220, 220, 2.0)
    # the nodata block maps to invalid pixels; off-map border invalid; centre valid
    assert not full.valid[:5].any() or full.valid.mean() < 1
    n_hole, e_hole = f.xy_to_ne(float(x0) - 200 + 80 * 2.0 + 1, float(y0) + 200 - 55 * 2.0 - 1)
    r, c = full.ne_to_rowcol(n_hole, e_hole)
    assert not full.valid[int(round(float(r))), int(round(float(c)))]
    assert full.valid[110, 110]
    v, ok = m.sample(n_hole, e_hole)
    assert not ok
    # a sub-window on the same grid equals the corresponding part of the full read
    sub = m.read_local(-100, 60, -40, 140, 2.0)
    r0 = int(round((full.north0_m - sub.north0_m) / 2.0))
    c0 = int(round((sub.east0_m - full.east0_m) / 2.0))
    part = full.data[r0:r0 + sub.shape[0], c0:c0 + sub.shape[1]]
    both = sub.valid & full.valid[r0:r0 + sub.shape[0], c0:c0 + sub.shape[1]]
    diff = np.abs(part.astype(int) - sub.data.astype(int))[both]
    assert diff.max() <= 1
    # coarse (decimated) read: mean brightness preserved
    coarse = m.read_local(-180, 180, -180, 180, 8.0)
    fine = m.read_local(-180, 180, -180, 180, 2.0)
    assert abs(coarse.data[coarse.valid].mean() - fine.data[fine.valid].mean()) < 3.0


def test_errors(tmp_path, origin):
    with pytest.raises(InputError, match="no such file"):
        MapSource(tmp_path / "missing.tif", origin)
    p = write_tif(tmp_path / "nogeo.tif", np.zeros((3, 10, 10), np.uint8), None,
                  rasterio.Affine.identity())
    with pytest.raises(InputError) as ei:
        MapSource(p, origin)
    msg = str(ei.value)
    assert "no georeference" in msg and "gdal_translate -a_srs" in msg and "\n" not in msg
    bad = tmp_path / "bad.tif"
    bad.write_text("not a tiff")
    with pytest.raises(InputError, match="not a readable raster"):
        MapSource(bad, origin)


def test_grey_and_elevation(tmp_path, origin):
    f = LocalFrame(origin, "EPSG:4326")
    lon, lat = f.ne_to_lonlat_deg(0.0, 0.0)
    res = 1e-4
    z = np.full((50, 60), 600.0, np.float32)
    z[:, 30:] = 650.0
    z[0:5, 0:5] = -32767
    p = write_tif(tmp_path / "dem.tif", z.astype(np.int16), "EPSG:4326",
                  from_origin(float(lon) - 30 * res, float(lat) + 25 * res, res, res), nodata=-32767)
    dem = ElevationModel(p, origin)
    hgt, ok = dem.height_and_valid([0.0, 0.0, 1e5], [-200.0, 200.0, 0.0])
    np.testing.assert_allclose(hgt[:2], [100.0, 150.0], atol=1e-3)  # DEM minus origin altitude
    assert list(ok) == [True, True, False] and hgt[2] == 0.0
    r = dem.read_local(-150, 150, -150, 150, 10.0)
    assert r.data.dtype == np.float32 and r.valid.any()
    assert FlatElevation(3.0).height_m([1.0, 2.0], 0.0).tolist() == [3.0, 3.0]
    g = write_tif(tmp_path / "g.tif", np.full((1, 20, 20), 99, np.uint8), "EPSG:4326",
                  from_origin(float(lon) - 10 * res, float(lat) + 10 * res, res, res))
    v, ok = MapSource(g, origin).sample(0.0, 0.0)
    assert ok and v.tolist() == [99.0, 99.0, 99.0]


def _reference_bilinear(data, valid, row, col):
    """Bilinear by the textbook formula, point by point (two-index lookups), with the
    validity rule of sample_bilinear: the reference the vectorised paths are held to."""
    h, w = data.shape[:2]
    out, good = [], []
    for r, c in zip(np.ravel(row), np.ravel(col)):
        if not (0 <= r <= h - 1 and 0 <= c <= w - 1):
            out.append(np.zeros(data.shape[2:]))
            good.append(False)
            continue
        r0, c0 = min(int(math.floor(r)), max(h - 2, 0)), min(int(math.floor(c)), max(w - 2, 0))
        fr, fc = r - r0, c - c0
        v, ok = np.zeros(data.shape[2:]), True
        for wt, ri, ci in (((1 - fr) * (1 - fc), r0, c0), ((1 - fr) * fc, r0, min(c0 + 1, w - 1)),
                           (fr * (1 - fc), min(r0 + 1, h - 1), c0), (fr * fc, min(r0 + 1, h - 1), min(c0 + 1, w - 1))):
            v = v + data[ri, ci].astype(np.float64) * wt
            ok = ok and (bool(valid[ri, ci]) or wt <= 0.0)
        out.append(v if ok else np.zeros(data.shape[2:]))
        good.append(ok)
    return np.array(out), np.array(good)


@pytest.mark.parametrize("gaps", [True, False], ids=["masked pixels", "no gaps"])
@pytest.mark.parametrize("shape", [(40, 50), (40, 50, 3), (1, 6), (2, 2)])
def test_bilinear_paths_give_the_same_values_bit_for_bit(shape, gaps):
    """bilinear_at_rowcol (on C- and Fortran-ordered data) and the one-point path (the
    dynamics' terrain) give the reference values exactly (the same bits, the sign of a zero
    included), and the same validity, at edges, in masked pixels, off the grid and at NaN; and
    on points all inside the grid (where the vectorised path skips its off-grid handling)."""
    from testbench.world.raster import bilinear_at_rowcol, bilinear_point

    rng = np.random.default_rng(4)
    data = rng.normal(0, 50, shape).astype(np.float32) if len(shape) == 2 else rng.integers(0, 255, shape, dtype=np.uint8)
    valid = rng.random(shape[:2]) > 0.15 if gaps else np.ones(shape[:2], bool)
    row = np.concatenate([rng.uniform(-2, shape[0] + 1, 400), np.arange(-1, shape[0] + 1, 0.5), [np.nan, 0.0]])
    col = np.concatenate([rng.uniform(-2, shape[1] + 1, 400), np.linspace(-1, shape[1] + 1, 2 * shape[0] + 4), [1.0, np.nan]])
    ref, ref_ok = _reference_bilinear(data, valid, row, col)
    assert ref_ok.any() and not ref_ok.all()
    inside = np.flatnonzero((row >= 0) & (col >= 0) & (row <= shape[0] - 1) & (col <= shape[1] - 1))
    for d in (data, np.asfortranarray(data)):
        for sel in (slice(None), inside):
            v, ok = bilinear_at_rowcol(d, valid, row[sel], col[sel])
            assert v.dtype == np.float64 and np.array_equal(ok, ref_ok[sel])
            assert np.array_equal(v.view(np.int64), ref[sel].view(np.int64))
    # Broadcast (row, col) keep their grid's shape.
    v, ok = bilinear_at_rowcol(data, valid, row[:7, None], col[None, :5])
    want, want_ok = _reference_bilinear(data, valid, *np.broadcast_arrays(row[:7, None], col[None, :5]))
    assert v.shape == (7, 5) + shape[2:] and np.array_equal(v.reshape(want.shape), want)
    assert np.array_equal(ok.ravel(), want_ok)
    if len(shape) == 2:
        for r, c, want, want_ok in zip(row, col, ref, ref_ok):
            got, got_ok = bilinear_point(data, valid, float(r), float(c))
            assert got_ok == want_ok and got == want, (r, c)


def test_height_at_is_height_m_at_one_point(tmp_path, origin):
    """ElevationModel.height_at (one point, the dynamics' per-step terrain) gives height_m's
    value exactly: across tiles, in nodata, off the DEM and at a non-finite point."""
    f = LocalFrame(origin, "EPSG:4326")
    lon, lat = f.ne_to_lonlat_deg(0.0, 0.0)
    res = 1e-5  # about 1 m: 600 x 500 pixels span several 256-pixel tiles
    rng = np.random.default_rng(2)
    z = (600.0 + 40.0 * rng.random((500, 600))).astype(np.float32)
    z[100:140, 200:260] = -32767
    p = write_tif(tmp_path / "dem.tif", z, "EPSG:4326",
                  from_origin(float(lon) - 300 * res, float(lat) + 250 * res, res, res), nodata=-32767)
    dem = ElevationModel(p, origin, outside_height_m=-5.0)
    n, e = rng.uniform(-400, 400, 600), rng.uniform(-450, 450, 600)
    want, ok = dem.height_and_valid(n, e)
    assert ok.any() and not ok.all()
    got = [dem.height_at(a, b) for a, b in zip(n, e)]
    assert all(type(g) is float for g in got) and np.array_equal(got, want)
    assert dem.height_at(math.nan, 0.0) == -5.0 and dem.height_at(0.0, math.inf) == -5.0
    assert FlatElevation(3.0).height_at(1.0, 2.0) == 3.0


def _local_grid_tif(tmp_path, origin, bands, kind):
    """A raster written on the local grid itself (as the procedural worlds are), 1.5 m, 60 x 80
    px: (path, band list); kind "plain", "masked" (uint8 with an internal mask) or "nodata"
    (float32 with nodata)."""
    from testbench.world.procedural.writer import write_geotiff

    rng = np.random.default_rng(3)
    valid = np.ones((60, 80), bool)
    if kind != "plain":
        valid[10:20, 5:30] = False
        valid[:, 79] = False  # a gap along the east edge
    if kind == "nodata":
        arr = rng.normal(400.0, 30.0, (60, 80)).astype(np.float32)
        write_geotiff(tmp_path / "z.tif", arr, origin, 1.5, valid=valid)
        return str(tmp_path / "z.tif"), [1]
    arr = rng.integers(1, 256, (60, 80, bands)).astype(np.uint8)
    write_geotiff(tmp_path / "m.tif", arr, origin, 1.5, valid=valid if kind == "masked" else None)
    return str(tmp_path / "m.tif"), list(range(1, bands + 1))


@pytest.mark.parametrize("kind,bands", [("plain", 3), ("masked", 3), ("nodata", 1), ("plain", 5)])
def test_a_read_on_the_maps_own_grid_copies_what_the_remap_gives_bit_for_bit(tmp_path, origin, monkeypatch, kind, bands):
    """A window on an 8-bit raster's own pixel grid (whole pixels from its corner, at its gsd) is
    copied, not remapped: the same bits and validity as the remap, inside, over each edge and
    corner and beyond the map; a grid half a pixel off, or finer, is still remapped, and so is
    float data (cv2 interpolates it at the exact coordinates, a few 1e-6 px off the pixels)."""
    import testbench.world.geotiff as geotiff

    path, band_list = _local_grid_tif(tmp_path, origin, bands, kind)
    reader = geotiff.GeoRasterReader(path, origin, band_list, what="test raster")
    taken = []
    shift = geotiff._integer_shift
    monkeypatch.setattr(geotiff, "_integer_shift", lambda *a: taken.append(shift(*a)) or taken[-1])
    # (north0_m, east0_m, gsd_m, height, width): the map spans north +-45 m, east +-60 m
    on_grid = [(30.0, -45.0, 1.5, 20, 30), (45.0, -60.0, 1.5, 60, 80), (52.5, -67.5, 1.5, 75, 100),
               (-33.0, 51.0, 1.5, 16, 16), (48.0, 30.0, 1.5, 10, 40), (0.0, -90.0, 1.5, 30, 40)]
    off_grid = [(30.75, -45.0, 1.5, 20, 30), (30.0, -45.0, 0.75, 40, 60)]
    for box in on_grid + off_grid:
        taken.clear()
        fast = reader.read_grid(*box)
        assert (bool(taken) and taken[0] is not None) == (box in on_grid and kind != "nodata"), box
        monkeypatch.setattr(geotiff, "_integer_shift", lambda *a: None)
        slow = reader.read_grid(*box)
        monkeypatch.setattr(geotiff, "_integer_shift", lambda *a: taken.append(shift(*a)) or taken[-1])
        assert fast[0].dtype == slow[0].dtype and fast[0].tobytes() == slow[0].tobytes(), box
        assert np.array_equal(fast[1], slow[1]), box
        if box in on_grid:
            assert fast[1].any() and (kind != "plain" or box[3:] != (60, 80) or fast[1].all()), box


def test_a_run_world_names_the_key_of_a_bad_map(tmp_path, origin):
    """A scenario's map that cannot be opened is named by its world key, so that a scenario
    with several maps says which one is wrong."""
    from testbench.config.schema import World
    from testbench.sim.world_runtime import RunWorld

    bad = tmp_path / "bad.tif"
    bad.write_text("not a tiff")
    good = write_tif(tmp_path / "good.tif", np.zeros((3, 10, 10), np.uint8), "EPSG:4326",
                     rasterio.Affine(1e-5, 0, 7.0, 0, -1e-5, 45.0))
    o = {"lat_deg": 45.0, "lon_deg": 7.0, "alt_m": 0.0}
    cases = [
        ({"imagery": str(good), "reference_map": str(bad)}, "reference_map", "world.reference_map '"),
        ({"imagery": str(bad)}, "reference_map", r"world.imagery \(the reference map too\) '"),
        ({"imagery": str(bad)}, "imagery", "world.imagery '"),
        ({"elevation": str(bad)}, "elevation", "world.elevation '"),
        ({"elevation": str(good), "reference_elevation": str(tmp_path / "none.tif")}, "reference_elevation",
         "world.reference_elevation '.*none.tif': no such file"),
        ({"elevation": str(bad)}, "reference_elevation", r"world.elevation \(the reference elevation too\) '"),
    ]
    for keys, opener, message in cases:
        with pytest.raises(InputError, match=message):
            getattr(RunWorld(World(origin=o, **keys), origin), opener)()
