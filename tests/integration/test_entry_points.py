"""The three ways to start the command line (the `testbench` console script, `python cli.py`,
`python -m testbench`) are one entry point: the same output and the same exit status."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def _entry_points():
    points = {"cli.py": [sys.executable, str(REPO / "cli.py")], "python -m": [sys.executable, "-m", "testbench"]}
    script = Path(sys.executable).with_name("testbench")
    script = script if script.exists() else shutil.which("testbench")
    if script:
        points["console script"] = [str(script)]
    return points


@pytest.mark.parametrize("args, status", [(["--version"], 0), (["run", "no/such/scenario.yaml"], 2)])
def test_every_entry_point_gives_the_same_output_and_status(args, status, tmp_path):
    points = _entry_points()
    assert "console script" in points, "the `testbench` console script is not installed (pip install -e .)"
    results = {name: subprocess.run(cmd + args, capture_output=True, text=True, cwd=tmp_path, timeout=120)
               for name, cmd in points.items()}
    for name, proc in results.items():
        assert proc.returncode == status, f"{name}: exit {proc.returncode}, stderr {proc.stderr!r}"
        assert "Traceback" not in proc.stderr, name
    outputs = {(proc.stdout, proc.stderr) for proc in results.values()}
    assert len(outputs) == 1, results
    if status == 0:
        assert next(iter(results.values())).stdout.startswith("testbench ")
    else:
        assert "scenario file not found" in next(iter(results.values())).stderr
