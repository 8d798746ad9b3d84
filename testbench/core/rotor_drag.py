"""A multirotor's rotor (momentum) drag, from its aircraft sidecar: the model that the JSBSim
airframe flies (aircraft/tb_quad: each rotor drags -c omega_i v_perp), reduced to the one
coefficient that the drag aiding of the INS measures with (navigation/ins/air_aiding.py) and
the velocity loop cancels (control/multirotor.py, drag_compensation). In core, not dynamics:
flight code (control) must not import the truth side (tests/navigation/relative/
test_no_truth_access.py), and this is the vehicle's published data, not its state."""

from __future__ import annotations

import math

from testbench.core.errors import InputError
from testbench.core.units import STANDARD_GRAVITY_MPS2


def momentum_drag_per_s(aircraft: dict, used_by: str, hint: str = "") -> float:
    """mu (1/s) of a multirotor's rotor (momentum) drag at hover from its sidecar: each rotor
    adds -c omega_i v_perp (body x, y; c = rotor_drag_coefficient, N s/(m rad)), and at hover
    omega = sqrt(m g / (n k_T)), so the body x, y specific force is -mu v_b with
    mu = n c omega / m (tb_quad: 0.365 1/s, i.e. 1.46 m/s^2 at 4 m/s through the air).

    used_by names the scenario key that asked and hint what to do instead, for the message
    when the sidecar has no drag model (an InputError: exit status 2)."""
    try:
        m = float(aircraft["mass_kg"])
        c = float(aircraft["rotor_drag_coefficient"])
        k_t = float(aircraft["motor_thrust_constant"])
        n = len(aircraft["motors"])
    except (KeyError, TypeError):
        raise InputError(
            f"{used_by}: the aircraft's sidecar has no rotor drag model "
            "(mass_kg, rotor_drag_coefficient, motor_thrust_constant, motors: a multirotor)"
            + (f"; {hint}" if hint else "")) from None
    omega_hover = math.sqrt(m * STANDARD_GRAVITY_MPS2 / (n * k_t))
    return n * c * omega_hover / m
