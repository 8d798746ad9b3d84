"""Optical flow end to end (scenarios/multirotor_flow_wind.yaml): a quad 30 m above textured
farmland in wind and light turbulence, GNSS jammed from 60 s. With the flow sensor and its
rangefinder the INS holds its velocity over the ground, and its claims hold what it errs by;
without them (rotor drag and wind states alone) the same flight drifts several times as far.
And the flow aiding without a rangefinder is bad input."""

from __future__ import annotations

import json
from pathlib import Path

import pyarrow.parquet as pq

from tests.conftest import run_scenario


def _run(out: Path, *sets: str) -> int:
    return run_scenario("multirotor_flow_wind", out, *sets)


def test_flow_holds_the_position_the_drag_alone_loses(tmp_path):
    code = _run(tmp_path / "flow", "duration_s=150")
    _run(tmp_path / "drag", "duration_s=150", "vehicles.quad0.navigation.params.optical_flow=null")
    # The flow flight is also the scenario's regression gate (tests/regression leaves it out
    # rather than fly it a third time): 150 s, 90 of them without GNSS, pass every threshold.
    thresholds = json.loads((tmp_path / "flow" / "metrics.json").read_text())["thresholds"]
    assert code == 0 and thresholds["passed"] and not thresholds["failed"], thresholds["failed"]
    flow = json.loads((tmp_path / "flow" / "metrics.json").read_text())["nav"]
    drag = json.loads((tmp_path / "drag" / "metrics.json").read_text())["nav"]
    # 90 s without GNSS (seed 1; 2026-12-01, with the tilted ground's reading and the flow's
    # error decorrelating over the ground its view passes): flow 4.7 m at most, drag 25.6 m (and
    # 156 m at 300 s, where the flow stays under 7.3 m).
    assert flow["denied"]["horizontal_error_m"]["max"] < 7.0
    assert drag["denied"]["horizontal_error_m"]["max"] > 3.0 * flow["denied"]["horizontal_error_m"]["max"]
    # The flow's slow error is a filter state, so the claims follow the errors.
    assert flow["nees"]["position"]["mean_per_dof"] < 2.5 and flow["nees"]["velocity"]["mean_per_dof"] < 2.5
    nis = flow["nis"]["optical_flow"]
    # Every sample gated or, while the gate refused many in a row, held out and checked (the
    # flow's hold-out): under a clear sky few are held.
    held = flow["nis"].get("optical_flow:held", {}).get("count", 0)
    assert nis["count"] + held > 0.95 * 150 * 20 and held < 0.05 * 150 * 20 and nis["accept_rate"] > 0.9
    tel = pq.read_table(tmp_path / "flow" / "telemetry.parquet").to_pandas()
    assert "nav_vn_mps" in tel.columns


def test_flow_aiding_without_a_rangefinder_is_bad_input(tmp_path, capsys):
    code = _run(tmp_path / "r", "duration_s=1", "vehicles.quad0.sensors.rangefinder.beam_half_angle_deg=20")
    assert code == 2
    err = capsys.readouterr().err
    assert "navigation.params.optical_flow" in err and "rangefinder" in err
    assert not (tmp_path / "r").exists()


def test_flow_aiding_without_a_flow_sensor_is_bad_input(tmp_path, capsys):
    code = _run(tmp_path / "r", "duration_s=1", "vehicles.quad0.sensors.flow.rate_hz=7")
    # (a flow rate that does not divide the physics rate names the sensor's key)
    assert code == 2 and "flow" in capsys.readouterr().err
