"""The stored fixed-wing gains are reproducible from the linear model and stabilise it."""

import numpy as np
import pytest

from testbench.control.design import design_fixed_wing
from testbench.control.gains import default_gains


@pytest.fixture(scope="module")
def result():
    return design_fixed_wing("tb_fixedwing", 25.0, 800.0)


def test_stored_gains_match_the_design(result):
    stored = default_gains("tb_fixedwing")
    np.testing.assert_allclose(stored.k_lon_array, result.gains.k_lon_array, rtol=1e-3, atol=1e-6)
    for k in ("k_phi", "k_p", "k_i_phi", "k_r", "trim_elevator", "trim_throttle"):
        assert getattr(stored, k) == pytest.approx(getattr(result.gains, k), rel=1e-3, abs=1e-6)


def test_closed_loops_stable_and_damped(result):
    assert np.all(result.lon_closed_loop_poles.real < 0)
    assert np.all(result.lat_closed_loop_poles.real < 0)
    assert result.report["lat_min_damping"] > 0.5
    assert result.report["lon_min_damping"] > 0.5
