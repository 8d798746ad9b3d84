"""Linearisation about the JSBSim trim: kinematics, linear vs nonlinear response, modes."""

from __future__ import annotations

import json
import math

import control
import numpy as np
import pytest

from testbench.core.errors import InputError
from testbench.dynamics.linear import linearize, linearize_exec
from testbench.dynamics.trim import FT_TO_M, trimmed_exec

DT_S = 1.0 / 120.0


@pytest.fixture(scope="module")
def fw():
    fdm, t = trimmed_exec("tb_fixedwing", 25.0, 1000.0, dt_s=DT_S)
    return fdm, linearize_exec(fdm, t)


def _entry(lm, row, col):
    return lm.a[lm.state_names.index(row), lm.state_names.index(col)]


def test_si_kinematic_rows(fw):
    """Exact kinematics in SI: hdot = V sin(theta - alpha) -> dhdot/dtheta = V = -dhdot/dalpha;
    dVdot/dtheta = -g cos(gamma) with g the apparent gravity on the equator (gravitation minus
    the centrifugal term of Earth's spin, ~9.777 m/s^2 at 1000 m); thetadot = q.
    """
    fdm, lm = fw
    assert _entry(lm, "altitude_m", "theta_rad") == pytest.approx(25.0, rel=1e-3)
    assert _entry(lm, "altitude_m", "alpha_rad") == pytest.approx(-25.0, rel=1e-3)
    g = fdm["accelerations/gravity-ft_sec2"] * FT_TO_M - 7.292115e-5**2 * (6378137.0 + 1000.0)
    assert _entry(lm, "airspeed_mps", "theta_rad") == pytest.approx(-g, rel=1e-3)
    assert _entry(lm, "theta_rad", "q_rps") == pytest.approx(1.0, abs=1e-3)


def test_linear_matches_nonlinear_elevator_step(fw):
    """A 0.02 (0.5 deg) elevator step held 2 s: the linear longitudinal model follows JSBSim.

    Tolerance: max error <= 15 % and RMS error <= 5 % of each state's peak response (the
    largest gap is a one-step timing offset at the short-period pitch-rate peak)."""
    fdm, lm = fw
    de = 0.02

    def state():
        return np.array([fdm["velocities/vt-fps"] * FT_TO_M, fdm["aero/alpha-rad"],
                         fdm["velocities/q-rad_sec"], fdm["attitude/theta-rad"]])

    x0 = state()
    fdm["fcs/elevator-cmd-norm"] = fdm["fcs/elevator-cmd-norm"] + de
    t, x = [0.0], [np.zeros(4)]
    for _ in range(int(round(2.0 / DT_S))):
        fdm.run()
        t.append(fdm["simulation/sim-time-sec"])
        x.append(state() - x0)
    t, x = np.array(t), np.array(x)
    u = np.zeros((2, len(t)))
    u[0] = de
    y = control.forced_response(lm.longitudinal, t, u).outputs.T
    for i, name in enumerate(lm.longitudinal.state_labels):
        peak = np.max(np.abs(x[:, i]))
        assert peak > 0.0, name
        err = y[:, i] - x[:, i]
        assert np.max(np.abs(err)) <= 0.15 * peak, name
        assert np.sqrt(np.mean(err**2)) <= 0.05 * peak, name
    # Trailing edge down: nose down.
    assert x[-1, 3] < 0.0 and y[-1, 3] < 0.0


def test_modes_of_tb_fixedwing(fw):
    _, lm = fw
    sp, ph = lm.mode("short_period"), lm.mode("phugoid")
    assert ph.stable and 0.0 < ph.damping_ratio < 0.3          # lightly damped phugoid
    assert sp.stable and sp.damping_ratio > 0.3                 # well damped short period
    assert sp.natural_frequency_rps > 5.0 * ph.natural_frequency_rps
    # Lanchester's approximation of the phugoid frequency, sqrt(2) g / V, within 30 %.
    assert ph.natural_frequency_rps == pytest.approx(math.sqrt(2.0) * 9.78 / 25.0, rel=0.3)
    roll, spiral, dr = lm.mode("roll"), lm.mode("spiral"), lm.mode("dutch_roll")
    assert roll.stable and roll.period_s is None and roll.time_constant_s < 0.2
    assert abs(spiral.eigenvalue_real) < abs(roll.eigenvalue_real) / 20.0
    assert dr.period_s is not None and dr.damping_ratio > 0.0
    # Mode set is complete and each eigenvalue belongs to its 4-state part.
    assert {m.name for m in lm.modes} == {"short_period", "phugoid", "roll", "spiral", "dutch_roll"}
    lon_eig = np.linalg.eigvals(lm.longitudinal.A)
    assert np.min(np.abs(lon_eig - sp.eigenvalue)) < 1e-9


def test_control_signs_and_named_signals(fw):
    _, lm = fw
    lon, lat = lm.longitudinal, lm.lateral
    assert list(lon.state_labels) == ["airspeed_mps", "alpha_rad", "q_rps", "theta_rad"]
    assert list(lat.input_labels) == ["aileron_norm", "rudder_norm"]
    assert lon.B[2, 0] < 0.0  # elevator > 0 (trailing edge down): nose-down pitch acceleration
    assert lon.B[0, 1] > 0.0  # throttle accelerates
    assert lat.B[1, 0] > 0.0  # aileron > 0 rolls right
    assert lat.B[2, 1] < 0.0  # rudder > 0 (trailing edge left) yaws left (JSBSim convention)


def test_to_dict_is_json(fw):
    _, lm = fw
    d = json.loads(json.dumps(lm.to_dict()))
    assert {m["name"] for m in d["modes"]} == {"short_period", "phugoid", "roll", "spiral", "dutch_roll"}
    assert len(d["longitudinal"]["A"]) == 4


def test_multirotor_modes_are_refused():
    with pytest.raises(InputError, match="multirotor"):
        linearize("tb_quad", 0.0, 100.0)
