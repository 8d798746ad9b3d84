"""Small synthetic worlds and cameras shared by the ISMN tests (sizes kept small for CI)."""

from __future__ import annotations

import numpy as np
import pytest

from testbench.core.camera_geometry import CameraMount, PinholeCamera, mount_rotation
from testbench.core.messages import NavEstimate
from testbench.core.rotations import euler_to_quat
from testbench.navigation.ismn.synth import procedural_seasons


@pytest.fixture(scope="session")
def seasons():
    """(summer, winter) procedural 4.8 km x 4.8 km worlds at 4 m per pixel."""
    return procedural_seasons(np.random.default_rng(7), 1200, 4.0, n_fields=250)


@pytest.fixture(scope="session")
def camera():
    """A small 120 deg camera (nadir ground sample about 4.3 m at 800 m)."""
    return PinholeCamera.from_hfov(640, 360, 120.0)


@pytest.fixture(scope="session")
def mount():
    """Nadir camera, image top towards the nose, 0.5 m ahead and 0.2 m below the CG."""
    return CameraMount(mount_rotation(0.0, -90.0, 0.0), np.array([0.5, 0.0, 0.2]))


def _make_estimate(pos_ned_m, rpy_deg, sigma_pos_m=10.0, sigma_att_deg=0.2) -> NavEstimate:
    rpy = np.radians(rpy_deg)
    return NavEstimate(
        0.0, np.asarray(pos_ned_m, float), np.zeros(3), euler_to_quat(rpy), rpy, np.zeros(3),
        np.eye(3) * sigma_pos_m**2, np.eye(3) * 0.1, np.eye(3) * np.radians(sigma_att_deg) ** 2,
    )


@pytest.fixture(scope="session")
def make_estimate():
    """Factory: NavEstimate(pos_ned_m, rpy_deg, sigma_pos_m=10, sigma_att_deg=0.2)."""
    return _make_estimate
