"""Snapshots of a navigator's state and the inputs since, to undo a source found faulty late.

A fault monitor raises its alarm seconds after the fault began (the GNSS spoofing monitor needs
its window filled with the spoofer's acceleration): by then the filter has fused the faulty
fixes and carries their error in its velocity and biases, and going on without the source keeps
that error. The navigator therefore snapshots its state before each fix of the source, keeps
every input since (IMU samples and the other sources' measurements, in the order they came),
and on the alarm goes back to the snapshot taken `horizon_s` before it and replays those inputs
without the faulty source (Brumback and Srinath's fault detection with a delayed "backup"
state, in the form INS/GNSS integrity monitors use).
"""

from __future__ import annotations

import copy
from collections import deque
from typing import Any

from testbench.core.messages import ImuSample


class RollbackBuffer:
    """Snapshots (t_s, state) with the index of the last input before each, and the inputs
    (index, item); both kept for keep_s seconds of snapshots."""

    def __init__(self, keep_s: float):
        self.keep_s = float(keep_s)
        self._snapshots: deque[tuple[float, int, Any]] = deque()
        self._inputs: deque[tuple[int, Any]] = deque()
        self._count = 0

    def record(self, item: Any) -> None:
        """An input the navigator took (an ImuSample, or a measurement it will replay)."""
        self._count += 1
        self._inputs.append((self._count, item))

    def snapshot(self, t_s: float, state: Any) -> None:
        """A deep copy of `state`, taken at t_s after every input recorded so far."""
        self._snapshots.append((t_s, self._count, copy.deepcopy(state)))
        while len(self._snapshots) > 1 and self._snapshots[1][0] <= t_s - self.keep_s:
            self._snapshots.popleft()
        first = self._snapshots[0][1]
        while self._inputs and self._inputs[0][0] <= first:
            self._inputs.popleft()

    def rewind(self, before_t_s: float) -> tuple[Any, list[Any]] | None:
        """The latest snapshot taken at or before before_t_s (else the oldest) and the inputs
        recorded after it, in order; the buffer is emptied. None without a snapshot."""
        if not self._snapshots:
            return None
        pick = self._snapshots[0]
        for snap in self._snapshots:
            if snap[0] <= before_t_s:
                pick = snap
        _, idx, state = pick
        items = [item for i, item in self._inputs if i > idx]
        self._snapshots.clear()
        self._inputs.clear()
        return state, items


def restore(nav, state: dict[str, Any]) -> None:
    """Set a navigator's attributes back to a snapshot's (name -> value); its cached estimate
    goes with them."""
    for k, v in state.items():
        setattr(nav, k, v)
    nav._estimate = None


def replay(nav, item: Any) -> None:
    """One recorded input again: an ImuSample through nav.predict, a measurement through
    nav.correct."""
    if isinstance(item, ImuSample):
        nav.predict(item)
    else:
        nav.correct(item)
