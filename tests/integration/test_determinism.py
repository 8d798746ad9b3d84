"""Same scenario and seed -> byte-identical telemetry; another seed differs where noise acts.

Also: the ISMN feature image does not depend on where the heap puts its buffers."""

import hashlib
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np

from testbench.navigation.ismn.features import robust_image

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


def test_ismn_features_do_not_depend_on_where_buffers_land():
    """The matcher's feature image of one image is bit-identical whatever the heap layout.

    Some OpenCV routines (cv2.magnitude through the IPP HAL) split the work between a vector loop
    and head/tail code that round differently, by the output buffer's address mod 32 bytes;
    numpy puts that buffer wherever the heap has room, which differs between runs, and the ISMN
    fixes of two runs of one seed differed in the last bits. A run-pair of the ISMN scenario
    catches that only now and then (about half the pairs of 8 s); here the heap is shifted
    between calls (blocks of random multiples of 16 bytes held and released, malloc's
    granularity), so the output buffers land on both sides of a 32-byte boundary: with the old
    code the 100 calls gave two results, split about evenly, for every seed tried.
    """
    rng = np.random.default_rng(0)
    img = cv2.GaussianBlur(rng.integers(0, 256, (120, 160), dtype=np.uint8), (0, 0), 1.5)
    valid = np.ones(img.shape, bool)
    valid[:, :9] = False  # the no-data branch (fill and erosion) too
    results = set()
    held = []
    for _ in range(100):
        held.append([np.empty(int(rng.integers(1, 4096)) * 16, np.uint8) for _ in range(int(rng.integers(1, 8)))])
        if len(held) > 12:
            held.pop(int(rng.integers(0, len(held))))
        f, v = robust_image(img, valid, "gradmag")
        results.add(f.tobytes() + v.tobytes())
    assert len(results) == 1
