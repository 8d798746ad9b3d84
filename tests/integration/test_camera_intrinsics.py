"""A scene-matching camera off its intrinsic calibration, end to end (paper_ismn_800m shortened
to 30 s, GNSS on): the true intrinsics render, the run records them, the navigator's estimate of
them is in the telemetry and scored.

How the error hurts and how well the states learn it over the full flight: docs/measurements.md,
"A camera off its intrinsic calibration"."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from testbench.cli import main

REPO = Path(__file__).resolve().parents[2]
SCENARIO = str(REPO / "scenarios" / "paper_ismn_800m.yaml")


def test_the_intrinsics_error_is_recorded_estimated_and_scored(tmp_path):
    out = tmp_path / "run"
    code = main(["run", SCENARIO, "--set", "duration_s=30",
                 "--set", "vehicles.uav0.sensors.down.principal_point_error_px=[0.8, -0.4]",
                 "--set", "vehicles.uav0.sensors.down.focal_error_rel=0.001",
                 "--set", "vehicles.uav0.navigation.params.camera_intrinsics={principal_point_sigma_px: 1.0}",
                 "--out", str(out), "--no-report", "--quiet"])
    assert code in (0, 3), code  # 30 s hold no GNSS-denied time to score
    run = json.loads((out / "run.json").read_text())
    assert run["camera_intrinsics_error"] == {"uav0": {"down": {"focal_error_rel": 0.001,
                                                                "principal_point_error_px": [0.8, -0.4]}}}
    assert run["camera_intrinsics_estimated"] == {"uav0": "down"}
    tel = pd.read_parquet(out / "telemetry.parquet")
    sig_u = tel["nav_sigma_camera_pp_u_px"].to_numpy()
    sig_f = tel["nav_sigma_camera_focal_rel"].to_numpy()
    assert sig_u[0] == 1.0 and sig_f[0] == 0.002 and np.all(np.diff(sig_u) <= 1e-12)  # constants: sigmas only fall
    assert sig_f[-1] < 0.6 * sig_f[0]  # GNSS heights against the fixes' show the focal length (0.52 when written)
    m = json.loads((out / "metrics.json").read_text())["nav"]
    stats = m["camera_intrinsics"]
    est = np.array([tel["nav_camera_pp_u_px"].iloc[-1], tel["nav_camera_pp_v_px"].iloc[-1]])
    assert abs(stats["final_principal_point_error_px"] - np.hypot(*(est - [0.8, -0.4]))) < 1e-9
    assert abs(stats["final_focal_error_ppm"] - 1e6 * abs(tel["nav_camera_focal_rel"].iloc[-1] - 0.001)) < 1e-6
    assert m["nees"]["camera_intrinsics"]["dof"] == 3.0
