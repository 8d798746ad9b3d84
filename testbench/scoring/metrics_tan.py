"""Metrics of terrain-aided navigation from events/tan.parquet (one row per window of radar
altimeter ranges, navigation.tan_aid). None when the run recorded no such table, so that its
keys are absent from metrics.json (a threshold on them then fails as "missing")."""

from __future__ import annotations

import numpy as np

from testbench.scoring.metrics_events import fix_errors_ne_m
from testbench.scoring.metrics_nav import ne_quadratic_form
from testbench.scoring.record_io import RunRecord, column
from testbench.scoring.result import TanMetrics
from testbench.scoring.stats import chi_square_stats, error_stats, rate


def tan_window_errors_ne_m(record: RunRecord, tan) -> np.ndarray:
    """(n, 2) the window's offset placed at the ranges' mean time (mean_north_m, mean_east_m at
    t_s - vel_lag_s) minus the truth then, north and east (m), the truth interpolated in the
    vehicle's telemetry; NaN on rows without a fix. The density's own error: the fix less the
    velocity lag that the navigator models (PositionFix.vel_lag_s)."""
    out = np.full((len(tan), 2), np.nan)
    if not {"mean_north_m", "vel_lag_s"} <= set(tan.columns):
        return out
    t_mean = column(tan, "t_s") - column(tan, "vel_lag_s")
    vids = tan["vehicle_id"].astype(str).to_numpy()
    for vid in np.unique(vids):
        tel = record.vehicle_telemetry(vid)
        sel = vids == vid
        tt = column(tel, "t_s")
        out[sel, 0] = column(tan, "mean_north_m")[sel] - np.interp(t_mean[sel], tt, column(tel, "truth_north_m"))
        out[sel, 1] = column(tan, "mean_east_m")[sel] - np.interp(t_mean[sel], tt, column(tel, "truth_east_m"))
    return out


def compute_tan(record: RunRecord) -> TanMetrics | None:
    """TanMetrics of the record's tan table."""
    tan = record.event("tan")
    if tan is None:
        return None
    fix = column(tan, "fix", dtype=bool).astype(bool)
    accepted = column(tan, "accepted", dtype=bool).astype(bool) & fix
    e_ne = fix_errors_ne_m(tan)[fix]
    e_win = tan_window_errors_ne_m(record, tan)[fix]
    e_d = (column(tan, "fix_down_m") - column(tan, "truth_down_m"))[fix]
    sn, se = column(tan, "sigma_north_m")[fix], column(tan, "sigma_east_m")[fix]
    c_ne = column(tan, "cov_ne_m2")[fix] if "cov_ne_m2" in tan.columns else np.zeros(len(sn))
    with np.errstate(divide="ignore", invalid="ignore"):
        nees = ne_quadratic_form(e_win[:, 0], e_win[:, 1], sn * sn, se * se, c_ne, sn * sn * se * se - c_ne * c_ne)
    nees = nees[np.isfinite(nees)]
    reasons = tan["reason"].astype(str)[~fix] if "reason" in tan.columns else []
    rejected = {str(k): int(v) for k, v in (reasons.value_counts().items() if len(reasons) else [])}
    n_win, n_fix, n_acc = len(tan), int(fix.sum()), int(accepted.sum())
    return TanMetrics(
        windows=n_win,
        fixes=n_fix,
        accepted=n_acc,
        fix_rate=rate(n_fix, n_win),
        accept_rate=rate(n_acc, n_fix),
        horizontal_error_m=error_stats(np.hypot(e_ne[:, 0], e_ne[:, 1]), cep=True) if n_fix else None,
        vertical_error_m=error_stats(np.abs(e_d)) if n_fix else None,
        window_error_m=error_stats(np.hypot(e_win[:, 0], e_win[:, 1]), cep=True) if np.isfinite(e_win).any() else None,
        horizontal_nees=chi_square_stats(nees, 2) if len(nees) else None,
        rejected=rejected,
    )
