"""The filter's IMU noise refitted to the sensor's flicker bias (imu_noise.fit_to_flicker)."""

import math

import numpy as np
import pytest

from testbench.navigation.ins.imu_noise import (
    fit_to_flicker,
    flicker_drift_sigma,
    imu_noise_from_datasheet,
    preset_datasheet,
)
from testbench.sensors.noise import FLICKER_CORR_TIMES_S, TriadNoise

_DEG_H = math.pi / 180.0 / 3600.0


def _paper_noise():
    sheet = preset_datasheet("paper")
    sheet.pop("gyro_turn_on_bias_deg_h")
    sheet.pop("accel_turn_on_bias_ug")
    return imu_noise_from_datasheet(**sheet)


def test_drift_formula_matches_the_simulated_sensor():
    """flicker_drift_sigma against the sensor model itself: 400 gyro triads of the paper IMU,
    each run 100 s from a stationary start; the drift is the integral of the error less what
    the bank's known starting state predicts (its decay)."""
    n = _paper_noise()
    dt_s, steps, runs = 0.1, 1000, 400
    rng = np.random.default_rng(7)
    a = np.exp(-dt_s / FLICKER_CORR_TIMES_S)  # (K,)
    # Sample n (0-based) carries the bank's state after n + 1 steps: a^(n+1) x0 in the mean.
    decay = a[None, :] ** np.arange(1, steps + 1)[:, None]  # (steps, K)
    horizons = np.array([100, 400, 1000])  # samples: 10, 40, 100 s
    drift = np.empty((runs, 3, len(horizons)))
    for r in range(runs):
        tn = TriadNoise(n.gyro_arw_rad_sqrt_s, n.gyro_bias_sigma_rps, 0.0, dt_s)
        tn._init_state(rng)
        x0 = tn._gm.copy()  # (K, 3)
        err = tn.sample_block(steps, rng) - decay @ x0  # (steps, 3)
        drift[r] = (np.cumsum(err, axis=0)[horizons - 1] * dt_s).T
    measured = drift.reshape(-1, len(horizons)).std(axis=0)
    expected = flicker_drift_sigma(n.gyro_arw_rad_sqrt_s, n.gyro_bias_sigma_rps, 0.0, horizons * dt_s)
    # 1200 axes: the sample SD is good to about 2 % (1 sigma).
    np.testing.assert_allclose(measured, expected, rtol=0.08)


@pytest.mark.parametrize("band_s", [(5.0, 100.0), (10.0, 200.0)])
def test_fit_follows_the_flicker_drift_over_the_band(band_s):
    """Fitted, the filter's own drift (white N'^2 T + random walk q' T^3 / 3) lies within 20 %
    of the sensor's across the band, gyro and accelerometer; the datasheet's model as it is
    claims half of it or less somewhere in the band, so the fit is what closes the gap."""
    n = _paper_noise()
    f = fit_to_flicker(n, band_s)
    t = np.geomspace(*band_s, 50)

    def filter_sigma(white, sigma, tau_s, rrw):
        return np.sqrt(white**2 * t + (2.0 * sigma**2 / tau_s + rrw**2) * t**3 / 3.0)

    for sensor, fitted, raw in [
        (flicker_drift_sigma(n.gyro_arw_rad_sqrt_s, n.gyro_bias_sigma_rps, 0.0, t),
         filter_sigma(f.gyro_arw_rad_sqrt_s, f.gyro_bias_sigma_rps, f.gyro_bias_tau_s, f.gyro_rrw_rps_sqrt_s),
         filter_sigma(n.gyro_arw_rad_sqrt_s, n.gyro_bias_sigma_rps, n.gyro_bias_tau_s, n.gyro_rrw_rps_sqrt_s)),
        (flicker_drift_sigma(n.accel_vrw_mps_sqrt_s, n.accel_bias_sigma_mps2, 0.0, t),
         filter_sigma(f.accel_vrw_mps_sqrt_s, f.accel_bias_sigma_mps2, f.accel_bias_tau_s, f.accel_rrw_mps2_sqrt_s),
         filter_sigma(n.accel_vrw_mps_sqrt_s, n.accel_bias_sigma_mps2, n.accel_bias_tau_s, n.accel_rrw_mps2_sqrt_s)),
    ]:
        ratio = fitted / sensor
        assert 0.8 <= ratio.min() and ratio.max() <= 1.25, (ratio.min(), ratio.max())
        assert (raw / sensor).min() < 0.7
    # The Gauss-Markov's sigma and tau are kept (initial bias uncertainty, gauss_markov mode).
    assert (f.gyro_bias_sigma_rps, f.gyro_bias_tau_s) == (n.gyro_bias_sigma_rps, n.gyro_bias_tau_s)
    assert f.gyro_arw_rad_sqrt_s > n.gyro_arw_rad_sqrt_s and f.gyro_rrw_rps_sqrt_s > 0.0


def test_fit_rejects_a_band_out_of_order():
    with pytest.raises(ValueError, match="0 < t1 < t2"):
        fit_to_flicker(_paper_noise(), (100.0, 5.0))


def test_navigator_carries_the_fitted_noise():
    from testbench.core.interfaces import BuildContext, GeodeticOrigin
    from testbench.navigation.ins.navigator import InsEkfNavigator
    from testbench.navigation.ins.settings import InsEkfParams

    ctx = BuildContext("uav0", ("uav0",), GeodeticOrigin(46.0, 7.0, 500.0))
    plain = InsEkfNavigator(InsEkfParams(), ctx=ctx)
    fitted = InsEkfNavigator(InsEkfParams(imu={"flicker_fit_band_s": [5.0, 100.0]}), ctx=ctx)
    assert fitted.noise == fit_to_flicker(plain.noise, (5.0, 100.0))
    assert fitted.noise.gyro_arw_rad_sqrt_s > 1.5 * plain.noise.gyro_arw_rad_sqrt_s
    assert plain.noise.gyro_bias_sigma_rps == pytest.approx(7.0 * _DEG_H)
