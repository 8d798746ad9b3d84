"""The three ways to start the command line (the `testbench` console script, `python cli.py`,
`python -m testbench`) are one entry point: the same output and the same exit status."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def _entry_points() -> dict[str, list[str]]:
    """name -> command line of each entry point, the console script beside this interpreter's."""
    script = Path(sys.executable).with_name("testbench")
    script = str(script) if script.exists() else shutil.which("testbench")
    assert script, "the `testbench` console script is not installed (pip install -e .)"
    return {"console script": [script], "cli.py": [sys.executable, str(REPO / "cli.py")],
            "python -m": [sys.executable, "-m", "testbench"]}


@pytest.mark.parametrize("args, status", [(["--version"], 0), (["run", "no/such/scenario.yaml"], 2)])
def test_every_entry_point_gives_the_same_output_and_status(args, status, tmp_path):
    points = _entry_points()
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
