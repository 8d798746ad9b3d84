"""The guidance status built only when it is read.

A controller runs at the control rate (40-100 Hz) but the engine records its GuidanceStatus at
the record rate (10 Hz): building the status every tick cost more than some of the loops.
A controller keeps the arguments of its latest tick (`_defer_status(...)`) and the status is
built from them, once, when `status()` (or `_status`) is read.
"""

from __future__ import annotations

from testbench.core.messages import GuidanceStatus


class DeferredStatus:
    """Mixin for a Controller: `status()` from the arguments of the latest tick.

    The class using it defines `_guidance_status(*inputs) -> GuidanceStatus` and calls
    `_defer_status(*inputs)` each tick. `_status` stays an attribute that a subclass can read
    or replace (a formation follower sets its own law's status)."""

    _status_inputs: tuple | None = None  # arguments of _guidance_status for the latest tick
    _status_value: GuidanceStatus = GuidanceStatus(t_s=0.0)

    def _guidance_status(self, *inputs) -> GuidanceStatus:
        raise NotImplementedError

    def _defer_status(self, *inputs) -> None:
        """Keep the arguments of this tick's status; it is built when read."""
        self._status_inputs = inputs

    @property
    def _status(self) -> GuidanceStatus:
        if self._status_inputs is not None:
            self._status_value = self._guidance_status(*self._status_inputs)
            self._status_inputs = None
        return self._status_value

    @_status.setter
    def _status(self, value: GuidanceStatus) -> None:
        self._status_value = value
        self._status_inputs = None

    def status(self) -> GuidanceStatus:
        """What guidance is doing now (see Controller.status)."""
        return self._status
