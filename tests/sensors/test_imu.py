"""IMU model: Allan statistics vs configured noise, static readings, edges, determinism."""

import numpy as np
import pytest

from testbench.core.errors import InputError
from testbench.core.geodesy import earth_rate_ned_rps, normal_gravity_mps2
from testbench.core.interfaces import BuildContext
from testbench.core.registry import build
from testbench.sensors.allan import analyse_record
from testbench.sensors.fakes import ORIGIN, FakeWorld, make_truth
from testbench.core.rotations import euler_to_quat, quat_multiply, quat_to_dcm, rotvec_to_quat
from testbench.core.geodesy import transport_rate_ned_rps
from testbench.sensors.imu import Imu, ImuErrorModel, mean_rate_ib_b
from testbench.sensors.imu_params import ImuParams
from testbench.sensors.imu_static import COLUMNS, static_record
from testbench.sensors.noise import TriadNoise

CTX = BuildContext("uav0", ("uav0",), ORIGIN)
QUIET = dict(gyro_turn_on_bias_deg_h=0.0, gyro_scale_factor_ppm=0.0, gyro_misalignment_mrad=0.0,
             accel_turn_on_bias_mg=0.0, accel_scale_factor_ppm=0.0, accel_misalignment_mrad=0.0)


@pytest.fixture(scope="module")
def paper_fits():
    spec = ImuParams(preset="paper").spec()
    rec = static_record(spec, 1200.0, 100.0, np.random.default_rng(2024))
    return spec, analyse_record(rec)


def test_allan_white_noise_matches_configured_arw_vrw(paper_fits):
    # 20 min at 100 Hz: the -1/2 line is read to ~1 %; a wrong deg/sqrt(h) conversion is >= x1.4.
    spec, fits = paper_fits
    for name, fit in fits.items():
        ref = spec.gyro if name.startswith("gyro") else spec.accel
        assert fit.white_density == pytest.approx(ref.white_density, rel=0.05), name


def test_allan_floor_matches_configured_bias_instability(paper_fits):
    # Per-axis scatter of the floor from 20 min is ~10 %; averaged over 3 axes within 15 %.
    # A bank scaled for a two-sided PSD (floor x 0.707) fails this.
    spec, fits = paper_fits
    for triad, ref in (("gyro", spec.gyro), ("accel", spec.accel)):
        ratios = [f.bias_instability / ref.bias_instability for n, f in fits.items() if n.startswith(triad)]
        assert np.mean(ratios) == pytest.approx(1.0, abs=0.15), (triad, ratios)
        assert all(0.65 < r < 1.35 for r in ratios), (triad, ratios)


def test_allan_sees_rate_random_walk():
    p = ImuParams(preset="tactical", gyro_rrw_deg_h_rth=100.0, gyro_bias_instability_deg_h=0.1)
    spec = p.spec()
    rec = static_record(spec, 1200.0, 50.0, np.random.default_rng(7))
    fits = analyse_record(rec, ["gyro_x_rad_s", "gyro_y_rad_s", "gyro_z_rad_s"])
    ratios = [f.rate_random_walk / spec.gyro.rate_random_walk for f in fits.values()]
    # 20 min shows the +1/2 slope over ~1.5 decades: per axis +-50 %, the mean within 30 %.
    assert np.mean(ratios) == pytest.approx(1.0, abs=0.3), ratios


def test_static_record_reads_gravity_and_earth_rate():
    p = ImuParams(preset="tactical", gyro_bias_instability_deg_h=0.0, accel_bias_instability_ug=0.0, **QUIET)
    lat = np.deg2rad(30.0)
    rec = static_record(p.spec(), 600.0, 100.0, np.random.default_rng(1), lat_rad=lat)
    assert list(rec) == list(COLUMNS)
    gyro = np.column_stack([rec[c] for c in COLUMNS[1:4]]).mean(axis=0)
    accel = np.column_stack([rec[c] for c in COLUMNS[4:7]]).mean(axis=0)
    # ARW 0.09 deg/sqrt(h) averaged over 600 s: sigma 0.22 deg/h = 1.1e-6 rad/s.
    np.testing.assert_allclose(gyro, earth_rate_ned_rps(lat), atol=5e-6)
    assert abs(gyro[0]) > 5e-5  # the Earth rate is really there (6.3e-5 rad/s north)
    np.testing.assert_allclose(accel, [0, 0, -normal_gravity_mps2(lat, 0.0)], atol=2e-4)


def test_in_loop_imu_at_rest_reads_gravity_and_earth_rate():
    imu = Imu(ImuParams(preset="tactical", gyro_bias_instability_deg_h=0.0, accel_bias_instability_ug=0.0, **QUIET), ctx=CTX)
    rng = np.random.default_rng(3)
    w = FakeWorld()
    out = [imu.measure(make_truth(k / 100.0, rpy_rad=(0.1, -0.2, 1.0)), w, rng) for k in range(1, 3001)]
    truth = make_truth(0.0, rpy_rad=(0.1, -0.2, 1.0))
    np.testing.assert_allclose(np.mean([s.f_ib_b_mps2 for s in out], axis=0), truth.f_b_mps2, atol=5e-4)
    np.testing.assert_allclose(np.mean([s.omega_ib_b_rps for s in out], axis=0), truth.omega_ib_b_rps, atol=2e-5)


def test_block_and_per_sample_draws_coincide():
    spec = ImuParams(preset="consumer_mems").spec()
    w = np.tile([0.1, -0.2, 0.3], (50, 1))
    f = np.tile([0.5, 0.0, -9.8], (50, 1))
    a, b = ImuErrorModel(spec, 0.01), ImuErrorModel(spec, 0.01)
    wa, fa = a.apply(w, f, np.random.default_rng(5))
    rng = np.random.default_rng(5)
    per = [b.apply(w[i : i + 1], f[i : i + 1], rng) for i in range(50)]
    np.testing.assert_allclose(wa, np.vstack([p[0] for p in per]), rtol=0, atol=1e-15)
    np.testing.assert_allclose(fa, np.vstack([p[1] for p in per]), rtol=0, atol=1e-12)


def test_in_loop_samples_drawn_ahead_equal_one_block():
    # apply_one draws the random errors 128 samples ahead; across block boundaries it must
    # give the samples one block draw gives (up to the running sum's rounding).
    spec = ImuParams(preset="consumer_mems").spec()
    rng = np.random.default_rng(11)
    w = rng.normal(0.0, 0.3, (300, 3))
    f = rng.normal(0.0, 3.0, (300, 3)) + [0.0, 0.0, -9.8]
    a, b = ImuErrorModel(spec, 0.01), ImuErrorModel(spec, 0.01)
    wa, fa = a.apply(w, f, np.random.default_rng(5))
    rng_b = np.random.default_rng(5)
    per = [b.apply_one(w[i], f[i], rng_b) for i in range(300)]
    np.testing.assert_allclose(wa, np.vstack([p[0] for p in per]), rtol=0, atol=1e-12)
    np.testing.assert_allclose(fa, np.vstack([p[1] for p in per]), rtol=0, atol=1e-10)
    assert not np.allclose(wa[1:], wa[:-1])  # the noise does move (not a constant row)


def test_flicker_bank_is_stationary():
    n = TriadNoise(0.0, 1.0, 0.0, 0.01)
    x = np.vstack([TriadNoise(0.0, 1.0, 0.0, 0.01).sample_block(1, np.random.default_rng(s)) for s in range(2000)])
    # Stationary variance of the bank: 6 components of B^2 ln10 / pi each.
    assert x.var() == pytest.approx(6 * np.log(10) / np.pi, rel=0.1)
    assert n.n_states == 8


def test_saturation_and_quantisation():
    p = ImuParams(preset="consumer_mems", gyro_arw_deg_rth=0.0, gyro_bias_instability_deg_h=0.0, gyro_rrw_deg_h_rth=0.0)
    spec = p.spec()
    m = ImuErrorModel(spec, 0.01)
    w = np.array([[100.0, -100.0, 0.123456]])  # rad/s, far past 2000 deg/s on x and y
    f = np.array([[1000.0, -1000.0, -9.80665]])
    wm, fm = m.apply(w, f, np.random.default_rng(0))
    assert wm[0, 0] == pytest.approx(spec.gyro.range_q, abs=spec.gyro.lsb)
    assert wm[0, 1] == pytest.approx(-spec.gyro.range_q, abs=spec.gyro.lsb)
    assert fm[0, 0] == pytest.approx(spec.accel.range_q, abs=spec.accel.lsb)
    for v, lsb in ((wm, spec.gyro.lsb), (fm, spec.accel.lsb)):
        k = v / lsb
        np.testing.assert_allclose(k, np.round(k), atol=1e-6)


def test_same_seed_same_samples_and_no_double_walk():
    p = ImuParams(preset="consumer_mems")
    a, b, c = Imu(p, ctx=CTX), Imu(p, ctx=CTX), Imu(p, ctx=CTX)
    ra, rb, rc = (np.random.default_rng(11) for _ in range(3))
    w = FakeWorld()
    for k in range(1, 20):
        t = make_truth(k / 100.0)
        sa = a.measure(t, w, ra)
        sb = b.measure(t, w, rb)
        again = b.measure(t, w, rb)  # asked twice: cached, no second walk
        assert again is sb
        sc = c.measure(t, w, rc)
        np.testing.assert_array_equal(sa.omega_ib_b_rps, sb.omega_ib_b_rps)
        np.testing.assert_array_equal(sb.f_ib_b_mps2, sc.f_ib_b_mps2)
    assert not np.array_equal(
        Imu(p, ctx=CTX).measure(make_truth(0.01), w, np.random.default_rng(12)).omega_ib_b_rps, sa.omega_ib_b_rps
    )


def test_lever_arm_centripetal():
    p = ImuParams(preset="tactical", lever_arm_b_m=(1.0, 0.0, 0.0), accel_vrw_mps_rth=0.0, accel_bias_instability_ug=0.0, **QUIET)
    imu = Imu(p, ctx=CTX)
    rng, w = np.random.default_rng(0), FakeWorld()
    wz = 1.0  # rad/s yaw rate: centripetal -wz^2 r on x (the heading turns with it)
    for k in range(1, 4):
        s = imu.measure(make_truth(k / 100.0, rpy_rad=(0.0, 0.0, wz * k / 100.0), omega_eb_b_rps=(0.0, 0.0, wz)), w, rng)
    truth = make_truth(0.03, rpy_rad=(0.0, 0.0, 0.03 * wz), omega_eb_b_rps=(0.0, 0.0, wz))
    wib = truth.omega_ib_b_rps
    expected = truth.f_b_mps2 + np.cross(wib, np.cross(wib, [1.0, 0, 0]))
    np.testing.assert_allclose(s.f_ib_b_mps2, expected, atol=1e-3)
    assert s.f_ib_b_mps2[0] == pytest.approx(-1.0, abs=0.01)


def test_params_presets_overrides_and_errors():
    spec = ImuParams(preset="paper").spec()
    assert np.rad2deg(spec.gyro.range_q) == pytest.approx(450.0)
    assert spec.gyro.bias_instability == pytest.approx(np.deg2rad(7.0) / 3600.0)
    assert spec.accel.bias_instability == pytest.approx(14e-6 * 9.80665)
    assert ImuParams(preset="tactical", gyro_arw_deg_rth=0.5).datasheet()["gyro_arw_deg_rth"] == 0.5
    with pytest.raises(InputError, match="gyro_arw_deg_rh"):
        build("sensor", "imu", {"gyro_arw_deg_rh": 1.0}, "vehicles.uav0.sensors.imu", ctx=CTX)
    with pytest.raises(InputError, match="rate_hz"):
        build("sensor", "imu", {"rate_hz": 30.0}, "imu", ctx=CTX)


def test_mean_rate_is_the_rotation_between_attitudes_plus_the_ned_rate():
    q0 = euler_to_quat(np.array([0.3, -0.1, 2.0]))
    w_nb_b = np.array([0.2, -0.5, 0.9])  # body rate relative to NED (rad/s)
    dt = 0.01
    q1 = quat_multiply(q0, rotvec_to_quat(w_nb_b * dt))
    lat, h, v = np.deg2rad(47.0), 1300.0, np.array([20.0, -15.0, 1.0])
    w_in_n = earth_rate_ned_rps(lat) + transport_rate_ned_rps(lat, h, v)
    got = np.array(mean_rate_ib_b(q0, q1, dt, lat, h, v))
    np.testing.assert_allclose(got, w_nb_b + quat_to_dcm(q1).T @ w_in_n, atol=1e-9)


def test_gyro_reads_the_rate_that_moved_the_attitude_not_the_one_reported_after_it():
    # A JSBSim-like truth: each step turns the heading with the rate at the step's START
    # (rectangular Euler), and the truth then reports the new rate. A noiseless gyro must give
    # the increment's rate, so that an INS integrating it stays on the truth attitude.
    quiet = dict(QUIET, gyro_arw_deg_rth=0.0, gyro_bias_instability_deg_h=0.0, gyro_lsb_deg_s=0.0)
    imu = Imu(ImuParams(preset="tactical", rate_hz=100.0, **quiet), ctx=CTX)
    rng, world = np.random.default_rng(0), FakeWorld()
    yaw, rate = 0.0, 0.0
    for k in range(1, 50):
        prev_rate = rate
        yaw += prev_rate * 0.01
        rate = 0.02 * k  # a roll-in: the yaw rate ramps up
        s = imu.measure(make_truth(k / 100.0, rpy_rad=(0.0, 0.0, yaw), omega_eb_b_rps=(0.0, 0.0, rate)), world, rng)
        if k > 1:
            earth_z = (quat_to_dcm(euler_to_quat(np.array([0.0, 0.0, yaw]))).T @ earth_rate_ned_rps(ORIGIN.lat_rad))[2]
            assert s.omega_ib_b_rps[2] == pytest.approx(prev_rate + earth_z, abs=1e-7)
            assert abs(s.omega_ib_b_rps[2] - (rate + earth_z)) > 0.019  # not the reported rate
