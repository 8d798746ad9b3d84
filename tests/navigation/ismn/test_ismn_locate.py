"""`testbench locate` on a NAIP 2018 'photo' against the 2016 map (real data), and bad input."""

from __future__ import annotations

import argparse
import json
import math

import cv2
import numpy as np
import pytest

from testbench.commands import locate
from testbench.core.camera_geometry import PinholeCamera, CameraMount, mount_rotation
from testbench.core.errors import InputError
from testbench.core.geodesy import ned_to_geodetic, geodetic_to_ned
from testbench.core.interfaces import GeodeticOrigin
from testbench.core.rotations import euler_to_dcm
from testbench.navigation.ismn.synth import render_plane_frame
from testbench.world.geotiff import map_centre_lat_lon_deg
from testbench.world.imagery import MapSource


def _parse(argv):
    ap = argparse.ArgumentParser()
    locate.register(ap.add_subparsers(dest="cmd"))
    return ap.parse_args(["locate", *argv])


def _write_camera(tmp_path):
    cam_yaml = tmp_path / "cam.yaml"
    cam_yaml.write_text("width: 640\nheight: 360\nhfov_deg: 120\nmount_pitch_deg: -90\n")
    return cam_yaml


def test_bad_attitude_is_input_error(tmp_path):
    args = _parse(["--map", "x.tif", "--image", "x.png", "--camera", str(_write_camera(tmp_path)),
                   "--altitude-agl-m", "800", "--attitude-deg", "1,2"])
    with pytest.raises(InputError, match="--attitude-deg"):
        args.handler(args)


def test_bad_camera_key_is_input_error(tmp_path):
    (tmp_path / "c.yaml").write_text("width: 10\nheight: 10\nhfov: 90\n")
    with pytest.raises(InputError, match="unknown key 'hfov'"):
        locate.load_camera(str(tmp_path / "c.yaml"))


def _blank_map_and_photo(tmp_path):
    """A georeferenced 2 x 2 km map of one grey (no feature to match) at 47 N, 99 W, and a
    grey photo of the camera's size."""
    import rasterio
    from rasterio.transform import from_origin

    path = tmp_path / "map.tif"
    with rasterio.open(path, "w", driver="GTiff", width=400, height=400, count=3, dtype="uint8",
                       crs="EPSG:32614", transform=from_origin(500000.0, 5206000.0, 5.0, 5.0)) as ds:
        ds.write(np.full((3, 400, 400), 128, np.uint8))
    cv2.imwrite(str(tmp_path / "photo.png"), np.full((360, 640, 3), 128, np.uint8))
    return ["--map", str(path), "--image", str(tmp_path / "photo.png"), "--camera", str(_write_camera(tmp_path)),
            "--altitude-agl-m", "800", "--attitude-deg", "0,0,0"]


def test_a_prior_off_the_map_is_input_error(tmp_path):
    argv = _blank_map_and_photo(tmp_path)
    lat, lon = map_centre_lat_lon_deg(tmp_path / "map.tif")
    for prior, radius, message in ((f"{lat + 0.1},{lon}", "300", r"km off the map, beyond --prior-radius-m 300"),
                                   ("95,0", "300", "expected a latitude in"),
                                   (f"{lat},{lon}", "-5", "expected a positive radius")):
        args = _parse(argv + ["--prior-lat-lon", prior, "--prior-radius-m", radius])
        with pytest.raises(InputError, match=message):
            args.handler(args)
    # 11 km north of the map's centre: 10 km off its edge, within a 12 km radius.
    args = _parse(argv + ["--prior-lat-lon", f"{lat + 0.1},{lon}", "--prior-radius-m", "12000"])
    assert args.handler(args) == 3


def test_a_photo_not_found_is_exit_3_with_the_reason(tmp_path, capsys):
    """Not found is an outcome, not a bug (exit 1) nor bad input: found false on stdout and why."""
    argv = _blank_map_and_photo(tmp_path)
    lat, lon = map_centre_lat_lon_deg(tmp_path / "map.tif")
    for extra in ([], ["--prior-lat-lon", f"{lat},{lon}", "--prior-radius-m", "200"]):
        args = _parse(argv + extra)
        assert args.handler(args) == 3
        captured = capsys.readouterr()
        out = json.loads(captured.out)
        assert out["found"] is False and "quality" in out["reason"] and out["reason"] in captured.err


@pytest.mark.realdata
@pytest.mark.parametrize("with_prior", [True, False])
def test_locate_naip_photo(realdata, tmp_path, capsys, with_prior):
    nd = realdata / "naip_nd"
    lat0, lon0 = map_centre_lat_lon_deg(nd / "m_4709963_se_14_1_20160816.tif")
    origin = GeodeticOrigin(math.radians(lat0), math.radians(lon0), 0.0)
    truth = np.array([120.0, -80.0, -800.0])
    rpy = [2.0, -1.0, 20.0]
    cam = PinholeCamera.from_hfov(640, 360, 120.0)
    mount = CameraMount(mount_rotation(0.0, -90.0, 0.0), np.zeros(3))
    with MapSource(nd / "m_4709963_se_14_1_20180716.tif", origin) as m18:
        src = m18.read_local(truth[0] - 2400, truth[0] + 2400, truth[1] - 2400, truth[1] + 2400, 2.5)
    frame = render_plane_frame(src, cam, truth, euler_to_dcm(np.radians(rpy)), mount)
    cv2.imwrite(str(tmp_path / "photo.png"), cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))
    argv = ["--map", str(nd / "m_4709963_se_14_1_20160816.tif"), "--image", str(tmp_path / "photo.png"),
            "--camera", str(_write_camera(tmp_path)), "--altitude-agl-m", "800", "--attitude-deg", "2,-1,20"]
    if with_prior:  # prior 150 m off the truth
        lat, lon, _ = ned_to_geodetic(truth * [1, 1, 0] + [100.0, 110.0, 0.0], origin.lat_rad, origin.lon_rad, 0.0)
        argv += ["--prior-lat-lon", f"{math.degrees(lat)},{math.degrees(lon)}", "--prior-radius-m", "300"]
    args = _parse(argv)
    assert args.handler(args) == 0
    out = json.loads(capsys.readouterr().out)
    ned = geodetic_to_ned(math.radians(out["lat_deg"]), math.radians(out["lon_deg"]), 0.0,
                          origin.lat_rad, origin.lon_rad, 0.0)
    err = float(np.hypot(ned[0] - truth[0], ned[1] - truth[1]))
    # The CLI trusts the given attitude to 1 deg only, so PnP frees it: a few metres (the two
    # NAIP years also differ in georeference by a few metres).
    assert err < 8.0 and err < 3.0 * out["sigma_h_m"], (out, err)
    assert 0 < out["sigma_h_m"] < 10 and out["quality"] > 0.2 and out["time_ms"] > 0
