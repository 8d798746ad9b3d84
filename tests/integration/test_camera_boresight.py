"""A scene-matching camera whose mount is off its calibration, end to end (paper_ismn_800m,
80 s, GNSS jammed from 60 s): the navigator with the camera's boresight states learns the
boresight from the fixes' image-only pose while GNSS holds its position, and scene matching
keeps the position after the jamming; the same flight without the states takes every fix
of the turned camera for a position error.

Measured on the 300 s flight (docs/measurements.md, "A camera off its calibration"): with the
boresight (0.5, -0.5, 0.5) deg, the navigator without the states was lost at 64 s (denied mean
26 m), with them 0.51 m. Here the boresight is (1, -1, 1) deg (1.7 deg in all), which the tiles
find only because they search as far as the camera's heading is uncertain, the unlearnt
boresight's yaw included."""

from __future__ import annotations

import json
from pathlib import Path

from testbench.cli import main

REPO = Path(__file__).resolve().parents[2]
SCENARIO = str(REPO / "scenarios" / "paper_ismn_800m.yaml")
MISALIGNED = "vehicles.uav0.sensors.down.mount_error_deg=[1.0, -1.0, 1.0]"
STATES = ("--set", "vehicles.uav0.navigation.params.camera_boresight={sigma_deg: 1.0}",
          "--set", "vehicles.uav0.aids.ismn.pipeline.pose_from_image=true")


def _run(tmp_path, name, *extra):
    out = tmp_path / name
    code = main(["run", SCENARIO, "--set", "duration_s=80", "--set", MISALIGNED, *extra, "--out", str(out),
                 "--no-report", "--quiet"])
    return code, json.loads((out / "metrics.json").read_text())


def test_the_boresight_states_learn_a_misaligned_camera_and_keep_the_fixes(tmp_path):
    code, m = _run(tmp_path, "states", *STATES)
    nav = m["nav"]
    # (80 s holds no turn, so the turning gate has nothing to score)
    assert code in (0, 3) and all(f["kind"] == "missing" for f in m["thresholds"]["failed"]), m["thresholds"]["failed"]
    # Of 1.7 deg; measured 0.035 deg (claimed 0.061): learnt to 0.1 deg by the image pose, then
    # refined by the MAP fixes' coupling (camera_boresight.handover_sigma_deg).
    b = nav["camera_boresight"]
    assert b["final_error_deg"] < 0.08 and b["final_error_deg"] < 3 * b["final_sigma_deg"], b
    assert nav["denied"]["horizontal_error_m"]["max"] < 2.0
    _, plain = _run(tmp_path, "plain")
    assert plain["ismn"]["smooth"]["horizontal_error_m"]["mean"] > 3 * m["ismn"]["smooth"]["horizontal_error_m"]["mean"]
    assert plain["nav"]["denied"]["horizontal_error_m"]["max"] > 5 * nav["denied"]["horizontal_error_m"]["max"]
    assert "camera_boresight" not in plain["nav"]
