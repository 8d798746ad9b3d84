"""Error types and the process exit status each one maps to.

The CLI turns these into one line on stderr and an exit status (DESIGN.md, output contract):
0 run completed and thresholds held, 3 a threshold failed, 2 bad input, 4 the simulation was
aborted (vehicle crashed, NaN or runaway state, diverging filter), 1 an internal error.
"""

from __future__ import annotations

EXIT_OK = 0
EXIT_INTERNAL = 1
EXIT_BAD_INPUT = 2
EXIT_THRESHOLD_FAILED = 3
EXIT_RUN_ABORTED = 4


class TestbenchError(Exception):
    """Base class of every error the testbench raises on purpose."""

    exit_status = EXIT_INTERNAL


class InputError(TestbenchError):
    """A user mistake: missing or malformed file, unknown key, wrong type or unit.

    The message names the file, key or value and what was expected, on one line.
    """

    exit_status = EXIT_BAD_INPUT


class SimulationAborted(TestbenchError):
    """The simulated world left its valid domain: ground contact, NaN, runaway state,
    or a diverging estimator. Carries the simulation time and the vehicle involved."""

    exit_status = EXIT_RUN_ABORTED

    def __init__(self, message: str, *, t_s: float | None = None, vehicle_id: str | None = None):
        where = []
        if vehicle_id is not None:
            where.append(f"vehicle {vehicle_id}")
        if t_s is not None:
            where.append(f"t={t_s:.3f} s")
        prefix = f"{', '.join(where)}: " if where else ""
        super().__init__(prefix + message)
        self.t_s = t_s
        self.vehicle_id = vehicle_id
        self.reason = message
