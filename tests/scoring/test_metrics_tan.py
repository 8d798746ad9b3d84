"""scoring.metrics_tan: figures of terrain-aided navigation from a tan table worked by hand."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from testbench.scoring.metrics_tan import compute_tan
from testbench.scoring.record_io import RunRecord


def _record(rows: list[dict]) -> RunRecord:
    t = np.arange(0.0, 61.0, 0.1)
    tel = pd.DataFrame({"t_s": t, "vehicle_id": "uav0", "truth_north_m": 25.0 * t, "truth_east_m": 0.0 * t,
                        "truth_down_m": -300.0 + 0.0 * t})
    base = dict(vehicle_id="uav0", accepted=True, cov_ne_m2=0.0, samples=100, roughness_m=8.0,
                mass_in_ellipse=0.99, edge_mass=0.0, outliers=0, truth_down_m=-300.0, truth_height_agl_m=300.0)
    return RunRecord(tel, {"vehicles": [{"id": "uav0"}]}, {"tan": pd.DataFrame([{**base, **r} for r in rows])})


def test_errors_nees_and_rejections():
    nan = math.nan
    rows = [
        # fix 3 m north and 4 m east off at 20 s; its window offset 1 m off at the mean time 10 s
        dict(t_s=20.0, fix=True, fix_north_m=503.0, fix_east_m=4.0, fix_down_m=-301.0, truth_north_m=500.0,
             truth_east_m=0.0, sigma_north_m=1.0, sigma_east_m=2.0, sigma_down_m=1.0, vel_lag_s=10.0,
             mean_north_m=251.0, mean_east_m=0.0, reason=""),
        dict(t_s=40.0, fix=True, accepted=False, fix_north_m=1000.0, fix_east_m=0.0, fix_down_m=-302.0,
             truth_north_m=1000.0, truth_east_m=0.0, sigma_north_m=1.0, sigma_east_m=1.0, sigma_down_m=1.0,
             vel_lag_s=10.0, mean_north_m=750.0, mean_east_m=2.0, reason=""),
        dict(t_s=60.0, fix=False, accepted=False, fix_north_m=nan, fix_east_m=nan, fix_down_m=nan,
             truth_north_m=1500.0, truth_east_m=0.0, sigma_north_m=nan, sigma_east_m=nan, sigma_down_m=nan,
             vel_lag_s=nan, mean_north_m=nan, mean_east_m=nan, reason="flat"),
    ]
    m = compute_tan(_record(rows))
    assert (m.windows, m.fixes, m.accepted) == (3, 2, 1)
    assert m.fix_rate == pytest.approx(2 / 3) and m.accept_rate == pytest.approx(0.5)
    assert m.horizontal_error_m.mean == pytest.approx((5.0 + 0.0) / 2)
    assert m.window_error_m.mean == pytest.approx((1.0 + 2.0) / 2)
    # NEES of the window errors: (1/1)^2 = 1 and (2/1)^2 = 4
    assert m.horizontal_nees.mean == pytest.approx(2.5)
    assert m.vertical_error_m.mean == pytest.approx(1.5)
    assert dict(m.rejected) == {"flat": 1}


def test_no_table_no_section():
    rec = _record([])
    rec.events.clear()
    assert compute_tan(rec) is None


def test_the_lag_matrix_term_is_taken_out_with_the_windows_velocity_error():
    # The navigator's velocity errs by +0.5 m/s north and -0.2 m/s east over the window (0-20 s);
    # the fix at 20 s holds L e_v besides the match's own error, L = [[8, 2], [1, 12]] s: a term
    # of (3.6, -1.9) m. The fix lies (4.6, -1.9) m off the truth: the match's own error is
    # (1, 0) m, NEES 1 against 1 m sigmas.
    t = np.arange(0.0, 30.0, 0.1)
    tel = pd.DataFrame({"t_s": t, "vehicle_id": "uav0", "truth_north_m": 25.0 * t, "truth_east_m": 0.0 * t,
                        "truth_down_m": -300.0 + 0.0 * t, "truth_vn_mps": 25.0 + 0.0 * t, "truth_ve_mps": 0.0 * t,
                        "nav_vn_mps": 25.5 + 0.0 * t, "nav_ve_mps": -0.2 + 0.0 * t})
    row = dict(vehicle_id="uav0", accepted=True, cov_ne_m2=0.0, samples=100, roughness_m=8.0, mass_in_ellipse=0.99,
               edge_mass=0.0, outliers=0, truth_down_m=-300.0, truth_height_agl_m=300.0, t_s=20.0, fix=True,
               fix_north_m=500.0 + 4.6, fix_east_m=-1.9, fix_down_m=-300.0, truth_north_m=500.0, truth_east_m=0.0,
               sigma_north_m=1.0, sigma_east_m=1.0, sigma_down_m=1.0, vel_lag_s=10.0, mean_north_m=math.nan,
               mean_east_m=math.nan, lag_nn_s=8.0, lag_ne_s=2.0, lag_en_s=1.0, lag_ee_s=12.0, window_start_s=0.0,
               reason="")
    m = compute_tan(RunRecord(tel, {"vehicles": [{"id": "uav0"}]}, {"tan": pd.DataFrame([row])}))
    assert m.window_error_m.mean == pytest.approx(1.0)
    assert m.horizontal_nees.mean == pytest.approx(1.0)
    assert m.horizontal_error_m.mean == pytest.approx(math.hypot(4.6, 1.9))
