"""Control metrics: how well the vehicles flew the guidance commands (on TRUTH, not estimate).

Inputs are the gd_* guidance columns of the telemetry (DESIGN.md run record):
gd_alt_cmd_m (up, above the origin), gd_on_leg, gd_line_start/end_{n,e}_m (the commanded leg
line), gd_airspeed_cmd_mps. Rows without a command (NaN) are not scored.
"""

from __future__ import annotations

import numpy as np

from testbench.scoring.record_io import RunRecord, column
from testbench.scoring.result import ControlMetrics
from testbench.scoring.stats import error_stats


def cross_track_m(pos_n_m, pos_e_m, start_n_m, start_e_m, end_n_m, end_e_m) -> np.ndarray:
    """Signed distance (m) of points from the infinite line start -> end in the N-E plane.

    Positive to the right of the direction of travel (east of a northbound line). Where the
    line is degenerate (|end - start| < 1 mm) the distance to the start point is returned.
    Shapes broadcast; NaN in, NaN out.
    """
    pn, pe = np.asarray(pos_n_m, float), np.asarray(pos_e_m, float)
    an, ae = np.asarray(start_n_m, float), np.asarray(start_e_m, float)
    dn = np.asarray(end_n_m, float) - an
    de = np.asarray(end_e_m, float) - ae
    length = np.hypot(dn, de)
    ok = length > 1e-3
    safe = np.where(ok, length, 1.0)
    signed = (dn * (pe - ae) - de * (pn - an)) / safe
    return np.where(ok, signed, np.hypot(pn - an, pe - ae))


def compute_control(record: RunRecord) -> ControlMetrics | None:
    """ControlMetrics of the record's telemetry (all vehicles it holds); None without guidance."""
    tel = record.telemetry
    if len(tel) == 0:
        return None
    alt_cmd = column(tel, "gd_alt_cmd_m")
    alt_err = -column(tel, "truth_down_m") - alt_cmd
    on_leg = column(tel, "gd_on_leg", dtype=bool).astype(bool)

    xt = cross_track_m(
        column(tel, "truth_north_m"),
        column(tel, "truth_east_m"),
        column(tel, "gd_line_start_n_m"),
        column(tel, "gd_line_start_e_m"),
        column(tel, "gd_line_end_n_m"),
        column(tel, "gd_line_end_e_m"),
    )
    xt = np.where(on_leg, xt, np.nan)
    as_err = np.where(on_leg, column(tel, "truth_airspeed_mps") - column(tel, "gd_airspeed_cmd_mps"), np.nan)

    roll = column(tel, "truth_roll_rad")
    bank_max = float(np.rad2deg(np.nanmax(np.abs(roll)))) if np.isfinite(roll).any() else None

    miss, overshoot = waypoint_errors(tel)
    out = ControlMetrics(
        altitude_error_m=error_stats(alt_err),
        cross_track_error_m=error_stats(xt),
        airspeed_error_mps=error_stats(as_err),
        bank_max_deg=bank_max,
        waypoint_miss_m=error_stats(miss) if miss.size else None,
        waypoint_overshoot_m=error_stats(overshoot) if overshoot.size else None,
    )
    if out == ControlMetrics():
        return None
    return out


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """3-D distance (m) of points p (n, 3) from the segment a -> b."""
    d = b - a
    L2 = float(d @ d)
    t = np.zeros(len(p)) if L2 < 1e-12 else np.clip((p - a) @ d / L2, 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * d), axis=1)


def waypoint_errors(tel) -> tuple[np.ndarray, np.ndarray]:
    """(miss_m per waypoint reached, overshoot_m per waypoint) over the vehicles of `tel`.

    A waypoint is "reached" when guidance moves on to the next target. Its miss is the closest
    true 3-D approach while it was active; its overshoot is the largest true distance from the
    path through it (previous -> it -> next) while the next one is active.
    """
    miss, over = [], []
    vids = tel["vehicle_id"].to_numpy() if "vehicle_id" in tel else np.zeros(len(tel), object)
    for vid in dict.fromkeys(vids):
        m = vids == vid
        tgt = np.c_[column(tel, "gd_target_n_m")[m], column(tel, "gd_target_e_m")[m], column(tel, "gd_target_d_m")[m]]
        pos = np.c_[column(tel, "truth_north_m")[m], column(tel, "truth_east_m")[m], column(tel, "truth_down_m")[m]]
        ok = np.isfinite(tgt).all(axis=1)
        if not ok.any():
            continue
        # Runs of rows with the same target, in order.
        change = np.r_[True, np.any(tgt[1:] != tgt[:-1], axis=1)] & ok
        starts = np.flatnonzero(change)
        runs = [(s, e) for s, e in zip(starts, np.r_[starts[1:], len(tgt)])]
        for i, (s, e) in enumerate(runs):
            if i + 1 >= len(runs):
                break  # the last target is never left: not "reached then moved on"
            wp = tgt[s]
            # Closest approach of the trajectory between records (linear between rows), so the
            # record rate does not inflate the miss.
            track = pos[s:min(e + 1, len(pos))]
            if len(track) > 1:
                miss.append(float(min(_segment_distance(wp[None, :], a, b)[0] for a, b in zip(track[:-1], track[1:]))))
            else:
                miss.append(float(np.linalg.norm(track[0] - wp)))
            ns, ne = runs[i + 1]
            prev = tgt[runs[i - 1][0]] if i > 0 else pos[s]
            nxt = tgt[ns]
            p_next = pos[ns:ne]
            d = np.minimum(_segment_distance(p_next, prev, wp), _segment_distance(p_next, wp, nxt))
            over.append(float(d.max()))
    return np.asarray(miss, float), np.asarray(over, float)
