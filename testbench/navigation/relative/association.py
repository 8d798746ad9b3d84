"""Which neighbour a camera line of sight belongs to, beyond its track's decoded LED ID.

The decoded ID is the primary evidence. These rules use the neighbour estimates themselves:
- `gates(f, b)`: a settled estimate (10 bearings fused, position sigma below
  assoc_max_sigma_m) predicts the bearing within its chi-square gate;
- `predicted_peer(...)`: an undecoded track may feed the one neighbour whose settled estimate
  gates its bearing (predicted association), if unique;
- `claimed_by_other(...)`: a neighbour's healthy estimate (a bearing fused within
  healthy_age_s) other than `peer` predicts the bearing (a restart from it is refused);
- `ambiguity(...)`: why a bearing identified as `peer` should not be fused as that
  neighbour's ("occluded", "closer_to_other") or None.

Why: in the paper's arrowhead the triangular lattice puts three or four vehicles on one line of
sight. Their LEDs saturate at every range here, so the blobs merge (the near one's drawn over
the far ones) and part as the formation breathes; a track can leave with the other vehicle
under the old ID until its chips revoke it (tracking). Estimates fed such bearings are dragged
onto the other vehicle's line of sight.
Nothing here reads another vehicle's state: only this vehicle's estimates of its neighbours.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from testbench.navigation.relative.neighbour_filter import NeighbourFilter, bearing_noise_cov

_I2 = np.eye(2)  # read-only identity, reused by every d2
_I2.flags.writeable = False


@dataclass(frozen=True)
class Bearing:
    """One camera line of sight at t_s: m_xy (2,) normalised image coordinates (undistorted),
    R_nc (3, 3) camera -> NED from the OWN estimated attitude, cam_offset_ned_m (3,) the
    camera centre's offset from our CG (NED, m; target offset included), focal_px, and the own
    attitude uncertainty att_sigma_rad (largest axis)."""

    t_s: float
    m_xy: np.ndarray
    R_nc: np.ndarray
    cam_offset_ned_m: np.ndarray
    focal_px: float
    att_sigma_rad: float


@dataclass(frozen=True)
class AssociationRules:
    """bearing_sigma_px: pixel noise of a detection centre; assoc_max_sigma_m: a settled
    estimate's largest position sigma (sqrt trace); healthy_age_s: an estimate with a bearing
    fused this recently is healthy; occlusion_margin_m: a neighbour this much nearer occludes;
    restart_max_jump_m, restart_speed_mps: the reach of a restart (within_reach);
    bearing_sigma_model: how the pixel noise spreads over the image
    (neighbour_filter.bearing_noise_cov), as in the neighbour filters."""

    bearing_sigma_px: float
    assoc_max_sigma_m: float
    healthy_age_s: float
    occlusion_margin_m: float
    restart_max_jump_m: float = 30.0
    restart_speed_mps: float = 5.0
    bearing_sigma_model: str = "pixel"

    def within_reach(self, anchor: NeighbourFilter, candidate: NeighbourFilter, t_s: float) -> bool:
        """Whether a restart at candidate's position is a move the neighbour can have made since
        `anchor` (its last estimate): within restart_max_jump_m plus 3 sigma of anchor's position
        predicted to t_s, plus restart_speed_mps for every second since anchor's last update."""
        dt = max(t_s - anchor.t_s, 0.0)
        jump = float(np.linalg.norm(candidate.x[:3] - (anchor.x[:3] + dt * anchor.x[3:])))
        sigma = float(np.sqrt(max(float(np.trace(anchor.P[:3, :3])), 0.0)))
        return jump <= self.restart_max_jump_m + 3.0 * sigma + self.restart_speed_mps * dt

    def d2(self, f: NeighbourFilter, b: Bearing, settled_only: bool = True) -> float:
        """Normalised innovation squared of bearing b against f's prediction at b.t_s; inf when
        f is not in front of the camera or, with settled_only, not settled."""
        if settled_only and not self.settled(f, b.t_s):
            return float("inf")
        m_pred = self.predicted_m_xy(f, b)
        if m_pred is None:
            return float("inf")
        R = bearing_noise_cov(b.m_xy, self.bearing_sigma_px, b.focal_px, self.bearing_sigma_model) + _I2 * b.att_sigma_rad**2
        _, H = f.bearing_model(b.R_nc, b.cam_offset_ned_m)
        S = H @ f.P @ H.T + R
        y = b.m_xy - m_pred
        return float(y @ np.linalg.solve(S, y))

    def settled(self, f: NeighbourFilter, t_s: float) -> bool:
        """Whether f is settled at t_s: 10 bearings fused, and its position sigma (sqrt trace,
        predicted to t_s) at most assoc_max_sigma_m."""
        if f.counters["bearing_accepted"] < 10:
            return False
        dt = max(t_s - f.t_s, 0.0)
        P = f.P[:3, :3] + dt * (f.P[:3, 3:] + f.P[3:, :3]) + dt * dt * f.P[3:, 3:]
        return bool(np.sqrt(max(np.trace(P), 0.0)) <= self.assoc_max_sigma_m)

    @staticmethod
    def predicted_m_xy(f: NeighbourFilter, b: Bearing) -> np.ndarray | None:
        """(2,) normalised image coordinates at which f's estimate, predicted to b.t_s, lies
        seen from b's camera (R_nc, cam_offset_ned_m); None when it is not in front."""
        dt = max(b.t_s - f.t_s, 0.0)
        d = (f.x[:3] + dt * f.x[3:] - b.cam_offset_ned_m) @ b.R_nc
        if d[2] <= 0.2 * np.linalg.norm(d):
            return None  # not in front of this camera
        return np.array([d[0] / d[2], d[1] / d[2]])

    def nearest_part(self, f: NeighbourFilter, b: Bearing, parts_m_xy: np.ndarray) -> int | None:
        """Index of the part (parts_m_xy (k, 2), normalised) nearest where f's settled estimate
        predicts b, or None (f not settled, or not in front).

        A detection of several vehicles merged on one line of sight (Detection.parts_px) is
        centred between them, a few pixels off each: its bearing drags an estimate across the
        line of sight. The part the estimate predicts is its own vehicle's LEDs: the others
        stand 5-15 px away, and a settled estimate (sigma at most assoc_max_sigma_m, mostly
        0.1-0.3 m) predicts its own within a few pixels at 100-300 m. The nearest part is
        taken without a gate: the bearing's own gate in the filter still applies."""
        if not self.settled(f, b.t_s):
            return None
        m_pred = self.predicted_m_xy(f, b)
        if m_pred is None:
            return None
        return int(np.argmin(np.linalg.norm(np.asarray(parts_m_xy, float) - m_pred, axis=1)))

    def gates(self, f: NeighbourFilter, b: Bearing) -> bool:
        """Whether a settled estimate f predicts bearing b within its gate."""
        return self.d2(f, b) <= f.gate2

    def _healthy_others(self, peer: str | None, filters: Mapping[str, NeighbourFilter], t_s: float):
        return [(other, g) for other, g in filters.items()
                if other != peer and t_s - g.last_bearing_t_s < self.healthy_age_s]

    def predicted_peer(self, filters: Mapping[str, NeighbourFilter], b: Bearing, excluded: set[str]) -> str | None:
        """The one neighbour, not in `excluded`, whose settled estimate gates bearing b; None
        when none or several do."""
        hits = [peer for peer, f in filters.items() if peer not in excluded and self.gates(f, b)]
        return hits[0] if len(hits) == 1 else None

    def claimed_by_other(self, peer: str, filters: Mapping[str, NeighbourFilter], b: Bearing) -> bool:
        """Whether another neighbour's healthy settled estimate predicts bearing b: a track
        identified as `peer` there is most likely that neighbour under a stale ID."""
        return any(self.gates(g, b) for _, g in self._healthy_others(peer, filters, b.t_s))

    def ambiguity(self, peer: str, filters: Mapping[str, NeighbourFilter], b: Bearing) -> str | None:
        """Why bearing b, identified as `peer` (whose estimate is filters[peer]), should not be
        fused as that neighbour's, or None.

        "occluded": a healthy estimate of a neighbour more than occlusion_margin_m nearer also
        predicts it: the far ones' LEDs are hidden in, or merged with, the near one's blob,
        whose centre is the near one's bearing. Left to the near one; the far ones coast on
        their ranges. "closer_to_other": another healthy estimate predicts it better (smaller
        normalised innovation) than this neighbour's."""
        f = filters[peer]
        d2_own = self.d2(f, b, settled_only=False)
        rho = float(np.linalg.norm(f.x[:3]))
        for _, g in self._healthy_others(peer, filters, b.t_s):
            d2 = self.d2(g, b)
            if d2 > g.gate2:
                continue
            if float(np.linalg.norm(g.x[:3])) < rho - self.occlusion_margin_m:
                return "occluded"
            if d2 < d2_own:
                return "closer_to_other"
        return None
