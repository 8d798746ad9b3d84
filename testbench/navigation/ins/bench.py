"""Benchmarks of the INS/EKF (wired into `testbench bench` by the lead).

nav.ekf_predict_us: mean wall time of one `InsEkfNavigator.predict` at 100 Hz, including
    the share of the covariance propagation (every cov_interval_s = 0.05 s, i.e. every 5th
    sample; see ekf.py for that choice);
nav.ekf_predict_cov_every_step_us: the same with the covariance propagated at every sample;
nav.ekf_update_us: one 3-D position-fix update (gate, Joseph form, injection, reset);
nav.ins_step_us: the bare mechanisation step (StrapdownINS.step_increments).
"""

from __future__ import annotations

import math
import time

import numpy as np

from testbench.core.interfaces import BuildContext, GeodeticOrigin
from testbench.core.messages import ImuSample, NavEstimate, PositionFix
from testbench.core.registry import build


def _navigator(cov_interval_s: float):
    origin = GeodeticOrigin(math.radians(47.0), math.radians(-97.0), 300.0)
    ctx = BuildContext("bench", ("bench",), origin)
    nav = build("navigator", "ins_ekf", {"cov_interval_s": cov_interval_s}, "bench", ctx=ctx)
    nan = np.full((3, 3), np.nan)
    nav.initialize(0.0, NavEstimate(0.0, np.array([0.0, 0.0, -500.0]), np.array([30.0, 0.0, 0.0]),
                                    np.array([1.0, 0, 0, 0]), np.zeros(3), np.zeros(3), nan, nan, nan))
    return nav


def _time_predict(cov_interval_s: float, n: int) -> float:
    nav = _navigator(cov_interval_s)
    w = np.array([0.0, 0.0, 0.05])
    f = np.array([0.0, 1.5, -9.81])
    samples = [ImuSample((k + 1) * 0.01, w, f) for k in range(n)]
    t0 = time.perf_counter()
    for s in samples:
        nav.predict(s)
    return (time.perf_counter() - t0) / n * 1e6


def run_benchmarks(n: int = 20000) -> dict[str, float]:
    """Timings in microseconds (best of 3 for the predictions)."""
    out = {
        "nav.ekf_predict_us": min(_time_predict(0.05, n) for _ in range(3)),
        "nav.ekf_predict_cov_every_step_us": min(_time_predict(0.0, n // 4) for _ in range(3)),
    }
    nav = _navigator(0.05)
    fixes = [PositionFix(0.0, np.array([1.0, -1.0, -500.0]), np.eye(3) * 25.0, 0.9) for _ in range(2000)]
    t0 = time.perf_counter()
    for fx in fixes:
        nav.correct(fx)
    out["nav.ekf_update_us"] = (time.perf_counter() - t0) / len(fixes) * 1e6
    ins = nav.ekf.ins
    t0 = time.perf_counter()
    for _ in range(n):
        ins.step_increments((0.0, 0.0, 5e-4), (0.0, 0.015, -0.0981), 0.01)
    out["nav.ins_step_us"] = (time.perf_counter() - t0) / n * 1e6
    return out
