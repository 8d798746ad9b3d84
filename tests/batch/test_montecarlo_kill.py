"""A batch killed for real (SIGKILL to the whole process group, mid-batch) leaves a folder that
`testbench montecarlo` resumes: the finished runs are kept and not flown again, the rest are."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SCENARIO = str(REPO / "scenarios" / "fixedwing_racetrack.yaml")


def _cmd(out: Path) -> list[str]:
    return [sys.executable, "-m", "testbench.cli", "montecarlo", SCENARIO, "--runs", "6", "--workers", "2",
            "--out", str(out), "--set", "duration_s=20"]


def _finished(out: Path) -> dict[str, float]:
    """run folder -> mtime of its result.json (a run is finished when that file exists)."""
    return {p.parent.name: p.stat().st_mtime_ns for p in (out / "runs").glob("run_*/result.json")}


def test_killed_batch_resumes_without_losing_finished_runs(tmp_path):
    out = tmp_path / "mc"
    proc = subprocess.Popen(_cmd(out), cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    try:
        deadline = time.monotonic() + 240
        while len(_finished(out)) < 2 and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.2)
        assert proc.poll() is None, "the batch ended before it could be killed (runs too short?)"
        os.killpg(proc.pid, signal.SIGKILL)  # the CLI and its pool workers, mid-batch
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    before = _finished(out)
    assert 2 <= len(before) < 6, before
    for name in before:  # what finished is complete and readable
        assert json.loads((out / "runs" / name / "result.json").read_text())["status"] == "passed"

    res = subprocess.run(_cmd(out), cwd=REPO, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    after = _finished(out)
    assert len(after) == 6
    assert all(after[name] == mtime for name, mtime in before.items())  # kept, not flown again
    assert f"({len(before)} resumed)" in res.stdout + res.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["runs_done"] == 6 and summary["status_counts"] == {"passed": 6}
