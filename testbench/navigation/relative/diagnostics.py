"""What relative navigation reports to the recorder: table "relnav" (one row per neighbour
estimate at log_rate_hz) and table "relnav_id" (one row per identified track per frame when
the frame carries truth annotations, to score the LED IDs).

Truth relative positions are not known onboard (the frame's truth annotations give pixels and
ranges, not positions): the engine fills truth_north_m, truth_east_m, truth_down_m
(peer truth minus own truth, NED, m, at t_s) in the "relnav" rows; they are nan here.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from testbench.navigation.relative.types import Detection, NeighbourTable

NAN = float("nan")


def id_check(det: Detection | None, truths: Sequence[Any]) -> str | None:
    """Id of the visible truth vehicle a detection belongs to, None when none.

    The detection centre inside the boxes of several vehicles (two neighbours on one line of
    sight): the nearest in range, which is drawn over the other and gives the blob its pixels.
    Inside no box: the nearest truth centre whose box grown by 3 px contains it."""
    if det is None:
        return None
    u, v = det.centre_px
    inside = [t for t in truths if getattr(t, "visible", True)
              and t.bbox_px[0] <= u <= t.bbox_px[2] and t.bbox_px[1] <= v <= t.bbox_px[3]]
    if inside:
        return min(inside, key=lambda t: getattr(t, "range_m", 0.0)).id
    best, best_d = None, np.inf
    for t in truths:
        if not getattr(t, "visible", True):
            continue
        u0, v0, u1, v1 = t.bbox_px
        if not (u0 - 3 <= u <= u1 + 3 and v0 - 3 <= v <= v1 + 3):
            continue
        d = float(np.hypot(u - t.centre_px[0], v - t.centre_px[1]))
        if d < best_d:
            best, best_d = t.id, d
    return best


@dataclass
class RelnavDiagnostics:
    """Diagnostics of one processed camera frame. table: the NeighbourTable logged at this
    frame (None between log ticks); id_rows: ID checks against the frame's truth; id_correct:
    per logged peer, 1.0 when the last bearing fused for it came from that vehicle according
    to the frame's truth annotations (0.0 when from another, nan when unknown); column
    "id_correct" of table "relnav" (scored as relnav.id_correct_rate)."""

    t_s: float
    table: NeighbourTable | None = None
    id_rows: list[dict] = field(default_factory=list)
    id_correct: dict[str, float] = field(default_factory=dict)

    def event_rows(self, vehicle_id: str) -> list[tuple[str, dict]]:
        """Rows for the recorder: ("relnav", {...}) per neighbour, ("relnav_id", {...}) per check."""
        rows: list[tuple[str, dict]] = []
        for peer, e in (self.table or {}).items():
            rows.append(("relnav", dict(
                t_s=e.t_s, vehicle_id=vehicle_id, peer_id=peer,
                est_north_m=float(e.pos_ned_m[0]), est_east_m=float(e.pos_ned_m[1]), est_down_m=float(e.pos_ned_m[2]),
                est_vn_mps=float(e.vel_ned_mps[0]), est_ve_mps=float(e.vel_ned_mps[1]), est_vd_mps=float(e.vel_ned_mps[2]),
                sigma_m=e.sigma_m, id_confidence=float(e.id_confidence),
                bearing_age_s=float(e.t_s - e.last_bearing_t_s), range_age_s=float(e.t_s - e.last_range_t_s),
                id_correct=float(self.id_correct.get(peer, NAN)),
                truth_north_m=NAN, truth_east_m=NAN, truth_down_m=NAN)))
        for r in self.id_rows:
            rows.append(("relnav_id", dict(vehicle_id=vehicle_id, **r)))
        return rows
