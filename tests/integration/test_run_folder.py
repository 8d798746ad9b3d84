"""A run's --out folder: what an earlier run left there is not passed off as this run's, and a
run folder and a batch folder are not written into each other."""

import json
from pathlib import Path

from testbench.cli import main

SCENARIO = str(Path(__file__).resolve().parents[2] / "scenarios" / "fixedwing_racetrack.yaml")
SHORT = ["--set", "duration_s=1", "--no-report"]


def test_a_run_removes_what_an_earlier_run_into_its_folder_left(tmp_path, capsys):
    out = tmp_path / "run"
    # What an earlier scene-matching swarm run would have left, and a file of the user's own.
    stale = ["trajectories/uav1_truth.tum", "trajectories/uav1_nav.tum", "events/ismn.parquet", "events/relnav.parquet",
             "ismn_examples/t00012.00.npz", "frames/down_000010.png", "report.pdf", "map_preview.png"]
    for name in stale + ["notes.txt", "events/my_table.csv"]:
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        (out / name).write_text("earlier")
    assert main(["run", SCENARIO, "--out", str(out), *SHORT]) == 0
    assert not [name for name in stale if (out / name).exists()]
    assert sorted(p.name for p in (out / "trajectories").iterdir()) == ["uav0_nav.tum", "uav0_truth.tum"]
    assert (out / "notes.txt").read_text() == "earlier" and (out / "events" / "my_table.csv").exists()
    assert "ismn" not in json.loads((out / "metrics.json").read_text())


def test_a_run_and_a_batch_do_not_share_a_folder(tmp_path, capsys):
    batch, run = tmp_path / "batch", tmp_path / "run"
    batch.mkdir()
    (batch / "batch.json").write_text("{}")
    assert main(["run", SCENARIO, "--out", str(batch), *SHORT]) == 2
    assert "holds a Monte Carlo batch (batch.json)" in capsys.readouterr().err
    assert sorted(p.name for p in batch.iterdir()) == ["batch.json"]
    assert main(["run", SCENARIO, "--out", str(run), *SHORT]) == 0
    assert main(["montecarlo", SCENARIO, "--runs", "1", "--workers", "1", "--out", str(run), "--set", "duration_s=1"]) == 2
    assert "holds a run of `testbench run` (run.json)" in capsys.readouterr().err
    assert not (run / "batch.json").exists() and not (run / "runs").exists()
