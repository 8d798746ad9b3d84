"""Latency benchmarks of the CNN detector (`testbench bench --only cnn`)."""

from __future__ import annotations

import time

import numpy as np


def _median_ms(fn, repeats: int) -> float:
    fn()  # warm-up (allocations, oneDNN primitive creation)
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(ts))


def run_benchmarks() -> dict[str, float]:
    """Median wall milliseconds of CnnDetector.detect (packaged weights, CPU, torch's threads)
    on one 256 x 256 region, on four 256 x 256 regions of a full frame, and on a whole
    1920 x 1080 frame (tiled); rendered content (a farmland view with a quad at 100 m)."""
    from testbench.navigation.relative.cnn import dataset
    from testbench.navigation.relative.cnn.detector import CnnDetector

    det = CnnDetector()
    s = dataset.make_samples(1, 7, dataset.DataSettings(crop_px=256, p_negative=0.0), range_m=(95.0, 105.0))[0]
    roi_img = s.image
    frame = np.tile(roi_img, (5, 8, 1))[:1080, :1920]
    rois = [(0, 0, 256, 256), (600, 300, 856, 556), (1200, 500, 1456, 756), (1600, 800, 1856, 1056)]
    return {
        "cnn.detect_roi256_ms": _median_ms(lambda: det.detect(roi_img), 10),
        "cnn.detect_4rois_in_frame_ms": _median_ms(lambda: det.detect(frame, rois=rois), 5),
        "cnn.detect_full_frame_ms": _median_ms(lambda: det.detect(frame), 2),
    }
