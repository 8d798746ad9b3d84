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
    """(n, 2) the density's own error, north and east (m): the fix less its velocity lag term
    (which a navigator with velocity_lag "model" fuses), against the truth at the fix's time;
    NaN on rows without a fix.

    With the lag matrix (lag_nn_s ... lag_ee_s, L) the fix holds L (v_est - v_true) besides the
    match's own error; that term is taken out with the window's mean velocity error (the
    navigator's velocity less the truth over the telemetry rows from window_start_s to just
    before the fix, which the dead reckoning integrated). Records before it (one scalar lag)
    place the offset on the dead-reckoned track at t_s - vel_lag_s (mean_north_m, mean_east_m)
    against the truth then."""
    out = np.full((len(tan), 2), np.nan)
    vids = tan["vehicle_id"].astype(str).to_numpy()
    t_fix = column(tan, "t_s")
    if {"lag_nn_s", "window_start_s"} <= set(tan.columns):
        lag = np.stack([np.stack([column(tan, "lag_nn_s"), column(tan, "lag_ne_s")], -1),
                        np.stack([column(tan, "lag_en_s"), column(tan, "lag_ee_s")], -1)], -2)  # (n, 2, 2)
        t0 = column(tan, "window_start_s")
        fix_ne = np.stack([column(tan, "fix_north_m"), column(tan, "fix_east_m")], -1)
        for vid in np.unique(vids):
            tel = record.vehicle_telemetry(vid)
            tt = column(tel, "t_s")
            truth_ne = np.stack([column(tel, "truth_north_m"), column(tel, "truth_east_m")], -1)
            e_v = np.stack([column(tel, "nav_vn_mps") - column(tel, "truth_vn_mps"),
                            column(tel, "nav_ve_mps") - column(tel, "truth_ve_mps")], -1)
            for r in np.flatnonzero(vids == vid):
                if not np.isfinite(fix_ne[r]).all():
                    continue
                win = (tt >= t0[r]) & (tt < t_fix[r] - 1e-9)
                if not win.any():
                    continue
                truth_at_fix = [np.interp(t_fix[r], tt, truth_ne[:, i]) for i in range(2)]
                out[r] = fix_ne[r] - truth_at_fix - lag[r] @ e_v[win].mean(axis=0)
        return out
    if not {"mean_north_m", "vel_lag_s"} <= set(tan.columns):
        return out
    t_mean = t_fix - column(tan, "vel_lag_s")
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
