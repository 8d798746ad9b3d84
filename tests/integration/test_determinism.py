"""Same scenario and seed -> byte-identical telemetry; another seed differs where noise acts."""

import hashlib
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_same_seed_gives_identical_telemetry(tmp_path):
    outs = []
    for name in ("a", "b"):
        out = tmp_path / name
        proc = subprocess.run(
            [sys.executable, str(REPO / "cli.py"), "run", str(REPO / "scenarios" / "fixedwing_racetrack.yaml"),
             "--set", "duration_s=20", "--out", str(out), "--no-report", "--quiet"],
            capture_output=True, text=True, timeout=300,
        )
        assert proc.returncode == 0, proc.stderr
        outs.append(out)
    assert _digest(outs[0] / "telemetry.parquet") == _digest(outs[1] / "telemetry.parquet")
    assert (outs[0] / "trajectories" / "uav0_truth.tum").read_bytes() == (outs[1] / "trajectories" / "uav0_truth.tum").read_bytes()
