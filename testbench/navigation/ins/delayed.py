"""Fixes that reach the navigator late: a scene matcher's processing time (IsmnAid latency_s).

A fix is stamped with its frame's exposure time t_c but reaches the filter at t_c + tau. Fused
as if it were a measurement of now, it pulls the estimate back to where the vehicle was tau
ago: at 25 m/s and the earlier method's 600 ms, 15 m along the track, far beyond its sub-metre
claim, so the gate refuses it or the filter takes a 15 m error. InsEkfParams.delayed_fixes
chooses how the navigator fuses it instead:

- "replay" (exact): when the engine learns that a fix of t_c is coming (Engine._hold), the
  navigator snapshots its state and keeps every input after it (IMU samples, the other sources'
  measurements); when the fix comes, the snapshot is restored, the fix fused at t_c, and the
  inputs since replayed, so the estimate is the one a fix without delay would have given (the
  controller flew the tau in between on the estimate without it). Each replay costs the IMU
  steps of tau (0.6 s at 120 Hz: 72 propagations).
- "carry" (first order, no replay): the fix is carried to now on the filter's own motion since
  t_c, z + (p_now - p_tc): its innovation is the one it had at t_c (what the filter was
  corrected by in between is not undone), fused now with the lag term of a position found tau
  ago and carried on the estimated velocity (PositionFix.vel_lag_s: H_v = -tau R), as
  delayed-measurement filters without a state buffer do.
- "as_current": fused as a measurement of now, unchanged: the naive filter, for contrast.

Whichever is chosen, a navigator that is not told a fix is coming (no `expect`) fuses it as
current, and says so once in the log.
"""

from __future__ import annotations

import copy
import dataclasses
import logging
from typing import Any, Literal

import numpy as np

from testbench.core.messages import PositionFix
from testbench.navigation.ins.measurements import add_lag
from testbench.navigation.ins.rollback import replay, restore

log = logging.getLogger(__name__)

DelayMode = Literal["replay", "carry", "as_current"]

_EPS_S = 1e-9


class DelayedFixes:
    """One navigator's held states for fixes in flight. `nav` below is the InsEkfNavigator:
    its `ekf`, `predict`, `correct`, `_estimate` and the attributes in `state_attrs`."""

    def __init__(self, mode: DelayMode, state_attrs: tuple[str, ...]):
        self.mode = mode
        self.state_attrs = state_attrs
        self._held: list[list] = []
        """[t_c (s), what the mode keeps: replay a deep copy of the navigator's state, carry the
        nominal position (3,) NED m at the origin], oldest first."""
        self._inputs: list[Any] = []
        """replay: the inputs since the oldest held state, with ("held", t_c) marks where a
        later one was taken."""
        self.replaying = False
        self._warned = False

    @property
    def recording(self) -> bool:
        """Whether the navigator's inputs must be kept (a replay pending, not in one)."""
        return self.mode == "replay" and bool(self._held) and not self.replaying

    def expect(self, nav, t_s: float) -> None:
        """A fix stamped t_s (now, or just before: the frame of this tick) will come later."""
        if self.mode == "as_current":
            return
        if self.mode == "replay":
            if self._held:
                self._inputs.append(("held", float(t_s)))
            self._held.append([float(t_s), self._snapshot(nav)])
        else:
            self._held.append([float(t_s), np.array(nav.estimate().pos_ned_m, float)])

    def record(self, item: Any) -> None:
        """An input the navigator took (ImuSample or measurement) while a replay is pending."""
        if self.recording:
            self._inputs.append(item)

    def is_late(self, nav, fix: PositionFix) -> bool:
        return float(fix.t_s) < nav.ekf.t_s - _EPS_S

    def fuse(self, nav, fix: PositionFix):
        """The late fix fused as the mode says; returns the navigator's correction info(s)."""
        popped = self._pop(float(fix.t_s))
        if popped is None:
            if not self._warned and self.mode != "as_current":
                log.warning("%s: a position fix of t=%.3f s came %.3f s late without notice: fused as a measurement "
                            "of now (delayed_fixes %s needs the engine's expect())", nav.ctx.vehicle_id, fix.t_s,
                            nav.ekf.t_s - fix.t_s, self.mode)
                self._warned = True
            return nav.fuse_fix_now(fix)
        i, held = popped
        if self.mode == "carry":
            tau = nav.ekf.t_s - float(fix.t_s)
            moved = np.asarray(nav.estimate().pos_ned_m, float) - held
            return nav.fuse_fix_now(dataclasses.replace(fix, pos_ned_m=np.asarray(fix.pos_ned_m, float) + moved,
                                                       vel_lag_s=add_lag(fix.vel_lag_s, tau)))
        return self._replay(nav, fix, i, held)

    # ------------------------------------------------------------------ replay
    def _snapshot(self, nav) -> dict[str, Any]:
        return copy.deepcopy({k: getattr(nav, k) for k in self.state_attrs})

    def _pop(self, t_s: float):
        """(index among the held states, what was held) of the fix stamped t_s, removed from
        the held states; None: none held for it."""
        for i, (t_c, kept) in enumerate(self._held):
            if abs(t_c - t_s) <= _EPS_S:
                del self._held[i]
                return i, kept
        return None

    def _mark_index(self, items: list, t_s: float) -> int:
        for j, item in enumerate(items):
            if _is_mark(item) and abs(item[1] - t_s) <= _EPS_S:
                return j
        raise RuntimeError(f"delayed fixes: no mark for the state held at t={t_s:.3f} s")

    def _replay(self, nav, fix: PositionFix, i: int, state: dict[str, Any]):
        """Restore `state` (held at the fix's time, the i-th oldest held), fuse the fix, replay
        the inputs since. Later held states are taken again on the way (theirs held the state
        without this fix). The oldest's inputs start at its snapshot, a later one's at its mark;
        what older held states still need keeps this fix in the mark's place, to fuse it in
        order when they are replayed."""
        items = self._inputs
        start = 0 if i == 0 else self._mark_index(items, fix.t_s) + 1
        restore(nav, state)
        self.replaying = True
        try:
            info = nav.fuse_fix_now(fix)
            for item in items[start:]:
                if not _is_mark(item):
                    replay(nav, item)
                    continue
                for h in self._held:
                    if abs(h[0] - item[1]) <= _EPS_S:
                        h[1] = self._snapshot(nav)
        finally:
            self.replaying = False
        nav._estimate = None
        if i == 0:
            self._inputs = items[self._mark_index(items, self._held[0][0]) + 1:] if self._held else []
        else:
            self._inputs = items[:start - 1] + [fix] + items[start:]
        return info


def _is_mark(item: Any) -> bool:
    return isinstance(item, tuple) and len(item) == 2 and item[0] == "held"
