"""GNSS spoofing end to end: the carry-off of scenarios/paper_ismn_spoofed.yaml against the same
flight without scene matching (ins_only_800m), where nothing contradicts the spoofer.

With scene matching the spoofing gate is tested in tests/regression (paper_ismn_spoofed, 120 s,
its own thresholds: error within 10 m, the spoofer's fixes refused within 30 s). This is the
other side, which shows that those figures measure the scene matching and not the spoofer's
clumsiness: with GNSS alone to correct the INS, the filter fuses the dragged fixes to the end
and the vehicle's estimate goes off with them.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from testbench.cli import main

REPO = Path(__file__).resolve().parents[2]
CARRY_OFF = "vehicles.uav0.sensors.gnss.denial=[{type: spoofing, start_s: 60.0, drift_ned_mps: [0.0, 3.0, 0.0], accel_mps2: 0.05}]"


def test_without_scene_matching_the_spoofer_carries_the_estimate_off(tmp_path):
    out = tmp_path / "run"
    code = main(["run", str(REPO / "scenarios" / "ins_only_800m.yaml"), "--set", "duration_s=110", "--set", CARRY_OFF,
                 "--out", str(out), "--no-report", "--quiet"])
    assert code in (0, 3)  # its own thresholds are about jamming, which this run has none of
    info = json.loads((out / "run.json").read_text())
    assert info["gnss_spoofed_windows"] == {"uav0": [[60.0, 110.0]]}
    assert info["gnss_denied_windows"] == {"uav0": []}
    spoofed = json.loads((out / "metrics.json").read_text())["nav"]["spoofed"]
    # 50 s of carry-off: the fixes are 0.05 / 2 * 50^2 = 62 m east at the end, and the filter
    # took them all along.
    assert spoofed["gnss_accept_rate"] > 0.9
    assert spoofed["gnss_captured_s"] > 45.0
    assert spoofed["horizontal_error_m"]["max"] > 40.0
    assert spoofed["duration_s"] == pytest.approx(50.0, abs=0.2)
