import numpy as np
import pytest
from scipy import stats as sps

from testbench.scoring.stats import chi2_bounds, chi_square_stats, error_stats


def test_error_stats_known_values():
    s = error_stats([3.0, -4.0, np.nan, 0.0, np.inf])
    assert s.n == 3
    assert s.mean == pytest.approx(7.0 / 3.0)
    assert s.rms == pytest.approx(np.sqrt(25.0 / 3.0))
    assert s.max == 4.0
    assert s.p95 == pytest.approx(np.percentile([0, 3, 4], 95))
    assert s.cep50 is None and "cep50" not in s.to_dict()


def test_error_stats_empty_is_none():
    assert error_stats([]) is None
    assert error_stats([np.nan, np.nan]) is None


def test_cep_of_rayleigh_matches_theory(rng):
    # Horizontal error of an isotropic Gaussian: Rayleigh; CEP50 = sigma sqrt(2 ln 2).
    sigma = 2.0
    e = np.hypot(*(sigma * rng.standard_normal((2, 200_000))))
    s = error_stats(e, cep=True)
    assert s.cep50 == pytest.approx(sigma * np.sqrt(2 * np.log(2)), rel=0.01)
    assert s.cep95 == pytest.approx(sigma * np.sqrt(-2 * np.log(0.05)), rel=0.01)
    assert s.rms == pytest.approx(sigma * np.sqrt(2), rel=0.01)


@pytest.mark.parametrize("dof", [1, 2, 3, 6])
def test_chi_square_stats_consistent_samples(rng, dof):
    x = rng.chisquare(dof, 100_000)
    s = chi_square_stats(x, dof)
    assert s.mean == pytest.approx(dof, rel=0.02)
    assert s.mean_per_dof == pytest.approx(1.0, rel=0.02)
    assert s.frac_in_95 == pytest.approx(0.95, abs=0.005)
    assert s.frac_above_95 == pytest.approx(0.025, abs=0.003)


def test_chi_square_stats_mixed_dims_and_overconfidence(rng):
    d = rng.integers(1, 4, 50_000)
    x = rng.chisquare(d)
    assert chi_square_stats(x, d).frac_in_95 == pytest.approx(0.95, abs=0.01)
    # A filter whose covariance is 4x too small: NEES x4, most samples above the bound.
    over = chi_square_stats(4.0 * x, d)
    assert over.mean_per_dof == pytest.approx(4.0, rel=0.03)
    assert over.frac_above_95 > 0.3


def test_chi2_bounds():
    lo, hi = chi2_bounds(3)
    assert sps.chi2.cdf(hi, 3) - sps.chi2.cdf(lo, 3) == pytest.approx(0.95)
