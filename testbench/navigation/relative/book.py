"""The book of neighbour estimates: which estimate a bearing feeds, and when an estimate starts,
restarts or is forgotten.

RelnavAid decides what a camera track is (its decoded or predicted neighbour ID) and hands the
bearing here; NeighbourBook keeps one NeighbourFilter per neighbour, the last UWB ranges of
each peer (a start needs a range), and the last estimate of each neighbour dropped as stale
(a restart must stay within reach of it). Every refusal is counted in the aid's counters.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

import numpy as np

from testbench.core.messages import NavEstimate, UwbRange
from testbench.navigation.relative.association import AssociationRules, Bearing
from testbench.navigation.relative.geometry import relative_from_bearing_range
from testbench.navigation.relative.layout import LayoutParams, start_fits_layout
from testbench.navigation.relative.neighbour_filter import FilterSettings, NeighbourFilter, initial_covariance

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class StartRules:
    """When estimates start, restart and are forgotten (settings.RelnavParams gives their meaning).

    reset_after_rejects: bearings rejected in a row that mark an estimate lost (with
    reset_bearing_after_s, s, since its last accepted bearing); id_confidence: the ID
    posterior a track needs to start an estimate; range_max_age_s: how recent a range a start
    needs; stale_after_s: no bearing for this long forgets the neighbour; forgotten_max_age_s:
    how long a forgotten estimate still anchors a restart; target_offset_b_m (3,): the
    detected point relative to the neighbour's CG, body m; layout: the formation's slot table
    (None: no check).
    """

    reset_after_rejects: int
    reset_bearing_after_s: float
    id_confidence: float
    range_max_age_s: float
    stale_after_s: float
    forgotten_max_age_s: float
    target_offset_b_m: np.ndarray
    layout: LayoutParams | None


class NeighbourBook:
    """One NeighbourFilter per neighbour, with the ranges and forgotten estimates behind them."""

    def __init__(self, self_id: str, rules: StartRules, fset: FilterSettings, assoc: AssociationRules,
                 counters: dict[str, int]):
        self.self_id = self_id
        self.rules = rules
        self.fset = fset
        self.assoc = assoc
        self.counters = counters
        self.filters: dict[str, NeighbourFilter] = {}
        self.forgotten: dict[str, NeighbourFilter] = {}  # the last estimate of each neighbour dropped as stale
        self.last_range: dict[str, list[tuple[float, float]]] = {}

    # -- UWB -------------------------------------------------------------------------------

    def add_range(self, m: UwbRange, est: NavEstimate) -> None:
        """Keep the range for starts and fuse it in the peer's estimate, if there is one."""
        if m.peer_id == self.self_id or not np.isfinite(m.range_m):
            return
        hist = self.last_range.setdefault(m.peer_id, [])
        hist.append((float(m.t_s), float(m.range_m)))
        del hist[:-5]
        f = self.filters.get(m.peer_id)
        if f is not None:
            # One installation on every vehicle, peer attitude taken equal to ours: the antenna
            # lever arms cancel (lever_diff = R_nb (l_peer - l_self) = 0).
            f.update_range(m.t_s, m.range_m, np.zeros(3), est.vel_ned_mps)

    def nearest_range_m(self, t: float, max_age_s: float) -> float | None:
        """The shortest UWB range (m) of any peer measured within max_age_s before t, or None."""
        recent = [rg for hist in self.last_range.values() for (tr, rg) in hist if t - tr <= max_age_s]
        return min(recent) if recent else None

    # -- bearings --------------------------------------------------------------------------

    def filter_for_bearing(self, peer: str, track: Any, bearing: Bearing, cam: Any, mount: Any, R_nb: np.ndarray,
                           est: NavEstimate) -> NeighbourFilter | None:
        """The estimate that `track`'s bearing of `peer` should feed: the running one, or one
        (re)started from this bearing and the recent ranges; None where a start is refused.

        track: the camera track (its id_index, id_confidence, last_detection); bearing: its
        line of sight at bearing.t_s; R_nb (3, 3): own estimated attitude, body -> NED.
        """
        r, t = self.rules, bearing.t_s
        f = self.filters.get(peer)
        # Bearings alone that disagree while the ranges still agree can be a track whose
        # decoded ID is stale (two neighbours crossed in the image and their tracks swapped)
        # rather than a lost filter: a restart from such a track put the neighbour on the
        # other one's line of sight, 20-40 m off with a sigma of 0.4 m. So bearings must
        # have disagreed for reset_bearing_after_s first. The tracker now revokes an ID its
        # last code cycle contradicts within about a second (tracking), so 1 s suffices;
        # with 3 s an estimate held on a parted neighbour's line of sight reached 7 m.
        identified = f is not None and track.id_index is not None
        lost_on_bearings = identified and (f.consecutive_bearing_rejects >= r.reset_after_rejects
                                           and t - f.last_bearing_t_s >= r.reset_bearing_after_s)
        lost_on_ranges = identified and f.consecutive_rejects >= self.fset.max_consecutive_rejects
        # Where a (re)start must stay near: the estimate lost on bearings alone (its ranges
        # still agree), or the one forgotten for want of bearings (drop_stale) not long ago.
        anchor = f if lost_on_bearings else (self.recently_forgotten(peer, t) if f is None else None)
        if lost_on_bearings or lost_on_ranges:
            self.counters["filter_resets"] += 1
            f = None  # the estimate lost its neighbour: restart from an identified bearing
        if f is not None:
            return f
        if track.id_confidence < r.id_confidence:
            self.counters["restarts_refused"] += 1  # a start needs an ID as sure as an assignment
            return None
        # A track whose bearing is where another neighbour's healthy estimate (a bearing fused
        # less than report_max_age_s ago) predicts one is most likely that neighbour under a
        # stale ID: do not (re)start from it.
        if self.assoc.claimed_by_other(peer, self.filters, bearing):
            self.counters["restarts_refused"] += 1
            return None
        f = self.new_filter(peer, t, cam, mount, R_nb, track.last_detection.centre_px, bearing.att_sigma_rad)
        if f is None:
            return None
        if anchor is not None and not self.assoc.within_reach(anchor, f, t):
            # A move the neighbour cannot have made: a track wearing a wrong ID (uav1's track
            # decoded as uav6 restarted uav3's forgotten estimate of uav6 250 m away, in front
            # of it instead of behind). A lost estimate stays as it was.
            self.counters["restarts_refused"] += 1
            return None
        if r.layout is not None and not start_fits_layout(r.layout, self.self_id, peer, f.x[:3], est.vel_ned_mps,
                                                          float(est.rpy_rad[2])):
            # Where the formation cannot have put that neighbour: a track wearing another
            # vehicle's ID (layout.py).
            self.counters["starts_off_layout"] += 1
            return None
        self.filters[peer] = f
        log.debug("%s: relnav filter for %s started at %.2f s", self.self_id, peer, t)
        return f

    def new_filter(self, peer: str, t: float, cam: Any, mount: Any, R_nb: np.ndarray, centre_px,
                   att_sigma: float) -> NeighbourFilter | None:
        """A neighbour filter started from this bearing (detection centre_px (2,), full-frame
        px) and the recent UWB ranges of `peer` (None without a recent range); the caller
        decides whether to keep it."""
        recent = [rg for (tr, rg) in self.last_range.get(peer, ()) if t - tr <= self.rules.range_max_age_s]
        if not recent:
            return None
        # Median of the lower half of the last few ranges: NLOS excesses are positive, so up to
        # half of them being NLOS cannot seed the filter with a long range.
        low = np.sort(recent)[: (len(recent) + 1) // 2]
        r0 = relative_from_bearing_range(cam, mount, R_nb, [centre_px], float(np.median(low)))
        r0 = r0 - R_nb @ np.asarray(self.rules.target_offset_b_m, float)
        ang = np.hypot(self.fset.bearing_sigma_px / (0.5 * (cam.fx + cam.fy)), att_sigma)
        P0 = initial_covariance(r0, self.fset.range_sigma_m, ang)
        return NeighbourFilter(t, r0, P0, self.fset)

    # -- forgetting ------------------------------------------------------------------------

    def recently_forgotten(self, peer: str, t: float) -> NeighbourFilter | None:
        """The estimate of `peer` dropped as stale less than forgotten_max_age_s ago, if any."""
        f = self.forgotten.get(peer)
        return f if f is not None and t - f.t_s <= self.rules.forgotten_max_age_s else None

    def drop_stale(self, t: float) -> None:
        """Forget neighbours without a bearing for stale_after_s. Ranges alone keep only the
        distance: the direction drifts over the range sphere (one estimate went from behind to
        in front of us in 47 s of ranges), and the filter's wide tangential covariance then
        accepts the first bearing of any track claiming that ID. A forgotten neighbour is
        restarted from an identified track (with the check against the other neighbours)."""
        for peer in [p for p, f in self.filters.items() if t - f.last_bearing_t_s > self.rules.stale_after_s]:
            self.forgotten[peer] = self.filters.pop(peer)
