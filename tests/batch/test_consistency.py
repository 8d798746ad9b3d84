"""Average NEES over a batch: a filter whose errors follow its covariance sits inside the 95 %
bounds about 95 % of the time; one that claims a third of its real sigma sits above them."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from testbench.batch.consistency import nees_consistency


def _write_run(folder: Path, rng: np.random.Generator, sigma_m: np.ndarray, error_scale: float, n: int = 400,
               tau_s: float = 0.0, t: np.ndarray | None = None) -> Path:
    """A run whose position error is error_scale times its claimed sigma, white or a first-order
    Gauss-Markov process of correlation time tau_s (stationary from the start)."""
    folder.mkdir(parents=True)
    t = np.arange(n) * 0.1 if t is None else t
    w = rng.standard_normal((n, 3))
    if tau_s > 0:
        a = np.exp(-0.1 / tau_s)
        for i in range(1, n):
            w[i] = a * w[i - 1] + np.sqrt(1 - a * a) * w[i]
    err = w * sigma_m * error_scale
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


def _batch(tmp_path: Path, scale: float, tau_s: float, runs: int = 20, seed: int = 3):
    rng = np.random.default_rng(seed)
    sigma = np.array([2.0, 3.0, 1.5])
    return nees_consistency([_write_run(tmp_path / f"run_{k:05d}", rng, sigma, scale, n=600, tau_s=tau_s)
                             for k in range(runs)])


def test_chance_figures_of_a_consistent_batch(tmp_path):
    """Errors correlated over 5 s that follow the claimed covariance: a consistent filter's
    fraction averages 95 % by construction, and this batch's is no worse than chance."""
    res = _batch(tmp_path, 1.0, 5.0)
    assert res.chance_share_mean == pytest.approx(0.95, abs=0.015)
    assert res.chance_share_p05 < 0.94
    assert res.chance_p_value > 0.05


def test_chance_widens_with_correlation_time(tmp_path):
    """Longer-correlated errors give fewer independent looks at the bounds, so a consistent
    filter's fraction spreads wider: a lower 5th percentile than white errors."""
    white = _batch(tmp_path / "white", 1.0, 0.0)
    slow = _batch(tmp_path / "slow", 1.0, 8.0)
    assert white.chance_share_p05 > slow.chance_share_p05 + 0.03


def test_chance_flags_an_overconfident_batch(tmp_path):
    res = _batch(tmp_path, 1.4, 5.0)
    assert res.fraction_within < res.chance_share_p05
    assert res.chance_p_value < 0.01


def test_chance_needs_even_record_times(tmp_path):
    rng = np.random.default_rng(2)
    t = np.cumsum(rng.uniform(0.05, 0.15, 300))
    dirs = [_write_run(tmp_path / f"run_{k:05d}", rng, np.ones(3), 1.0, n=300, t=t) for k in range(5)]
    res = nees_consistency(dirs)
    assert res.samples == 300 and np.isnan(res.chance_p_value) and np.isnan(res.chance_share_p05)


def test_batch_report_states_the_chance_figures(tmp_path):
    from testbench.batch.report import _nees_html

    res = _batch(tmp_path, 1.4, 5.0)
    html = _nees_html(res.as_dict())
    assert f"{100 * res.fraction_within:.1f} %" in html
    assert f"above {100 * res.chance_share_p05:.1f} % in 95 % of batches" in html
    assert f"inside at most this batch's share in {100 * res.chance_p_value:.1f} % of them" in html
    # Without the chance figures (uneven record times) the sentence is left out.
    assert "consistent filter whose errors" not in _nees_html({**res.as_dict(), "chance_p_value": float("nan")})


def test_series_gives_the_average_nees_and_its_axes(tmp_path):
    res = _batch(tmp_path, 1.0, 0.0, runs=5)
    s = res.series
    assert list(s.columns) == ["vehicle_id", "t_s", "average_nees", "average_z2_north", "average_z2_east", "average_z2_down"]
    assert len(s) == res.samples and (s["vehicle_id"] == "uav0").all()
    assert np.allclose(s["average_nees"], s[["average_z2_north", "average_z2_east", "average_z2_down"]].sum(axis=1))
    assert res.mean_of_average == pytest.approx(s["average_nees"].mean())
    assert "series" not in res.as_dict()


def test_ekf_batch_writes_the_nees_series_and_plots_it(tmp_path):
    """A real batch of an EKF scenario: nees_position.parquet beside summary.json, and the
    report's consistency section carries the NEES-against-time figure."""
    import json

    from testbench.batch import BatchPlan, run_batch

    scenario = str(Path(__file__).resolve().parents[2] / "scenarios" / "ins_only_800m.yaml")
    out = tmp_path / "mc"
    run_batch(BatchPlan(scenario, 2, 1, ("duration_s=4",), ()), out, workers=1, report=True)
    series = pd.read_parquet(out / "nees_position.parquet")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["nees_position"]["samples"] == len(series) > 30
    assert "average position NEES over 2 runs against time" in (out / "report.html").read_text()
