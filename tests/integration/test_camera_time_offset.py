"""A scene-matching camera whose clock is off, end to end (paper_ismn_800m shortened to 30 s,
GNSS on): the frames are rendered at their exposure, 40 ms before their stamps; the run
records the true offset, the navigator's estimate of it in the telemetry, and scores it.

How the offset hurts and how well the state learns it over the full flight: docs/measurements.md,
"A camera clock off the IMU's"."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from testbench.cli import main

REPO = Path(__file__).resolve().parents[2]
SCENARIO = str(REPO / "scenarios" / "paper_ismn_800m.yaml")


def test_the_offset_is_recorded_estimated_and_scored(tmp_path):
    out = tmp_path / "run"
    code = main(["run", SCENARIO, "--set", "duration_s=30", "--set", "vehicles.uav0.sensors.down.time_offset_s=0.04",
                 "--set", "vehicles.uav0.navigation.params.camera_time_offset={sigma_s: 0.05}",
                 "--out", str(out), "--no-report", "--quiet"])
    assert code in (0, 3), code  # 30 s hold no GNSS-denied time to score
    run = json.loads((out / "run.json").read_text())
    assert run["camera_time_offset_s"] == {"uav0": {"down": 0.04}}
    assert run["camera_time_offset_estimated"] == {"uav0": "down"}
    tel = pd.read_parquet(out / "telemetry.parquet")
    est, sig = tel["nav_camera_time_offset_s"].to_numpy(), tel["nav_sigma_camera_time_offset_s"].to_numpy()
    assert est[0] == 0.0 and sig[0] == 0.05 and np.all(np.diff(sig) <= 1e-12)  # a constant: its sigma only falls
    m = json.loads((out / "metrics.json").read_text())["nav"]
    stats = m["camera_time_offset"]
    assert abs(stats["final_error_ms"] - 1e3 * abs(est[-1] - 0.04)) < 1e-6
    assert stats["final_sigma_ms"] == 1e3 * sig[-1] or abs(stats["final_sigma_ms"] - 1e3 * sig[-1]) < 1e-6
    assert m["nees"]["camera_time_offset"]["dof"] == 1.0
