"""Waypoint miss and overshoot from a synthetic multirotor record."""

import numpy as np
import pandas as pd
import pytest

from testbench.scoring.metrics_control import waypoint_errors


def _tel(points, targets):
    points = np.asarray(points, float)
    targets = np.asarray(targets, float)
    return pd.DataFrame({
        "vehicle_id": ["q"] * len(points),
        "truth_north_m": points[:, 0], "truth_east_m": points[:, 1], "truth_down_m": points[:, 2],
        "gd_target_n_m": targets[:, 0], "gd_target_e_m": targets[:, 1], "gd_target_d_m": targets[:, 2],
    })


def test_miss_uses_the_closest_approach_between_records_and_overshoot_the_path_deviation():
    wp1, wp2 = (10.0, 0.0, -100.0), (10.0, 10.0, -100.0)
    # Flies north towards wp1, passes 0.5 m east of it between two records, overshoots 2 m
    # north, then heads to wp2.
    pts = [(0, 0.5, -100), (8, 0.5, -100), (12, 0.5, -100), (12, 3, -100), (10.5, 8, -100), (10, 10, -100)]
    tgt = [wp1, wp1, wp1, wp2, wp2, wp2]
    miss, over = waypoint_errors(_tel(pts, tgt))
    assert miss == pytest.approx([0.5])  # between rows 1 and 2, not at either row (2.06 m)
    # overshoot: (12, 3) lies 2 m from the incoming leg's end and 2 m from the outgoing line
    assert over == pytest.approx([2.0])


def test_no_targets_no_waypoint_metrics():
    nan = (np.nan, np.nan, np.nan)
    miss, over = waypoint_errors(_tel([(0, 0, 0), (1, 0, 0)], [nan, nan]))
    assert miss.size == 0 and over.size == 0
