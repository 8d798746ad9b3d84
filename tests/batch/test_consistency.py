"""Average NEES over a batch: a filter whose errors follow its covariance sits inside the 95 %
bounds about 95 % of the time; one that claims a third of its real sigma sits above them."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from testbench.batch.consistency import nees_consistency


def _write_run(folder: Path, rng: np.random.Generator, sigma_m: np.ndarray, error_scale: float, n: int = 400) -> Path:
    folder.mkdir(parents=True)
    t = np.arange(n) * 0.1
    err = rng.standard_normal((n, 3)) * sigma_m * error_scale
    truth = np.zeros((n, 3))
    tel = pd.DataFrame({
        "vehicle_id": "uav0", "t_s": t,
        "truth_north_m": truth[:, 0], "truth_east_m": truth[:, 1], "truth_down_m": truth[:, 2],
        "nav_north_m": err[:, 0], "nav_east_m": err[:, 1], "nav_down_m": err[:, 2],
        "nav_sigma_north_m": sigma_m[0], "nav_sigma_east_m": sigma_m[1], "nav_sigma_down_m": sigma_m[2],
        "nav_cov_ne_m2": 0.0,
    })
    tel.to_parquet(folder / "telemetry.parquet")
    return folder


@pytest.mark.parametrize("scale, within_min, above_min", [(1.0, 0.9, 0.0), (3.0, 0.0, 0.99)])
def test_average_nees_flags_an_overconfident_filter(tmp_path, scale, within_min, above_min):
    rng = np.random.default_rng(5)
    sigma = np.array([2.0, 3.0, 1.5])
    dirs = [_write_run(tmp_path / f"run_{k:05d}", rng, sigma, scale) for k in range(20)]
    res = nees_consistency(dirs)
    assert res.runs == 20 and res.samples == 400
    assert res.fraction_within >= within_min and res.fraction_above >= above_min
    if scale == 1.0:
        assert res.fraction_within <= 0.99 and res.mean_of_average == pytest.approx(3.0, abs=0.15)


def test_needs_two_runs(tmp_path):
    d = _write_run(tmp_path / "run_00000", np.random.default_rng(1), np.ones(3), 1.0)
    assert nees_consistency([d]) is None
