"""run.json's environment: what a record's bits depend on besides the scenario and seed."""

import copy
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from testbench.cli import main
from testbench.sim.provenance import environment, numerics_differences


def test_environment_names_the_numerical_builds_of_this_process():
    env = environment()
    assert env["packages"]["numpy"] == np.__version__
    assert env["packages"]["jsbsim"] and env["packages"]["opencv-python-headless"]
    assert env["python"].count(".") == 2
    # numpy's run-time SIMD dispatch: the groups this CPU gets (x86: X86_V2 / V3 / V4 ...)
    assert env["numpy_simd"] is None or isinstance(env["numpy_simd"], list)
    json.dumps(env)  # it goes into run.json as it is


def test_numerics_differences_names_what_changes_the_numbers():
    a = environment()
    assert numerics_differences(a, copy.deepcopy(a)) in ([], ["code: uncommitted changes in the base and the new"])
    b = copy.deepcopy(a)
    b["numpy_simd"] = ["X86_V3", "X86_V4"]
    b["packages"]["opencv-python-headless"] = "4.8.0.76"
    b["testbench"] = {"version": "0.1.0", "git_commit": "f" * 40, "git_dirty": False}
    diffs = numerics_differences(a, b)
    assert any(d.startswith("numpy CPU features") for d in diffs)
    assert any(d.startswith("opencv-python-headless") and "4.8.0.76" in d for d in diffs)
    assert any(d.startswith("code: commit") for d in diffs)
    assert numerics_differences(None, a) == ["environment not recorded"]


def _run_folder(path, environment_):
    path.mkdir()
    (path / "metrics.json").write_text(json.dumps({"nav": {"horizontal_error_m": {"mean": 1.0}}}))
    (path / "run.json").write_text(json.dumps({"scenario_name": "s", "environment": environment_}))
    return str(path)


@pytest.mark.parametrize("change, noted", [(None, False), ("numpy_simd", True)])
def test_compare_notes_runs_made_under_different_numerics(tmp_path, capsys, change, noted):
    env = environment()
    env["testbench"]["git_dirty"] = False  # the test's own checkout may hold uncommitted changes
    other = copy.deepcopy(env)
    if change:
        other[change] = ["X86_V4"]
    a, b = _run_folder(tmp_path / "a", env), _run_folder(tmp_path / "b", other)
    assert main(["compare", a, b]) == 0
    err = capsys.readouterr().err
    assert ("numpy CPU features" in err) is noted


def test_bench_json_says_which_machine_and_builds_made_its_figures(tmp_path):
    out = tmp_path / "bench.json"
    assert main(["bench", "--only", "engine", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["engine.overhead_ratio"] > 0
    assert data["meta"]["environment"]["packages"]["numpy"] == np.__version__


@pytest.mark.parametrize("user_value, expected", [(None, "False"), ("1", "True")])
def test_cli_turns_numpys_huge_page_advice_off_unless_the_user_set_it(user_value, expected):
    # The command's import must come before numpy's (numpy reads the variable once, at import),
    # so this runs in a fresh interpreter: testbench.cli first, as the console script does.
    env = {k: v for k, v in os.environ.items() if k != "NUMPY_MADVISE_HUGEPAGE"}
    if user_value is not None:
        env["NUMPY_MADVISE_HUGEPAGE"] = user_value
    code = ("import testbench.cli, numpy; "
            "print(numpy._core.multiarray._get_madvise_hugepage())")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == expected
