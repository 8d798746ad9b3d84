"""The world's crustal magnetic anomaly: a potential field of the stated strength and
wavelengths, seeded as the scenario says, and what the magnetometer senses over the WMM."""

import numpy as np
import pytest

from testbench.config.schema import MagneticAnomaly, World
from testbench.core.errors import SimulationAborted
from testbench.core.interfaces import BuildContext
from testbench.core.rng import RngStreams
from testbench.core.rotations import quat_to_dcm
from testbench.sensors.fakes import ORIGIN, FakeWorld, make_truth
from testbench.sensors.magnetometer import Magnetometer, MagnetometerParams
from testbench.sim.world_runtime import RunWorld, TickWorldView
from testbench.world.magnetic import CrustalAnomaly


def _field_up(anomaly: CrustalAnomaly, p_neu_m: np.ndarray) -> np.ndarray:
    """The anomaly at (north, east, up) as (north, east, up) nT: a right-handed frame for
    the derivatives below."""
    b = anomaly.field_ned_nT(*p_neu_m)
    return np.array([b[0], b[1], -b[2]])


@pytest.mark.parametrize("point_neu_m", [(123.0, -456.0, 200.0), (-3_000.0, 2_500.0, 0.0), (40.0, 40.0, -300.0)])
def test_the_anomaly_is_curl_free_and_divergence_free(point_neu_m):
    """B = -grad V with V harmonic above its sources: the Jacobian is symmetric and traceless."""
    anomaly = CrustalAnomaly(200.0, 1_000.0, np.random.default_rng(3))
    p = np.asarray(point_neu_m)
    h = 0.5
    J = np.column_stack([(_field_up(anomaly, p + dp) - _field_up(anomaly, p - dp)) / (2 * h) for dp in h * np.eye(3)])
    scale = np.abs(J).max()
    assert scale > 1e-3  # nT/m: a field that varies, so the checks below can fail
    assert abs(np.trace(J)) < 1e-5 * scale
    np.testing.assert_allclose(J, J.T, atol=1e-5 * scale)


def test_rms_at_the_datum_and_its_upward_decay():
    """Over a wide area the RMS is the stated one at the datum and rms / (1 + z / d) above."""
    anomaly = CrustalAnomaly(100.0, 800.0, np.random.default_rng(11))
    rng = np.random.default_rng(5)
    n, e = rng.uniform(-3e5, 3e5, (2, 20_000))
    for z_m in (0.0, 400.0, 1_600.0):
        b = anomaly.field_ned_nT(n, e, z_m)
        expected = anomaly.rms_at_height_nT(z_m)
        assert np.sqrt(np.mean(b[:, 2] ** 2)) == pytest.approx(expected, rel=0.12)
        assert np.sqrt(np.mean(b[:, 0] ** 2 + b[:, 1] ** 2)) == pytest.approx(expected, rel=0.12)
    assert anomaly.rms_at_height_nT(1_600.0) == pytest.approx(100.0 / 3.0)


def test_correlation_length_follows_the_source_depth():
    """Deeper sources, longer wavelengths: the field changes less over 500 m."""
    rng = np.random.default_rng(2)
    n, e = rng.uniform(-1e5, 1e5, (2, 5_000))
    change = []
    for depth_m in (300.0, 3_000.0):
        a = CrustalAnomaly(100.0, depth_m, np.random.default_rng(4))
        change.append(np.sqrt(np.mean((a.field_ned_nT(n + 500.0, e, 0.0) - a.field_ned_nT(n, e, 0.0)) ** 2)))
    assert change[1] < 0.5 * change[0]


def test_below_half_the_source_depth_the_run_stops_with_a_clear_reason():
    anomaly = CrustalAnomaly(100.0, 1_000.0, np.random.default_rng(0))
    anomaly.field_ned_nT(0.0, 0.0, -400.0)
    with pytest.raises(SimulationAborted, match=r"source_depth_m"):
        anomaly.field_ned_nT(0.0, 0.0, -600.0)


def _world(seed=None) -> World:
    return World(origin={"lat_deg": 45.0, "lon_deg": 7.0, "alt_m": 300.0},
                 magnetic_anomaly=MagneticAnomaly(rms_nT=100.0, source_depth_m=1_000.0, seed=seed))


def test_a_seeded_field_is_the_worlds_and_an_unseeded_one_the_runs():
    truth = make_truth(0.0, pos_ned_m=(250.0, -80.0, -120.0))

    def sensed(world_spec, run_seed):
        run = RunWorld(world_spec, ORIGIN, streams=RngStreams(run_seed))
        return TickWorldView(run, 0.0, "uav0", {}).magnetic_anomaly_ned_T(truth)

    fixed = _world(seed=7)
    np.testing.assert_array_equal(sensed(fixed, 1), sensed(fixed, 2))
    drawn = _world()
    np.testing.assert_array_equal(sensed(drawn, 1), sensed(drawn, 1))
    assert not np.array_equal(sensed(drawn, 1), sensed(drawn, 2))
    assert np.linalg.norm(sensed(drawn, 1)) > 1e-9  # tesla: tens of nT, not zero
    calm = World(origin={"lat_deg": 45.0, "lon_deg": 7.0, "alt_m": 300.0})
    assert TickWorldView(RunWorld(calm, ORIGIN), 0.0, "uav0", {}).magnetic_anomaly_ned_T(truth) is None


def test_the_magnetometer_senses_the_wmm_plus_the_anomaly():
    ctx = BuildContext("uav0", ("uav0",), ORIGIN, epoch_utc_year=2026.0)
    truth = make_truth(0.02, pos_ned_m=(30.0, 40.0, -100.0), rpy_rad=(0.1, -0.05, 1.2))
    anomaly_ned_T = np.array([80e-9, -60e-9, 150e-9])
    plain = Magnetometer(MagnetometerParams(noise_nT=0.0), ctx=ctx).measure(truth, FakeWorld(), np.random.default_rng(0))
    crust = Magnetometer(MagnetometerParams(noise_nT=0.0), ctx=ctx).measure(
        truth, FakeWorld(magnetic_anomaly=lambda tr: anomaly_ned_T), np.random.default_rng(0))
    R_nb = quat_to_dcm(truth.q_nb_wxyz)
    np.testing.assert_allclose(crust.field_b_T - plain.field_b_T, R_nb.T @ anomaly_ned_T, atol=1e-15)
