"""JSBSim trim of the project's vehicles: residuals, steady flight, hover, bad input."""

from __future__ import annotations

import math

import pytest

from testbench.core.errors import InputError
from testbench.dynamics.catalog import aircraft_meta
from testbench.dynamics.trim import FT_TO_M, new_exec, set_flight_condition, trim, trimmed_exec


@pytest.fixture(scope="module")
def fw_trim():
    return trimmed_exec("tb_fixedwing", 25.0, 1000.0)


def test_fixed_wing_trim_residuals_near_zero(fw_trim):
    _, t = fw_trim
    assert t.max_linear_residual_mps2 < 1e-3
    assert t.max_angular_residual_rps2 < 1e-4
    # A sane cruise: small positive alpha, controls inside their range, wings level.
    assert 0.0 < t.alpha_rad < math.radians(8.0)
    assert 0.0 < t.throttle_norm < 1.0
    assert -1.0 < t.elevator_norm < 0.0  # nose-up elevator (trailing edge up) holds the trim
    assert abs(t.phi_rad) < math.radians(1.0)
    # Level flight: pitch equals alpha (gamma = 0).
    assert t.theta_rad == pytest.approx(t.alpha_rad, abs=1e-6)


def test_fixed_wing_trim_lift_balances_weight(fw_trim):
    """L = W at the trim: CL(alpha, delta_e) q S = m g, with the model's published numbers."""
    fdm, t = fw_trim
    rho = fdm["atmosphere/rho-slugs_ft3"] * 515.378821
    qbar_s = 0.5 * rho * t.airspeed_mps**2 * 0.55
    delta_e = fdm["fcs/elevator-pos-rad"]
    cl = 0.23 + 5.61 * t.alpha_rad + 0.13 * delta_e  # sigma(alpha) ~ 1e-10 here
    thrust_n = fdm["tb/prop/thrust-n"]
    # Apparent gravity on the equator: gravitation minus the centrifugal term of Earth's spin.
    g_app = fdm["accelerations/gravity-ft_sec2"] * FT_TO_M - 7.292115e-5**2 * (6378137.0 + 1000.0)
    lift_needed = 11.0 * g_app - thrust_n * math.sin(t.alpha_rad)
    assert cl * qbar_s == pytest.approx(lift_needed, rel=2e-3)


def test_fixed_wing_holds_trim_for_five_seconds():
    fdm, t = trimmed_exec("tb_fixedwing", 25.0, 1000.0, dt_s=0.01)
    h0 = fdm["position/h-sl-ft"] * FT_TO_M
    for _ in range(500):
        fdm.run()
    assert fdm["position/h-sl-ft"] * FT_TO_M == pytest.approx(h0, abs=0.5)
    assert fdm["velocities/vt-fps"] * FT_TO_M == pytest.approx(25.0, abs=0.1)
    assert abs(fdm["attitude/phi-rad"]) < math.radians(2.0)


def test_fixed_wing_trims_in_a_climb():
    t = trim("tb_fixedwing", 25.0, 1000.0, flight_path_deg=3.0)
    assert t.max_linear_residual_mps2 < 1e-3
    assert t.theta_rad - t.alpha_rad == pytest.approx(math.radians(3.0), abs=1e-3)
    assert t.throttle_norm > trim("tb_fixedwing", 25.0, 1000.0).throttle_norm


def test_quad_hovers_on_the_sidecar_command():
    """JSBSim directly: all motors at hover_throttle_norm keep the altitude within 0.3 m for 3 s."""
    meta = aircraft_meta("tb_quad")
    fdm = new_exec("tb_quad", dt_s=0.005)
    for i in range(len(meta["motors"])):
        fdm[f"fcs/throttle-cmd-norm[{i}]"] = meta["hover_throttle_norm"]
    set_flight_condition(fdm, 0.0, 100.0)
    h0 = fdm["position/h-sl-ft"] * FT_TO_M
    for _ in range(600):
        fdm.run()
        assert abs(fdm["position/h-sl-ft"] * FT_TO_M - h0) < 0.3
    assert abs(fdm["attitude/phi-rad"]) < 1e-6 and abs(fdm["attitude/theta-rad"]) < 1e-6
    assert abs(fdm["velocities/r-rad_sec"]) < 1e-6  # balanced rotor torques: no yaw


def test_quad_hover_trim_zeroes_wdot_near_the_sidecar_value():
    t = trim("tb_quad", 0.0, 100.0)
    assert abs(t.wdot_mps2) < 1e-6
    assert t.throttle_norm == pytest.approx(aircraft_meta("tb_quad")["hover_throttle_norm"], rel=0.01)
    assert len(set(t.motor_throttles_norm)) == 1


def test_unknown_aircraft_lists_the_available_ones():
    with pytest.raises(InputError) as exc:
        trim("no_such_plane", 25.0, 1000.0)
    msg = str(exc.value)
    assert "no_such_plane" in msg and "tb_fixedwing" in msg and "tb_quad" in msg and "c172x" in msg
    assert "\n" not in msg


def test_untrimmable_condition_is_an_input_error():
    with pytest.raises(InputError, match="trim failed"):
        trim("tb_fixedwing", 5.0, 1000.0)
    with pytest.raises(InputError, match="hover"):
        trim("tb_quad", 10.0, 100.0)
