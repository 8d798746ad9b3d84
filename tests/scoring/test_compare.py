"""Comparing two runs or two batches: the direction of a metric from its name, a run's changes
against the tolerance, a batch's paired and unpaired rank tests (a real shift is found, a
reshuffle of the same scatter is not), and the `testbench compare` command end to end on run
and batch folders, with its bad-input messages, and on real records of the racetrack."""

import json
import math

import numpy as np
import pandas as pd
import pytest

from testbench.cli import main
from testbench.scoring.compare import compare_batches, compare_runs, direction, failed, runs_are_paired
from testbench.sim.bench import SCENARIOS_DIR


@pytest.mark.parametrize("key, expected", [
    ("nav.horizontal_error_m.mean", -1),
    ("ismn.latency_ms.p95", -1),
    ("control.waypoint_overshoot_m.max", -1),
    ("ismn.fix_rate", +1),
    ("relnav.track_id_correct_rate", +1),
    ("real_time_factor", +1),
    ("relnav.id_ambiguous_rate", 0),
    ("relnav.within_3sigma_rate", 0),
    ("nav.nees.position.mean", 0),
    ("nav.nis.gnss.accept_rate", 0),
    ("nav.spoofed.gnss_accept_rate", -1),  # the spoofer's fixes the filter took
    ("nav.spoofed.gnss_captured_s", -1),
    ("nav.spoofed.horizontal_error_m.max", -1),
    ("nav.horizontal_error_m.n", 0),
    ("control.bank_max_deg", 0),
    ("nav.lost_at_s", 0),
    ("batch.nees_position.fraction_within", +1),
    ("batch.threshold_pass_rate.value", +1),
    ("ismn.false_fixes", -1),
    ("vehicles.uav0.ismn.false_fixes_accepted", -1),
    ("ismn.acquisition.first_fix_s", -1),
    ("ismn.acquisition.error_before_m", 0),  # the prior's draw
    ("ismn.acquisition.sigma_before_m", 0),
    ("ismn.acquisition.error_after_m", -1),
    ("ismn.acquisition.held", 0),
])
def test_direction_from_the_key(key, expected):
    assert direction(key) == expected


def test_runs_changes_against_the_tolerance():
    base = {"nav.horizontal_error_m.mean": 1.00, "ismn.fix_rate": 0.98, "relnav.error_m.max": 2.0,
            "control.bank_max_deg": 30.0, "real_time_factor": 10.0, "formation.error_m.rms": 2.0, "nav.lost_at_s": 120.0}
    new = {"nav.horizontal_error_m.mean": 1.01, "ismn.fix_rate": 1.00, "relnav.error_m.max": 2.5,
           "control.bank_max_deg": 31.0, "real_time_factor": 5.0, "nav.vertical_error_m.mean": 0.3}
    by_key = {c.key: c for c in compare_runs(base, new, rel_tol=0.02)}
    assert by_key["nav.horizontal_error_m.mean"].verdict == "same"  # +1 % < 2 %
    assert by_key["ismn.fix_rate"].verdict == "better"
    assert by_key["relnav.error_m.max"].verdict == "worse"
    assert by_key["relnav.error_m.max"].rel == pytest.approx(0.25)
    assert by_key["control.bank_max_deg"].verdict == "changed"
    assert by_key["real_time_factor"].verdict == "worse" and by_key["real_time_factor"].timing
    assert by_key["formation.error_m.rms"].verdict == "missing"
    assert by_key["nav.lost_at_s"].verdict == "missing"
    assert by_key["nav.vertical_error_m.mean"].verdict == "new"
    # What fails: the worse error and the missing formation figure; not the slower machine
    # (unless asked), not the neutral nav.lost_at_s that is absent when nothing was lost.
    assert {c.key for c in failed(by_key.values())} == {"relnav.error_m.max", "formation.error_m.rms"}
    assert "real_time_factor" in {c.key for c in failed(by_key.values(), timing_counts=True)}
    # A number that stops being one broke.
    nan_case = compare_runs({"relnav.error_m.mean": 0.2}, {"relnav.error_m.mean": math.nan})
    assert nan_case[0].verdict == "worse"


def _batch(values: np.ndarray, key: str = "nav.horizontal_error_m.mean", seeds=None) -> pd.DataFrame:
    n = len(values)
    return pd.DataFrame({"run": np.arange(n), "seed_entropy": 1.0 if seeds is None else seeds,
                         "seed_spawn_key": [f"[{i}]" for i in range(n)], "vary.x": np.linspace(-1, 1, n),
                         "status": "passed", key: values, "wall_time_s": 10.0 + np.arange(n)})


def test_paired_batches_find_a_small_consistent_shift_and_not_noise():
    rng = np.random.default_rng(3)
    per_run = rng.lognormal(0.0, 0.5, 20)  # the runs differ a lot from each other...
    base = _batch(per_run)
    new = _batch(per_run * 0.95)  # ...and the change takes 5 % off every one of them
    assert runs_are_paired(base, new)
    changes, paired = compare_batches(base, new)
    c = {x.key: x for x in changes}["nav.horizontal_error_m.mean"]
    assert paired and c.verdict == "better" and c.p < 0.001 and c.n == 20
    # Unpaired (other seeds), the same 5 % is lost in the run-to-run scatter.
    changes, paired = compare_batches(base, _batch(per_run * 0.95, seeds=2.0))
    assert not paired and {x.key: x for x in changes}["nav.horizontal_error_m.mean"].verdict == "same"
    # Noise alone: the same runs with small independent changes either way.
    noisy = _batch(per_run * (1 + 0.01 * rng.standard_normal(20)))
    changes, _ = compare_batches(base, noisy)
    assert {x.key: x for x in changes}["nav.horizontal_error_m.mean"].verdict == "same"
    # Significant but too small to matter: 0.1 % off every run.
    changes, _ = compare_batches(base, _batch(per_run * 0.999))
    tiny = {x.key: x for x in changes}["nav.horizontal_error_m.mean"]
    assert tiny.p < 0.001 and tiny.verdict == "same"


def test_failed_runs_are_left_out_of_a_batch():
    base = _batch(np.ones(6))
    new = _batch(np.ones(6))
    new.loc[0, "status"] = "aborted"
    new.loc[0, "nav.horizontal_error_m.mean"] = np.nan
    changes, paired = compare_batches(base, new)
    assert not paired  # run 0 is not in the new batch's finished runs
    assert {x.key: x for x in changes}["nav.horizontal_error_m.mean"].n == 5


def _run_folder(path, metrics, scenario="paper_ismn_800m", **run_info):
    path.mkdir()
    (path / "metrics.json").write_text(json.dumps(metrics))
    (path / "run.json").write_text(json.dumps({"scenario_name": scenario, **run_info}))
    return path


def test_an_aborted_run_is_worse_whatever_its_figures(tmp_path, capsys):
    """A run that aborted early has figures of its first seconds only, which can look better
    than the whole run's: its status makes the comparison fail, and says why it aborted."""
    done = _run_folder(tmp_path / "done", {"status": "completed", "nav": {"horizontal_error_m": {"mean": 1.0}}},
                       status="completed")
    reason = "vehicle uav0, t=12.5 s: navigation diverged"
    crashed = _run_folder(tmp_path / "crashed", {"status": "aborted", "nav": {"horizontal_error_m": {"mean": 0.2}}},
                          status="aborted", abort_reason=reason)
    out_json = tmp_path / "cmp.json"
    assert main(["compare", str(done), str(crashed), "--json", str(out_json)]) == 3
    out = capsys.readouterr().out
    assert "status: completed -> aborted  worse" in out and f"new: {reason}" in out
    rows = {r["key"]: r for r in json.loads(out_json.read_text())}
    assert rows["status"] == {"key": "status", "base": "completed", "new": "aborted", "verdict": "worse"}
    assert rows["nav.horizontal_error_m.mean"]["verdict"] == "better"
    assert main(["compare", str(crashed), str(done)]) == 3  # the error grew 5x, but the run now flies to its end
    assert "status: aborted -> completed  better" in capsys.readouterr().out
    assert main(["compare", str(done), str(done)]) == 0
    assert "status:" not in capsys.readouterr().out


def test_a_batch_with_more_aborted_runs_is_worse(tmp_path, capsys):
    """The per-run figures and the pass rate are of the finished runs only: the share of runs
    that finished is what shows the aborted ones."""
    for name, counts in (("base", {"passed": 12}), ("new", {"passed": 10, "aborted": 2})):
        (tmp_path / name).mkdir()
        runs = _batch(np.ones(12))
        runs.loc[12 - counts.get("aborted", 0):, "status"] = "aborted"
        runs.to_parquet(tmp_path / name / "runs.parquet")
        (tmp_path / name / "summary.json").write_text(json.dumps(
            {"status_counts": counts, "threshold_pass_rate": {"value": 1.0, "n": counts["passed"]}, "metrics": {}}))
    out_json = tmp_path / "cmp.json"
    assert main(["compare", str(tmp_path / "base"), str(tmp_path / "new"), "--json", str(out_json)]) == 3
    rows = {r["key"]: r for r in json.loads(out_json.read_text())}
    assert rows["batch.finished_rate"]["base"] == 1.0 and rows["batch.finished_rate"]["new"] == pytest.approx(10 / 12)
    assert rows["batch.finished_rate"]["verdict"] == "worse"
    assert rows["batch.threshold_pass_rate.value"]["verdict"] == "same"


def test_compare_command_on_runs(tmp_path, capsys):
    base = _run_folder(tmp_path / "a", {"nav": {"horizontal_error_m": {"mean": 1.0}}, "ismn": {"fix_rate": 0.99},
                                        "vehicles": {"uav0": {"nav": {"horizontal_error_m": {"mean": 1.0}}}}})
    same = _run_folder(tmp_path / "b", {"nav": {"horizontal_error_m": {"mean": 1.005}}, "ismn": {"fix_rate": 0.99},
                                        "vehicles": {"uav0": {"nav": {"horizontal_error_m": {"mean": 9.0}}}}})
    worse = _run_folder(tmp_path / "c", {"nav": {"horizontal_error_m": {"mean": 1.3}}, "ismn": {"fix_rate": 0.99}})
    assert main(["compare", str(base), str(same)]) == 0  # per-vehicle figures are left out by default
    assert main(["compare", str(base), str(same), "--details"]) == 3
    out_json = tmp_path / "cmp.json"
    assert main(["compare", str(base), str(worse), "--json", str(out_json)]) == 3
    out = capsys.readouterr().out
    assert "nav.horizontal_error_m.mean" in out and "+30.0%" in out and "worse" in out
    rows = {r["key"]: r for r in json.loads(out_json.read_text())}
    assert rows["nav.horizontal_error_m.mean"]["verdict"] == "worse" and rows["ismn.fix_rate"]["p"] is None


def test_compare_command_on_batches(tmp_path, capsys):
    rng = np.random.default_rng(5)
    per_run = rng.lognormal(0.0, 0.5, 12)
    for name, vals, within in (("base", per_run, 0.92), ("new", per_run * 1.1, 0.57)):
        (tmp_path / name).mkdir()
        _batch(vals).to_parquet(tmp_path / name / "runs.parquet")
        (tmp_path / name / "batch.json").write_text(json.dumps({"scenario": "scenarios/paper_ismn_800m.yaml"}))
        (tmp_path / name / "summary.json").write_text(json.dumps(
            {"nees_position": {"fraction_within": within, "mean_of_average": 2.9, "dof": 3}, "metrics": {}}))
    out_json = tmp_path / "cmp.json"
    assert main(["compare", str(tmp_path / "base"), str(tmp_path / "new"), "--json", str(out_json)]) == 3
    out = capsys.readouterr().out
    assert "paired runs, Wilcoxon" in out and "worse" in out
    rows = {r["key"]: r for r in json.loads(out_json.read_text())}
    assert rows["nav.horizontal_error_m.mean"]["verdict"] == "worse" and rows["nav.horizontal_error_m.mean"]["n"] == 12
    # The batch-level consistency figure, one number per batch: the share inside the NEES band fell.
    assert rows["batch.nees_position.fraction_within"]["verdict"] == "worse"
    assert rows["batch.nees_position.mean_of_average"]["verdict"] == "same"


@pytest.mark.parametrize("args, message", [
    (["{tmp}"], "neither a run folder"),
    (["{a}", "--rel-tol", "-1"], "--rel-tol"),
    (["{a}", "--alpha", "1.5"], "--alpha"),
    (["{a}", "--only", "nothing.*"], "no metric in common"),
])
def test_compare_bad_input(tmp_path, capsys, args, message):
    a = _run_folder(tmp_path / "a", {"nav": {"horizontal_error_m": {"mean": 1.0}}})
    fill = {"{tmp}": str(tmp_path), "{a}": str(a)}
    argv = ["compare", str(a)] + [fill.get(x, x) for x in args]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_compare_real_runs_same_seed_and_a_changed_autopilot(tmp_path, capsys):
    """End to end on real records: the same scenario and seed twice compare as the same (exit 0);
    a tighter bank limit in the turns changes the flight and is reported."""
    scenario = str(SCENARIOS_DIR / "fixedwing_racetrack.yaml")
    common = ["--no-report", "--set", "duration_s=150"]
    a, b, c = (str(tmp_path / n) for n in "abc")
    assert main(["run", scenario, "--out", a, *common]) in (0, 3)
    assert main(["run", scenario, "--out", b, *common]) in (0, 3)
    assert main(["run", scenario, "--out", c, *common, "--set", "vehicles.uav0.control.params.max_bank_deg=20"]) in (0, 3)
    capsys.readouterr()
    assert main(["compare", a, b, "--all", "--ignore", "*wall_time_s", "--ignore", "real_time_factor"]) == 0
    out = capsys.readouterr().out
    assert " worse" not in out and " better" not in out and "same" in out
    main(["compare", a, c, "--json", str(tmp_path / "ac.json")])
    rows = {r["key"]: r for r in json.loads((tmp_path / "ac.json").read_text())}
    assert rows["control.bank_max_deg"]["new"] < rows["control.bank_max_deg"]["base"]
    assert rows["control.bank_max_deg"]["verdict"] == "changed"
