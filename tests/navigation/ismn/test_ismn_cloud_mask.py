"""The scene matcher's cloud mask (ismn/cloud_mask.py): clouds found from the pixels alone,
their fringe grown over, thin bright ground kept, and the masked pixels no-data to the
orthorectification; a frame the clouds hide is not matched."""

from __future__ import annotations

import cv2
import numpy as np
from test_ismn_pipeline import _pipeline, render_plane_frame

from testbench.core.camera_geometry import PinholeCamera
from testbench.core.rotations import euler_to_dcm
from testbench.navigation.ismn.cloud_mask import CloudMaskParams, cloud_mask
from testbench.navigation.ismn.ortho import Orthorectifier


def _ground(h=360, w=640, seed=0):
    """(h, w, 3) uint8 green-brown fields with texture, darker than any cloud."""
    rng = np.random.default_rng(seed)
    base = cv2.resize(rng.uniform(60, 140, (h // 20, w // 20, 1)).astype(np.float32), (w, h), interpolation=cv2.INTER_NEAREST)
    img = np.stack([base * 0.8, base, base * 0.6], axis=2) + rng.normal(0, 4, (h, w, 3))
    return np.clip(img, 0, 255).astype(np.uint8)


def test_a_cloud_is_masked_with_its_fringe_and_a_bright_road_is_not():
    img = _ground()
    yy, xx = np.mgrid[0:360, 0:640]
    r = np.hypot(yy - 180, xx - 200)
    alpha = np.clip((70.0 - r) / 8.0, 0.0, 1.0)[..., None]  # a 70 px cloud, its fringe 8 px wide
    img = (img * (1 - alpha) + np.array([236, 238, 242]) * alpha).astype(np.uint8)
    img[100:340, 480:485] = (205, 205, 200)  # a road 5 px wide, bright and grey
    m = cloud_mask(img, CloudMaskParams())
    assert m[r < 70].all()  # the cloud and its whole fringe (8 px < the 10 px margin)
    assert not m[r > 85].any() or m[r > 85].mean() < 0.01  # nothing far from it ...
    assert not m[100:340, 478:487].any()  # ... and not the road
    assert not cloud_mask(_ground(), CloudMaskParams()).any()
    grey = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)  # without colour the brightness alone decides
    assert cloud_mask(grey, CloudMaskParams())[r < 60].all()


def test_masked_pixels_are_no_data_to_the_ortho_through_the_lens():
    cam = PinholeCamera.from_hfov(320, 240, 90.0, (-0.1, 0.02, 0.0, 0.0, 0.0))
    ortho = Orthorectifier(cam)
    img = _ground(240, 320)
    nodata = np.zeros((240, 320), bool)
    nodata[60:120, 100:200] = True
    plain, _ = ortho.prepare(img, 1.0)
    masked, _ = ortho.prepare(img, 1.0, nodata)
    assert (plain > 0).all() and (masked == 0).any()
    dropped = masked == 0
    assert np.array_equal(masked[~dropped], plain[~dropped])
    # The lens moves the block a little, not elsewhere: its centre is dropped, the corners not.
    assert dropped[85:95, 140:160].all() and not dropped[:30].any() and not dropped[200:].any()
    half, _ = ortho.prepare(img, 0.5, nodata)  # and at a reduced scale
    assert half.shape == (120, 160) and (half == 0).any() and (half[:15] > 0).all()


def test_a_frame_the_clouds_hide_is_not_matched(seasons, camera, mount, make_estimate):
    truth = np.array([0.0, 0.0, -800.0])
    frame = render_plane_frame(seasons[0], camera, truth, euler_to_dcm(np.radians([1.0, 0.0, 10.0])), mount)
    est = make_estimate(truth + [3.0, -2.0, 0.5], [1.0, 0.0, 10.0], sigma_pos_m=5.0)
    fix, diag = _pipeline(seasons, camera, mount, cloud_mask={}).process(frame, 1.0, est)
    assert fix is not None, diag.reason  # a clear frame is matched as without the mask
    overcast = np.full_like(frame, 235)
    fix, diag = _pipeline(seasons, camera, mount, cloud_mask={}).process(overcast, 2.0, est)
    assert fix is None and diag.reason == "clouds hide 100 % of the frame" and diag.attempted
