"""The project's JSBSim models against their published numbers and sign conventions."""

from __future__ import annotations

import numpy as np
import pytest

from testbench.dynamics.catalog import aircraft_meta
from testbench.dynamics.trim import FT_TO_M, new_exec, set_flight_condition

SLUGFT2_TO_KGM2 = 14.593903 * FT_TO_M**2
SLUG_TO_KG = 14.593903


@pytest.mark.filterwarnings("ignore::PendingDeprecationWarning")  # jsbsim returns np.matrix
def test_fixed_wing_mass_and_inertia():
    """Beard & McLain Aerosonde: m 11 kg; Jx, Jy, Jz, Jxz = 0.8244, 1.135, 1.759, 0.1204 kg m^2
    with Jxz = integral of x z dm, i.e. J = [[Jx, 0, -Jxz], [0, Jy, 0], [-Jxz, 0, Jz]]."""
    fdm = new_exec("tb_fixedwing")
    set_flight_condition(fdm, 25.0, 1000.0)
    assert fdm["inertia/mass-slugs"] * SLUG_TO_KG == pytest.approx(11.0, rel=1e-6)
    j = np.array(fdm.get_mass_balance().get_J(), dtype=float) * SLUGFT2_TO_KGM2
    expected = np.array([[0.8244, 0, -0.1204], [0, 1.135, 0], [-0.1204, 0, 1.759]])
    np.testing.assert_allclose(j, expected, rtol=5e-4, atol=1e-6)  # JSBSim's unit factors
    meta = aircraft_meta("tb_fixedwing")
    assert meta["kind"] == "fixed_wing" and meta["mass_kg"] == 11.0
    assert 2.5 <= meta["span_m"] <= 4.0 and 20.0 <= meta["cruise_airspeed_mps"] <= 30.0


def test_fixed_wing_ground_contact_is_detectable():
    fdm = new_exec("tb_fixedwing")
    set_flight_condition(fdm, 0.0, 0.05)  # belly 0.15 m below the CG: touching the ground
    fdm.run()
    # STRUCTURE contact points report through contact/unit[i]/WOW (gear/wow is for BOGEYs).
    assert any(fdm[f"contact/unit[{i}]/WOW"] == 1.0 for i in range(5))


def test_quad_sidecar_matches_the_model():
    """Hover command = m g0 / (4 T_max); motor layout symmetric (zero net roll/pitch moment)."""
    meta = aircraft_meta("tb_quad")
    fdm = new_exec("tb_quad")
    set_flight_condition(fdm, 0.0, 100.0)
    m = fdm["inertia/mass-slugs"] * SLUG_TO_KG
    assert m == pytest.approx(meta["mass_kg"], rel=1e-6)
    assert meta["hover_throttle_norm"] == pytest.approx(m * 9.80665 / (4 * meta["max_thrust_per_motor_n"]), abs=1e-3)
    pos = np.array([mot["position_b_m"] for mot in meta["motors"]])
    assert np.allclose(pos[:, :2].sum(axis=0), 0.0)
    assert sum(mot["spin"] for mot in meta["motors"]) == 0


@pytest.mark.parametrize(
    "delta, rate, sign",
    [
        # counter-clockwise rotors (spin -1: 0, 1) faster -> body yaws right (r > 0)
        ((+1, +1, -1, -1), "velocities/r-rad_sec", +1),
        # left motors (1 back left, 2 front left) faster -> roll right (p > 0)
        ((-1, +1, +1, -1), "velocities/p-rad_sec", +1),
        # front motors (0, 2) faster -> pitch up (q > 0)
        ((+1, -1, +1, -1), "velocities/q-rad_sec", +1),
    ],
)
def test_quad_motor_order_and_spin_directions(delta, rate, sign):
    meta = aircraft_meta("tb_quad")
    fdm = new_exec("tb_quad", dt_s=0.005)
    for i, d in enumerate(delta):
        fdm[f"fcs/throttle-cmd-norm[{i}]"] = meta["hover_throttle_norm"] * (1.0 + 0.05 * d)
    set_flight_condition(fdm, 0.0, 100.0)
    for _ in range(40):
        fdm.run()
    assert sign * fdm[rate] > 0.01


def test_quad_motor_lag_time_constant():
    """A thrust step reaches 1 - 1/e of its size after one time constant (0.025 s)."""
    meta = aircraft_meta("tb_quad")
    fdm = new_exec("tb_quad", dt_s=0.001)
    u0 = meta["hover_throttle_norm"]
    fdm["fcs/throttle-cmd-norm[0]"] = u0
    set_flight_condition(fdm, 0.0, 100.0)
    fdm.run()
    fdm["fcs/throttle-cmd-norm[0]"] = u0 + 0.1
    for _ in range(25):
        fdm.run()
    frac = (fdm["fcs/motor0-thrust-norm"] - u0) / 0.1
    assert frac == pytest.approx(1.0 - np.exp(-1.0), abs=0.03)


def test_flight_below_the_origin_over_low_terrain():
    """A canyon floor 300 m below the origin: JSBSim's own ground must not sit at the origin
    altitude (the vehicle would start 'underground' and blow up), and the adapter's own
    terrain check must still end the run when the vehicle meets the real terrain."""
    from testbench.core.errors import SimulationAborted
    from testbench.core.interfaces import GeodeticOrigin
    from testbench.core.messages import RotorCommand
    from testbench.dynamics.jsbsim_adapter import InitialCondition, JSBSimDynamics

    origin = GeodeticOrigin(lat_rad=np.radians(36.1), lon_rad=np.radians(-112.1), alt_m=1500.0)
    dyn = JSBSimDynamics("tb_quad", origin, 200.0, terrain_height_fn=lambda n, e: -300.0, vehicle_id="q")
    truth = dyn.reset(InitialCondition(pos_ned_m=(0.0, 0.0, 220.0)))  # 220 m below the origin
    assert truth.height_agl_m == pytest.approx(80.0, abs=0.5)
    dyn.advance(None, 200)  # 1 s of hover: no runaway
    t = dyn.truth()
    assert np.linalg.norm(t.vel_ned_mps) < 5.0 and t.height_agl_m > 70.0

    with pytest.raises(SimulationAborted, match="ground contact"):
        for _ in range(40):  # motors off: falls 80 m onto the canyon floor within ~5 s
            dyn.step(RotorCommand(motors=(0.0,) * 4), 0.25)


def test_flying_into_an_obstacle_ends_the_run_naming_it():
    """A quad hovering 8 m from a 120 m mast flies on; one that falls onto a roof ends the run
    as a collision naming it, as ground contact ends it; a start inside a box is bad input."""
    from testbench.core.errors import InputError, SimulationAborted
    from testbench.core.interfaces import GeodeticOrigin
    from testbench.core.messages import RotorCommand
    from testbench.core.obstacles import Obstacle
    from testbench.dynamics.jsbsim_adapter import InitialCondition, JSBSimDynamics

    origin = GeodeticOrigin(lat_rad=np.radians(47.0), lon_rad=np.radians(-99.0), alt_m=500.0)
    mast = Obstacle((-2.0, -2.0, -120.0), (2.0, 2.0, 0.0), "mast")
    clear = JSBSimDynamics("tb_quad", origin, 200.0, obstacles=(mast,), vehicle_id="q")
    clear.reset(InitialCondition(pos_ned_m=(10.0, 0.0, -80.0)))
    clear.advance(None, 200)
    assert clear.truth().height_agl_m > 70.0  # 8 m off the mast: nothing happens
    # Falling onto a roof 10 m below, motors off, ends the run as a collision with it.
    roof = Obstacle((-20.0, -20.0, -70.0), (20.0, 20.0, 0.0), "hall")
    falling = JSBSimDynamics("tb_quad", origin, 200.0, obstacles=(roof,), vehicle_id="q")
    falling.reset(InitialCondition(pos_ned_m=(0.0, 0.0, -80.0)))
    with pytest.raises(SimulationAborted, match="collision with obstacle 'hall'"):
        for _ in range(40):  # 10 m of free fall take about 1.4 s
            falling.step(RotorCommand(motors=(0.0,) * 4), 0.1)
    # Starting in it is bad input, named before anything flies.
    inside = JSBSimDynamics("tb_quad", origin, 200.0, obstacles=(mast,), vehicle_id="q")
    with pytest.raises(InputError, match="inside obstacle 'mast'"):
        inside.reset(InitialCondition(pos_ned_m=(1.0, 0.0, -80.0)))
