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
