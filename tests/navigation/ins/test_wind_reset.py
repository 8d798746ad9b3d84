"""Re-acquiring the wind from rotor-drag samples the gate keeps refusing (ErrorStateEKF.reset_wind)."""

from __future__ import annotations

import numpy as np
import pytest

from testbench.navigation.ins import measurements as meas
from testbench.navigation.ins.ekf import ErrorStateEKF
from testbench.navigation.ins.error_model import IV, IW
from testbench.navigation.ins.imu_noise import imu_noise_from_datasheet

MU_PER_S = 0.36


def _filter_sure_of_calm_air() -> ErrorStateEKF:
    """Flying north at 5 m/s, level, sure (0.1 m/s) that the air is calm."""
    ekf = ErrorStateEKF(imu_noise_from_datasheet(0.15, 7.0, 0.02, 14.0), wind_states=True)
    ekf.initialize(0.0, 0.8, 0.2, 500.0, np.array([5.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0, 0.0]),
                   np.diag(np.full(ekf.n, 1e-4)))
    ekf.P[IV, IV] = np.eye(3) * 0.05**2
    ekf.P[IW, IW] = np.eye(2) * 0.1**2
    return ekf


def _drag_sample(ekf: ErrorStateEKF):
    """What the accelerometers read when a 5 m/s wind carries the vehicle along: no velocity
    through the air, so no rotor drag."""
    v_b_air = (ekf.C_nb.T @ meas.air_velocity_ned(ekf))[:2]
    return meas.drag_specific_force(ekf, [0.0, 0.0], v_b_air, MU_PER_S, 0.05)


def test_a_wind_beyond_its_sigma_is_refused_then_reacquired():
    ekf = _filter_sure_of_calm_air()
    y, H, R = _drag_sample(ekf)
    assert not ekf.update("drag", 0.2, y, H, R).accepted  # 1.8 m/s^2 against a 0.05 sigma
    ekf.P[IV.start, IW.start] = ekf.P[IW.start, IV.start] = -0.002  # a tie left by earlier samples
    P_before = ekf.P.copy()
    seen = {}
    update = ekf.update

    def spy(kind, t_s, y, H, R, gate=True):  # the covariance the ungated update starts from
        seen["P"] = ekf.P.copy()
        return update(kind, t_s, y, H, R, gate)

    ekf.update = spy
    info = ekf.reset_wind("drag:reset", 0.4, y, H, R)
    assert info.accepted and info.nis > 100.0  # the NIS the gate saw
    # The wind's variance grew by the wind change that explains the disagreement (5 m/s north),
    # and its ties to the velocity are kept.
    assert seen["P"][IW, IW][0, 0] == pytest.approx(P_before[IW, IW][0, 0] + 25.0, rel=0.01)
    np.testing.assert_array_equal(seen["P"][IV, IW], P_before[IV, IW])
    # The disagreement went to the wind; the velocity over the ground stays with the INS.
    assert ekf.wind_ne_mps[0] == pytest.approx(5.0, abs=0.5)
    assert abs(float(ekf.ins.vel[0]) - 5.0) < 0.3
    y2, H2, R2 = _drag_sample(ekf)
    assert ekf.update("drag", 0.6, y2, H2, R2).accepted


def test_reset_wind_needs_wind_states():
    ekf = ErrorStateEKF(imu_noise_from_datasheet(0.15, 7.0, 0.02, 14.0))
    ekf.initialize(0.0, 0.8, 0.2, 500.0, np.array([5.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0, 0.0]), np.eye(ekf.n) * 1e-4)
    y, H, R = meas.drag_specific_force(ekf, [0.0, 0.0], [5.0, 0.0], MU_PER_S, 0.05)
    with pytest.raises(ValueError, match="wind states"):
        ekf.reset_wind("drag:reset", 0.2, y, H, R)
