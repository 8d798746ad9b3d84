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
