"""Small hand-made run records for scoring tests (imported by the test modules)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from testbench.scoring.record_io import RunRecord


def straight_telemetry(n: int = 100, dt: float = 0.1, vehicle_id: str = "a", err_ned=(3.0, 4.0, 12.0), **extra) -> pd.DataFrame:
    """A vehicle flying north at 20 m/s, 100 m up, with a constant navigation error err_ned."""
    t = np.arange(n) * dt
    cols = {
        "vehicle_id": [vehicle_id] * n,
        "t_s": t,
        "truth_north_m": 20.0 * t,
        "truth_east_m": np.zeros(n),
        "truth_down_m": np.full(n, -100.0),
        "truth_height_agl_m": np.full(n, 100.0),
        "truth_roll_rad": np.zeros(n),
        "truth_pitch_rad": np.zeros(n),
        "truth_yaw_rad": np.zeros(n),
        "truth_q_rps": np.zeros(n),
        "truth_r_rps": np.zeros(n),
    }
    cols["nav_north_m"] = cols["truth_north_m"] + err_ned[0]
    cols["nav_east_m"] = cols["truth_east_m"] + err_ned[1]
    cols["nav_down_m"] = cols["truth_down_m"] + err_ned[2]
    cols.update(extra)
    return pd.DataFrame(cols)


def record_of(tel: pd.DataFrame, events=None, **info) -> RunRecord:
    run_info = {"scenario_name": "t", "status": "completed", "sim_time_s": float(tel["t_s"].max()), "wall_time_s": 1.0, "real_time_factor": 2.0}
    run_info.update(info)
    return RunRecord(telemetry=tel, run_info=run_info, events=dict(events or {}))
