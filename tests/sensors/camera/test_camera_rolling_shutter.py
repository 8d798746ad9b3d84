"""The camera's rolling shutter (CameraParams.readout_s): rows exposed one after another, each
from the true pose of its own time, rendered in bands and stitched."""

from __future__ import annotations

import numpy as np
import pydantic
import pytest
from conftest import raster, textured
from test_camera_sensor import TinyWorld
from test_camera_sensor import _sensor as camera_sensor

from testbench.sensors.camera import CameraSensor
from testbench.sensors.camera.rolling_shutter import row_delay_s, split_rows
from testbench.sensors.fakes import make_truth


class OneMapWorld(TinyWorld):
    """TinyWorld over a map of one's own (flat ground at the origin's height)."""

    def __init__(self, data: np.ndarray, gsd_m: float, requests=None):
        super().__init__(requests)
        self.map = raster(data, gsd_m)


def _sensor(**kw) -> CameraSensor:
    return camera_sensor(**{"noise_std": 0.0, **kw})


def _dot_map(north_m: float, east_m: float, gsd_m: float = 0.25, n: int = 1200) -> np.ndarray:
    """(n, n, 3) uint8: dark ground with one bright Gaussian dot (sigma 2 m) at (north, east) of
    a map centred on the origin."""
    rows, cols = np.mgrid[0:n, 0:n]
    north = (0.5 * n - rows - 0.5) * gsd_m
    east = (cols + 0.5 - 0.5 * n) * gsd_m
    dot = np.exp(-((north - north_m) ** 2 + (east - east_m) ** 2) / (2 * 2.0**2))
    return np.repeat((20 + 220 * dot).astype(np.uint8)[..., None], 3, axis=2)


def _centroid_row(image: np.ndarray) -> float:
    w = np.clip(image[..., 0].astype(float) - 40.0, 0.0, None)
    return float((w.sum(axis=1) * np.arange(image.shape[0])).sum() / w.sum())


def test_row_delays_and_bands():
    assert row_delay_s(44.5, 90, 0.03) == pytest.approx(0.0)  # the middle row is the frame's time
    assert row_delay_s(0, 90, 0.03) == pytest.approx(-0.015 + 0.015 / 90)
    assert row_delay_s(89, 90, 0.03) == pytest.approx(0.015 - 0.015 / 90)
    bands = split_rows((0, 0, 160, 90), 90, 24)
    assert bands[0][1] == 0 and bands[-1][3] == 90 and len(bands) == 24
    assert all(a[3] == b[1] for a, b in zip(bands[:-1], bands[1:]))  # contiguous, no row twice
    assert split_rows((10, 40, 50, 48), 90, 24) == [(10, 40, 50, 44), (10, 44, 50, 48)]  # a region: its share


def test_a_still_camera_sees_the_same_frame_with_either_shutter():
    world = OneMapWorld(textured(512), 2.0)
    truth = make_truth(1.0, pos_ned_m=(0.0, 0.0, -100.0))
    glob = _sensor().measure(truth, world, np.random.default_rng(0))
    roll = _sensor(readout_s=0.03).measure(truth, world, np.random.default_rng(0))
    diff = np.abs(glob.image.astype(int) - roll.image.astype(int))
    assert roll.image.shape == glob.image.shape and roll.regions[0].roi is None
    assert diff.max() <= 1 and diff.mean() < 0.02  # only the bands' own resampling rounding
    assert np.array_equal(roll.regions[0].valid, glob.regions[0].valid)


@pytest.mark.parametrize("dot_north_m", [40.0, -40.0])
def test_each_row_sees_from_where_the_vehicle_was_when_it_was_exposed(dot_north_m):
    """Flying north at 100 m/s, 100 m up, a 90 ms readout: a dot 40 m north (near the frame's
    top edge: exposed early, the vehicle then about 3 m further south) shows about 2.5 px
    further north than a global shutter shows it, one 40 m south as far south; the row it
    lands on solves v = v_global(pose at the time of row v)."""
    speed, height, readout = 100.0, 100.0, 0.09
    world = OneMapWorld(_dot_map(dot_north_m, 0.0), 0.25)
    truth = make_truth(1.0, pos_ned_m=(0.0, 0.0, -height), vel_ned_mps=(speed, 0.0, 0.0))
    cam = _sensor(readout_s=readout, readout_bands=90)  # one band per row: the exact rolling shutter
    glob = _sensor().measure(truth, world, np.random.default_rng(0))
    roll = cam.measure(truth, world, np.random.default_rng(0))
    fy, cy = cam.camera.fy, cam.camera.cy
    v = cy - fy * dot_north_m / height  # global shutter (image top is north at zero yaw)
    v_glob = v
    for _ in range(20):  # the rolling shutter's row: the vehicle at the row's own time
        v = cy - fy * (dot_north_m - speed * float(row_delay_s(v, 90, readout))) / height
    assert _centroid_row(glob.image) == pytest.approx(v_glob, abs=0.15)
    assert _centroid_row(roll.image) == pytest.approx(v, abs=0.15)
    assert abs(v - v_glob) > 2.0  # the test sees the effect it claims


def test_a_region_keeps_its_box_and_a_readout_as_long_as_the_frame_interval_is_refused():
    world = OneMapWorld(textured(512), 2.0, requests=[(20, 10, 80, 50)])
    truth = make_truth(1.0, pos_ned_m=(0.0, 0.0, -100.0), vel_ned_mps=(25.0, 0.0, 0.0))
    frame = _sensor(readout_s=0.03).measure(truth, world, np.random.default_rng(0))
    (region,) = frame.regions
    assert region.roi == (20, 10, 80, 50) and region.image.shape == (40, 60, 3) and frame.image is None
    with pytest.raises(pydantic.ValidationError, match="readout_s 0.09 s must be shorter than the frame interval"):
        CameraSensor.Params(width_px=160, height_px=90, hfov_deg=90.0, rate_hz=12.5, readout_s=0.09)
