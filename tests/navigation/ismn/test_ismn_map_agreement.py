"""ismn.map_agreement: the displacement between two maps of one place, tile by tile. Two seasons
of a synthetic world, one displaced by a known shift or field, give back that shift and that
field; two real NAIP years agree to a metre or two; maps of two places are refused."""

from __future__ import annotations

import json

import numpy as np

from testbench.cli import main
from testbench.navigation.ismn.map_agreement import map_agreement
from testbench.navigation.ismn.synth import RasterMapSource
from testbench.world.map_error import DisplacedMap, MapDisplacement

BOUNDS = (-1800.0, 1800.0, -1800.0, 1800.0)


def test_a_shifted_season_reads_as_its_shift(seasons):
    summer, winter = seasons
    shifted = DisplacedMap(RasterMapSource(winter), MapDisplacement((6.0, -4.0), 0.0, 1000.0, None, np.random.default_rng(0)))
    res = map_agreement(RasterMapSource(summer), shifted, BOUNDS, 4.0, tile_m=400.0, search_m=25.0)
    s = res.summary()
    assert s["tiles_inliers"] >= 0.8 * s["tiles_tried"] >= 0.8 * 81
    np.testing.assert_allclose(s["mean_offset_ne_m"], [6.0, -4.0], atol=0.4)
    assert max(s["rms_about_mean_ne_m"]) < 0.3  # the tiles' own noise across seasons (0.08 m when written)


def test_a_displacement_field_is_read_tile_by_tile(seasons):
    summer, winter = seasons
    disp = MapDisplacement((0.0, 0.0), 5.0, 1200.0, (-2400.0, 2400.0, -2400.0, 2400.0), np.random.default_rng(2))
    res = map_agreement(RasterMapSource(summer), DisplacedMap(RasterMapSource(winter), disp), BOUNDS, 4.0,
                        tile_m=300.0, search_m=30.0)
    keep = res.inliers()
    d_n, d_e = disp.at(res.centre_ne_m[keep, 0], res.centre_ne_m[keep, 1])
    truth = np.stack([d_n, d_e], axis=1)
    assert keep.sum() >= 100 and np.ptp(truth) > 10.0
    resid = res.offset_ne_m[keep] - truth
    assert float(np.sqrt(np.mean(resid**2))) < 0.5  # 0.22 m when written, against a 5.2 / 3.9 m field
    assert res.summary()["correlation_length_m"] > 300.0  # a field, not the tiles' white noise


def test_two_naip_years_agree_to_metres(realdata, capsys, tmp_path):
    d = realdata / "naip_nd"
    code = main(["ismn", "map-agreement", str(d / "m_4709963_se_14_1_20160816.tif"),
                 str(d / "m_4709963_se_14_1_20180716.tif"), "--plot", str(tmp_path / "tiles.png"),
                 "--tiles", str(tmp_path / "tiles.csv")])
    assert code == 0
    s = json.loads(capsys.readouterr().out)
    rows = (tmp_path / "tiles.csv").read_text().splitlines()
    assert len(rows) == 1 + s["tiles_matched"] and sum(r.endswith(",1") for r in rows) == s["tiles_inliers"]
    assert (tmp_path / "tiles.png").read_bytes()[:4] == b"\x89PNG"
    # Measured when written (5 m NAIP, 400 m tiles): 55 of 70 tiles, shift (-1.20, -0.58) m,
    # 1.8 m RMS per axis about it, uncorrelated from one tile to the next.
    assert s["tiles_inliers"] >= 40
    assert np.hypot(*s["mean_offset_ne_m"]) < 3.0 and max(s["rms_about_mean_ne_m"]) < 3.0


def test_maps_of_two_places_are_refused(realdata, capsys):
    code = main(["ismn", "map-agreement", str(realdata / "naip_nd" / "m_4709963_se_14_1_20160816.tif"),
                 str(realdata / "naip_mcmillan" / "mcmillan_naip2016_utm10n.tif")])
    err = capsys.readouterr().err
    assert code == 2 and "share less than one" in err and "Traceback" not in err
