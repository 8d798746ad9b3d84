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

    out = ControlMetrics(
        altitude_error_m=error_stats(alt_err),
        cross_track_error_m=error_stats(xt),
        airspeed_error_mps=error_stats(as_err),
        bank_max_deg=bank_max,
    )
    if out == ControlMetrics():
        return None
    return out
