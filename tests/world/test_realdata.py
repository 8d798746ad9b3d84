"""Real rasters (TESTBENCH_DATA): NAIP North Dakota 2016/2018 (UTM 14N, NAD83), McMillan
(UTM 10N), the two DEMs. Skipped with a message when the data folder is absent."""

import math
import os

import numpy as np
import pyproj
import pytest
import rasterio

from testbench.core.interfaces import GeodeticOrigin
from testbench.world.elevation import ElevationModel
from testbench.world.imagery import MapSource

DATA = os.environ.get("TESTBENCH_DATA")
pytestmark = [pytest.mark.realdata,
              pytest.mark.skipif(not DATA or not os.path.isdir(DATA),
                                 reason="TESTBENCH_DATA not set or absent: real-data tests skipped")]


def _origin_inside(path, alt=0.0, fx=0.5, fy=0.5):
    with rasterio.open(path) as ds:
        b = ds.bounds
        x, y = b.left + fx * (b.right - b.left), b.bottom + fy * (b.top - b.bottom)
        lon, lat = pyproj.Transformer.from_crs(ds.crs, 4326, always_xy=True).transform(x, y)
    return GeodeticOrigin(math.radians(lat), math.radians(lon), alt)


@pytest.mark.parametrize("name", ["m_4709963_se_14_1_20160816.tif", "m_4709963_se_14_1_20180716.tif"])
def test_naip_nd(name):
    path = os.path.join(DATA, "naip_nd", name)
    o = _origin_inside(os.path.join(DATA, "naip_nd", "m_4709963_se_14_1_20160816.tif"), 500.0)
    m = MapSource(path, o)
    assert 4.9 < m.native_gsd_m < 5.1
    fp = m.footprint
    assert 4500 < fp.east_max_m - fp.east_min_m < 4900 and 3400 < fp.north_max_m - fp.north_min_m < 3800
    r = m.read_local(-1000, 1000, -1000, 1000, 5.0)
    assert r.data.shape == (400, 400, 3) and r.valid.all() and r.data.std() > 10
    big = m.read_local(-3000, 3000, -3000, 3000, 10.0)  # beyond the map north/south/east/west
    assert big.valid[big.shape[0] // 2, big.shape[1] // 2]
    assert not big.valid[0].any() and not big.valid[:, 0].any() and not big.data[0].any()


def test_nd_years_register_within_metres():
    o = _origin_inside(os.path.join(DATA, "naip_nd", "m_4709963_se_14_1_20160816.tif"))
    a = MapSource(os.path.join(DATA, "naip_nd", "m_4709963_se_14_1_20160816.tif"), o)
    b = MapSource(os.path.join(DATA, "naip_nd", "m_4709963_se_14_1_20180716.tif"), o)
    assert np.allclose(a.footprint.corners_ne_m, b.footprint.corners_ne_m, atol=20.0)


def test_mcmillan():
    path = os.path.join(DATA, "naip_mcmillan", "mcmillan_naip2016_utm10n.tif")
    o = _origin_inside(path, 300.0)
    m = MapSource(path, o)
    assert 0.78 < m.native_gsd_m < 0.84
    r = m.read_local(-500, 500, -500, 500, 1.0)
    assert r.valid.all() and r.data.shape == (1000, 1000, 3)
    coarse = m.read_local(-2000, 2000, -2000, 2000, 8.0)  # decimated, map edges inside
    assert 0.3 < coarse.valid.mean() < 0.6
    v, ok = m.sample([0.0, 5000.0], [0.0, 0.0])
    assert ok.tolist() == [True, False]


def test_dems():
    for name, lo, hi in (("mt_diablo_dem_28m_utm10n.tif", 0.0, 1200.0),
                         ("sainthelens_dem_30m.tif", 600.0, 2600.0)):
        path = os.path.join(DATA, "dem", name)
        o = _origin_inside(path, 100.0)
        dem = ElevationModel(path, o)
        h, ok = dem.height_and_valid(np.linspace(-2000, 2000, 9), np.zeros(9))
        assert ok.all()
        assert (h + 100.0 > lo).all() and (h + 100.0 < hi).all()
        r = dem.read_local(-3000, 3000, -3000, 3000, 30.0)
        assert r.data[r.valid].min() + 100.0 > lo - 1
