"""A cold start without GNSS, end to end (paper_ismn_cold_start shortened to 16 s): the receiver
jammed from launch, the starting position drawn from a 1 km prior. The ismn aid holds the first
fixes until three in a row agree through the INS's displacement, delivers the third with its
claim widened, and the estimate comes from hundreds of metres off to within metres; the metrics
say when and from where. Without the acquisition the first fix goes through at once.

Over real imagery (naip_ismn_cold_start, 14 s): the camera renders the 2018 NAIP image and
the vehicle carries 2016's, and the acquisition takes the same few seconds.

The batch figures (with and without the confirmation, 1 km and 3 km priors, and over NAIP):
docs/measurements.md, "A cold start without GNSS"."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from testbench.cli import main

REPO = Path(__file__).resolve().parents[2]
SCENARIO = str(REPO / "scenarios" / "paper_ismn_cold_start.yaml")
NAIP_SCENARIO = str(REPO / "scenarios" / "naip_ismn_cold_start.yaml")


def _run(
    tmp_path: Path, name: str, *sets: str, scenario: str = SCENARIO, duration_s: float = 16.0
) -> tuple[dict, pd.DataFrame, pd.DataFrame]:
    out = tmp_path / name
    args = ["run", scenario, "--set", f"duration_s={duration_s}", "--out", str(out), "--no-report", "--quiet"]
    for s in sets:
        args += ["--set", s]
    assert main(args) in (0, 3)
    metrics = json.loads((out / "metrics.json").read_text())
    return metrics, pd.read_parquet(out / "events" / "ismn.parquet"), pd.read_parquet(out / "events" / "corrections.parquet")


def test_the_first_fixes_are_held_until_they_agree_and_the_estimate_is_acquired(tmp_path):
    m, ismn, corr = _run(tmp_path, "acquire")
    assert not corr["kind"].str.startswith("gnss").any()  # jammed from launch: never a GNSS fix
    acq = m["ismn"]["acquisition"]
    assert acq["error_before_m"] > 100.0 and acq["sigma_before_m"] > 900.0  # the 1 km prior's draw
    assert acq["first_fix_s"] <= 10.0 and acq["error_after_m"] < 3.0
    fixes = ismn[ismn["fix"]]
    held = fixes[fixes["reason"].str.startswith("held for confirmation")]
    assert len(held) >= 2 and acq["held"] == len(held)
    assert not held["accepted"].any() and held["delivered_t_s"].isna().all()  # never delivered
    first = fixes[fixes["accepted"]].iloc[0]
    assert first["t_s"] == acq["first_fix_s"] and first["t_s"] > held["t_s"].max()
    # Its claim widened to acquired_sigma_m (5 m): the fixes after it refine the position.
    assert first["sigma_north_m"] >= 5.0 - 1e-9 and first["sigma_east_m"] >= 5.0 - 1e-9
    after = fixes[(fixes["t_s"] > first["t_s"])]
    assert after["accepted"].mean() > 0.8 and (after["sigma_north_m"] < 5.0).all()
    assert m["ismn"]["false_fixes_accepted"] == 0


def test_without_the_acquisition_the_first_fix_goes_through_at_once(tmp_path):
    m, ismn, _ = _run(tmp_path, "direct", "vehicles.uav0.aids.ismn.acquisition=null")
    fixes = ismn[ismn["fix"]]
    assert m["ismn"]["acquisition"]["held"] == 0
    assert m["ismn"]["acquisition"]["first_fix_s"] == fixes["t_s"].min()
    assert np.all(fixes["reason"] == "")


def test_over_real_imagery_of_another_year_the_estimate_is_acquired(tmp_path, realdata, monkeypatch):
    monkeypatch.setenv("TESTBENCH_DATA", str(realdata))
    m, ismn, corr = _run(tmp_path, "naip", scenario=NAIP_SCENARIO, duration_s=14.0)
    assert not corr["kind"].str.startswith("gnss").any()
    acq = m["ismn"]["acquisition"]
    assert acq["error_before_m"] > 100.0 and acq["sigma_before_m"] > 900.0
    assert acq["held"] >= 2 and acq["first_fix_s"] <= 10.0
    # 2016 against 2018: the fixes' floor is 2 m (the scenario's sigma_floor_m), not 0.2 m.
    assert acq["error_after_m"] < 5.0
    assert m["ismn"]["false_fixes_accepted"] == 0
    fixes = ismn[ismn["fix"]]
    assert fixes[fixes["t_s"] > acq["first_fix_s"]]["accepted"].mean() > 0.8
