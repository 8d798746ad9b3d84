"""`testbench ismn replay` end to end: a short recorded run's frames through the pipeline."""

from __future__ import annotations

import json
from pathlib import Path

from testbench.cli import main

SCENARIO = str(Path(__file__).resolve().parents[3] / "scenarios" / "paper_ismn_800m.yaml")


def test_replay_scores_a_recorded_runs_frames(tmp_path, capsys):
    run_dir = tmp_path / "run"
    assert main(["run", SCENARIO, "--set", "duration_s=2", "--no-report", "--out", str(run_dir)]) in (0, 3)
    capsys.readouterr()
    # The true pose as the estimate (the recorded 2 s heading sigma would hold the pipeline back).
    assert main(["ismn", "replay", SCENARIO, str(run_dir), "--t0", "1", "--t1", "2", "--step", "1", "--est-truth",
                 "--pipeline", '{"max_heading_sigma_deg": null}', "--frames-dir", str(tmp_path / "frames")]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["n"] == 2 and summary["fix_rate"] == 1.0
    assert summary["max"] < 5.0  # metres: the pipeline locates the rendered frames on the other season's map


def test_a_run_records_the_image_heading_next_to_each_accepted_fix(tmp_path):
    """heading_from_image on: every accepted scene-matching fix is followed in the corrections
    table by a heading correction of the same time (the engine records both corrections the
    navigator returns), and no heading comes without an accepted fix."""
    import pandas as pd

    run_dir = tmp_path / "run"
    assert main(["run", SCENARIO, "--set", "duration_s=5", "--no-report", "--out", str(run_dir),
                 "--set", "vehicles.uav0.aids.ismn.pipeline.heading_from_image=true",
                 "--set", "vehicles.uav0.aids.ismn.pipeline.max_heading_sigma_deg=null"]) in (0, 3)
    c = pd.read_parquet(run_dir / "events" / "corrections.parquet")
    fixes = c[(c.kind == "position_fix:ismn") & c.accepted]
    headings = c[c.kind == "heading_fix:ismn"]
    assert len(fixes) >= 3
    assert sorted(headings.t_s) == sorted(fixes.t_s)
    assert (headings.nis < 50.0).all()
