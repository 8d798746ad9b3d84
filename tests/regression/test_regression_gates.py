"""Regression gates: short versions of the shipped scenarios must pass their own `thresholds:`.

Each case flies a scenario through the real command line (in-process), shortened only as far as
keeps every phase its thresholds look at (the scene-matching flights keep GNSS denial, or the
spoofer, from 60 s and their first 30 deg turn at about 96-111 s; the cold starts 30 s, the first
fix and 20 s of settled flight after it; the terrain-aided flights 240 s
of denial, twelve windows of radar ranges and two turns; the control studies fly in full), and asserts
exit status 0 with every threshold in `metrics.json` passed. A renamed or missing metric fails
here too (thresholds.py treats a missing key as a failure).

Left out, with the reason:
- swarm_cnn: the CNN detector runs at about 35 ms per region on one core, so even a few
  simulated seconds cost minutes; its thresholds are those of paper_swarm_relnav, which is
  gated here, and the detector itself is gated by tests/navigation/relative/cnn.
- swarm_fixedwing, swarm_canyon_nlos: studies without thresholds (they report figures).
- multirotor_flow_wind: gated by tests/integration/test_flow_aided_ins.py, whose 150 s flow
  flight (90 s without GNSS) must pass every threshold too; a 120 s run here would fly the
  same flight a third time in the suite.

Known failures, kept visible (measured 2026-11-28, evening, since the leader's speed rises as an
S-curve; before, 1.26 m, 0.197 m, 0.977 (0.995), 2.57 m):
paper_swarm_relnav does not meet its gates yet (15 s: relnav.error_m.max 1.62 m
against 0.4, mean 0.187 m against 0.15, the estimates' IDs 0.977 against 0.99 (the track-frames'
0.994), formation.error_m.rms 2.67 m against 2 in the leader's start-up; the arrowhead's lattice puts
three or four vehicles on one line of sight, their LED blobs merge and part and tracks carry the
wrong ID for a while; the mean is the vehicles' own heading error, about 0.7 mrad RMS). It is a strict xfail, so the day
it passes the suite says so and its marker must go (lowalt_ismn_150m's went on 2026-11-24: its
consumer-grade quad now keeps the scene match, 300 s fix rate 0.995 where it had lost the match at
60-85 s; the magnetic heading's tilt coupling alone gave 0.81, with the fixes' attitude coupling
0.90, with the heading-aware tile search 0.995).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from testbench.cli import main
from tests.conftest import use_data_if_scenario_needs_it

REPO = Path(__file__).resolve().parents[2]

# scenario -> simulated seconds of its regression version (None: the full flight)
GATED = {
    "fixedwing_racetrack": None,
    "multirotor_waypoints": None,
    "multirotor_wind_drag": None,
    "multirotor_flow_kampala": 120.0,
    "multirotor_urban_street": None,
    "ins_only_800m": 120.0,
    "paper_ismn_800m": 120.0,
    "paper_ismn_spoofed": 120.0,
    "paper_ismn_anomaly": 120.0,
    "paper_ismn_boresight": 120.0,
    "paper_ismn_clouds": 120.0,
    "ins_spoofed_800m": 120.0,
    "naip_ismn_800m": 120.0,
    "paper_ismn_cold_start": 30.0,
    "naip_ismn_cold_start": 30.0,
    "lowalt_ismn_150m": 120.0,
    "tan_radalt_300m": 300.0,
    "tan_sainthelens": 300.0,
    "paper_swarm_relnav": 15.0,
}


KNOWN_FAILING = {
    "paper_swarm_relnav": "relative navigation and formation gates not met yet (15 s: relnav max 1.62 m, mean 0.187 m, "
                          "IDs 0.977 of the estimates, 0.994 of the track-frames, formation rms 2.67 m)",
}


def _cases():
    for name in sorted(GATED):
        marks = [pytest.mark.xfail(reason=KNOWN_FAILING[name], strict=True)] if name in KNOWN_FAILING else []
        yield pytest.param(name, id=name, marks=marks)


@pytest.mark.parametrize("name", list(_cases()))
def test_short_scenario_passes_its_thresholds(name, tmp_path, monkeypatch):
    path = REPO / "scenarios" / f"{name}.yaml"
    use_data_if_scenario_needs_it(path, monkeypatch)
    out = tmp_path / "run"
    args = ["run", str(path), "--out", str(out), "--no-report", "--quiet"]
    if GATED[name] is not None:
        args += ["--set", f"duration_s={GATED[name]}"]
    code = main(args)
    metrics = json.loads((out / "metrics.json").read_text())
    failed = metrics["thresholds"]["failed"]
    assert code == 0 and not failed, f"exit {code}; failed thresholds: {[f['reason'] for f in failed]}"
    assert metrics["thresholds"]["passed"], "the scenario has no thresholds to gate"
