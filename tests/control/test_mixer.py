"""Mixer: allocation then the forward map returns the commanded thrust and moments."""

import numpy as np
import pytest

from testbench.control.mixer import Mixer
from testbench.dynamics.catalog import aircraft_meta


@pytest.fixture(scope="module")
def mixer():
    meta = aircraft_meta("tb_quad")
    return Mixer(meta["motors"], meta["max_thrust_per_motor_n"], meta["yaw_torque_per_thrust_m"])


def test_allocation_inverse(mixer):
    rng = np.random.default_rng(3)
    for _ in range(50):
        thrust = rng.uniform(8.0, 20.0)
        m = rng.normal(0.0, [0.3, 0.3, 0.05])
        t = mixer.allocate(thrust, m)
        assert np.all(t >= 0) and np.all(t <= mixer.max_thrust_n)
        np.testing.assert_allclose(mixer.wrench(t), [thrust, *m], atol=1e-9)


def test_moment_signs(mixer):
    # Positive roll moment (right wing down) loads the left motors (y < 0) more.
    t = mixer.allocate(15.0, np.array([0.5, 0.0, 0.0]))
    y = -mixer.effectiveness[1]
    assert np.all(t[y < 0] > t[y > 0].max())


def test_saturation_keeps_thrust_and_drops_yaw_first(mixer):
    t = mixer.allocate(26.0, np.array([0.0, 0.0, 2.0]))  # near full thrust, large yaw demand
    assert np.all(t <= mixer.max_thrust_n + 1e-12)
    w = mixer.wrench(t)
    assert w[0] == pytest.approx(26.0) and abs(w[1]) < 1e-9 and abs(w[2]) < 1e-9
