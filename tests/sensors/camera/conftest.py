"""Small maps and poses shared by the renderer tests."""

from __future__ import annotations

import numpy as np
import pytest

from testbench.core.camera_geometry import CameraMount, mount_rotation
from testbench.world.raster import LocalRaster


def raster(data: np.ndarray, gsd_m: float, centre_ne_m=(0.0, 0.0), valid=None) -> LocalRaster:
    """A LocalRaster of `data` centred on centre_ne_m (north-up)."""
    h, w = data.shape[:2]
    n0 = centre_ne_m[0] + 0.5 * h * gsd_m
    e0 = centre_ne_m[1] - 0.5 * w * gsd_m
    return LocalRaster(data, np.ones((h, w), bool) if valid is None else valid, n0, e0, gsd_m)


def textured(n: int = 512, seed: int = 0) -> np.ndarray:
    """(n, n, 3) uint8 smooth random texture (no single dominant period)."""
    import cv2

    rng = np.random.default_rng(seed)
    acc = np.zeros((n, n, 3), np.float32)
    for k in range(2, 7):
        m = max(4, n >> (8 - k))
        acc += cv2.resize(rng.normal(0, 1, (m, m, 3)).astype(np.float32), (n, n), interpolation=cv2.INTER_CUBIC)
    acc = (acc - acc.mean()) / acc.std()
    return np.clip(120 + 40 * acc, 0, 255).astype(np.uint8)


def mount(pitch_deg: float, roll_deg: float = 0.0, yaw_deg: float = 0.0) -> CameraMount:
    return CameraMount(mount_rotation(roll_deg, pitch_deg, yaw_deg), np.zeros(3))


@pytest.fixture
def nadir() -> CameraMount:
    return mount(-90.0)
