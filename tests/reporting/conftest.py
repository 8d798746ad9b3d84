"""A synthetic run directory (two vehicles, every event table, images, map) shared by report tests."""

from __future__ import annotations

import numpy as np
import pytest

from testbench.scoring.synthetic import make_synthetic_run

THRESHOLDS = {
    "nav.horizontal_error_m.rms": {"max": 1000.0},
    "ismn.smooth.horizontal_error_m.mean": {"max": 0.001},   # fails on purpose
    "relnav.error_m.max": {"max": 50.0},
    "not.a.metric": {"min": 0.0},                            # missing: fails naming the key
}


@pytest.fixture(scope="session")
def synthetic_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("report_run")
    return make_synthetic_run(d, np.random.default_rng(5), n_vehicles=2, duration_s=60.0, rate_hz=5.0, thresholds=THRESHOLDS)


@pytest.fixture(scope="session")
def html_report(synthetic_run):
    from testbench.reporting import write_html_report

    return write_html_report(synthetic_run, synthetic_run / "report.html")
