"""ISMN latency benchmark on synthetic 1920 x 1080 frames at 800 m (paper camera: 120 deg).

Single core (cv2.setNumThreads(1)); the map is another season of a procedural world at 1.5 m
per pixel; poses vary (heading, small roll/pitch, 10-20 m position error). Reports the
orthorectification-to-fix latency (ortho + match + pose) and, separately, the whole call
including the map-window read.
"""

from __future__ import annotations

import cv2
import numpy as np

from testbench.core.camera_geometry import CameraMount, PinholeCamera, mount_rotation
from testbench.core.messages import NavEstimate
from testbench.core.rotations import euler_to_dcm, euler_to_quat
from testbench.navigation.ismn.area import NccMatcher
from testbench.navigation.ismn.pipeline import IsmnPipeline
from testbench.navigation.ismn.synth import RasterMapSource, procedural_seasons, render_plane_frame


def run_benchmarks(n_frames: int = 20, seed: int = 0) -> dict[str, float]:
    """{"ismn.latency_ms_p95", "ismn.latency_ms_mean", "ismn.total_ms_p95",
    "ismn.bench_error_m_mean", "ismn.bench_fix_rate"} over n_frames synthetic frames."""
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        rng = np.random.default_rng(seed)
        summer, winter = procedural_seasons(rng, 3200, 1.5, n_fields=600)
        cam = PinholeCamera.from_hfov(1920, 1080, 120.0)
        mount = CameraMount(mount_rotation(0.0, -90.0, 0.0), np.zeros(3))
        pipe = IsmnPipeline(cam, mount, RasterMapSource(winter), None, NccMatcher())
        lat, tot, errs, fixes = [], [], [], 0
        for k in range(n_frames + 2):
            truth = np.r_[rng.uniform(-150, 150, 2), -800.0]
            rpy = np.r_[rng.uniform(-3, 3, 2), rng.uniform(-180, 180)]
            frame = render_plane_frame(summer, cam, truth, euler_to_dcm(np.radians(rpy)), mount)
            est_rpy = np.radians(rpy + rng.normal(0, 0.05, 3))
            est = NavEstimate(0.0, truth + np.r_[rng.normal(0, 10, 2), 0.0], np.zeros(3), euler_to_quat(est_rpy),
                              est_rpy, np.zeros(3), np.eye(3) * 15.0**2, np.eye(3), np.eye(3) * np.radians(0.1) ** 2)
            fix, diag = pipe.process(frame, float(k), est)
            if k < 2:  # warm-up (caches, first allocations)
                continue
            ms = diag.latency_ms
            lat.append(ms.get("ortho", 0) + ms.get("match", 0) + ms.get("pose", 0))
            tot.append(ms["total"])
            if fix is not None:
                fixes += 1
                errs.append(float(np.hypot(*(fix.pos_ned_m[:2] - truth[:2]))))
        return {
            "ismn.latency_ms_p95": float(np.percentile(lat, 95)),
            "ismn.latency_ms_mean": float(np.mean(lat)),
            "ismn.total_ms_p95": float(np.percentile(tot, 95)),
            "ismn.bench_error_m_mean": float(np.mean(errs)) if errs else float("nan"),
            "ismn.bench_fix_rate": fixes / n_frames,
        }
    finally:
        cv2.setNumThreads(threads)
