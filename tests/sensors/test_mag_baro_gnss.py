"""Magnetometer vs WMM reference values, barometer, GNSS denial, airspeed, ideal state."""

import numpy as np
import pytest

from testbench.core.geodesy import geodetic_to_ned
from testbench.core.interfaces import BuildContext, GeodeticOrigin
from testbench.core.messages import StateObservation
from testbench.sensors.airspeed import Airspeed, AirspeedParams
from testbench.sensors.barometer import Barometer, BarometerParams, isa_altitude_m, isa_pressure_pa
from testbench.sensors.fakes import ORIGIN, FakeWorld, make_truth
from testbench.sensors.gnss import Gnss, GnssParams, Spoofing, spoof_offset
from testbench.sensors.ideal_state import IdealState, IdealStateParams
from testbench.sensors.magnetometer import Magnetometer, MagnetometerParams

# NOAA WMM2025 report, test values (decimal year, height km, lat, lon, X, Y, Z nT).
WMM2025_TEST_VALUES = [
    (2025.0, 0.0, 80.0, 0.0, 6521.6, 145.9, 54791.5),
    (2025.0, 0.0, 0.0, 120.0, 39677.8, -109.6, -10580.2),
    (2027.5, 100.0, -80.0, 240.0, 5984.0, 14760.1, -49317.7),
    (2027.5, 0.0, 0.0, 120.0, 39701.6, -167.4, -10381.8),
]


@pytest.mark.parametrize("year,h_km,lat,lon,x,y,z", WMM2025_TEST_VALUES)
def test_magnetometer_matches_wmm_reference(year, h_km, lat, lon, x, y, z):
    origin = GeodeticOrigin(np.deg2rad(lat), np.deg2rad(lon), h_km * 1000.0)
    ctx = BuildContext("uav0", ("uav0",), origin, epoch_utc_year=year)
    mag = Magnetometer(MagnetometerParams(noise_nT=0.0), ctx=ctx)
    m = mag.measure(make_truth(0.02, origin=origin), FakeWorld(), np.random.default_rng(0))
    np.testing.assert_allclose(m.field_b_T * 1e9, [x, y, z], atol=50.0)


def test_magnetometer_body_rotation_hard_soft_iron():
    ctx = BuildContext("uav0", ("uav0",), ORIGIN, epoch_utc_year=2026.0)
    mag = Magnetometer(MagnetometerParams(noise_nT=0.0), ctx=ctx)
    level = mag.measure(make_truth(0.02), FakeWorld(), np.random.default_rng(0)).field_b_T
    yawed = Magnetometer(MagnetometerParams(noise_nT=0.0, hard_iron_nT=(100.0, 0, 0), soft_iron=(2, 0, 0, 0, 1, 0, 0, 0, 1)), ctx=ctx)
    m = yawed.measure(make_truth(0.02, rpy_rad=(0, 0, np.pi / 2)), FakeWorld(), np.random.default_rng(0)).field_b_T
    # Heading east: body x sees the east component, body y minus the north component.
    np.testing.assert_allclose(m, [2 * level[1] + 100e-9, -level[0], level[2]], atol=1e-12)


def test_isa_round_trip_and_barometer():
    h = np.array([-200.0, 0.0, 500.0, 3000.0, 10000.0])
    np.testing.assert_allclose(isa_altitude_m(isa_pressure_pa(h)), h, atol=1e-6)
    assert isa_pressure_pa(0.0) == pytest.approx(101325.0)
    ctx = BuildContext("uav0", ("uav0",), ORIGIN)
    baro = Barometer(BarometerParams(noise_pa=0.0, bias_pa=0.0, bias_drift_pa_rth=0.0, lag_s=0.0, lsb_pa=0.0), ctx=ctx)
    t = make_truth(0.02, pos_ned_m=(0, 0, -200.0))
    assert baro.measure(t, FakeWorld(), np.random.default_rng(0)).altitude_m == pytest.approx(t.alt_m, abs=1e-6)


def test_barometer_lag_noise_quantisation():
    ctx = BuildContext("uav0", ("uav0",), ORIGIN)
    baro = Barometer(BarometerParams(noise_pa=0.0, bias_pa=0.0, bias_drift_pa_rth=0.0, lag_s=0.2, lsb_pa=0.0), ctx=ctx)
    rng = np.random.default_rng(0)
    p0 = baro.measure(make_truth(0.0, pos_ned_m=(0, 0, 0)), FakeWorld(), rng).pressure_pa
    step = make_truth(0.02, pos_ned_m=(0, 0, -100.0)).pressure_pa
    out = [baro.measure(make_truth(k * 0.02, pos_ned_m=(0, 0, -100.0)), FakeWorld(), rng).pressure_pa for k in range(1, 11)]
    # First-order lag: after tau (10 samples of 0.02 s) 1 - e^-1 of the step is done.
    assert (out[-1] - p0) / (step - p0) == pytest.approx(1 - np.exp(-1.0), abs=1e-9)
    q = Barometer(BarometerParams(noise_pa=3.0, lsb_pa=0.5), ctx=ctx)
    vals = np.array([q.measure(make_truth(k * 0.02), FakeWorld(), rng).pressure_pa for k in range(300)])
    np.testing.assert_allclose(vals / 0.5, np.round(vals / 0.5), atol=1e-9)
    assert np.std(np.diff(vals)) / np.sqrt(2) == pytest.approx(3.0, rel=0.15)


def _gnss_run(params, duration_s=120.0, seed=0):
    ctx = BuildContext("uav0", ("uav0",), ORIGIN, physics_rate_hz=100.0)
    g = Gnss(params, ctx=ctx)
    rng = np.random.default_rng(seed)
    out = []
    for k in range(int(duration_s * g.rate_hz)):
        t = k / g.rate_hz
        truth = make_truth(t, pos_ned_m=(10.0 * t, 0.0, -100.0), vel_ned_mps=(10.0, 0.0, 0.0))
        fix = g.measure(truth, FakeWorld(t), rng)
        if fix is not None:
            ned = geodetic_to_ned(fix.lat_rad, fix.lon_rad, fix.alt_m, ORIGIN.lat_rad, ORIGIN.lon_rad, ORIGIN.alt_m)
            out.append((t, fix.t_s, np.asarray(ned) - [10.0 * fix.t_s, 0.0, -100.0], fix))
    return out


def test_gnss_jamming_degraded_spoofing():
    p = GnssParams(
        rate_hz=5.0, pos_corr_sigma_m=0.0,
        denial=[{"type": "jamming", "start_s": 20.0, "end_s": 30.0},
                {"type": "degraded", "start_s": 40.0, "end_s": 100.0, "sigma_scale": 5.0},
                {"type": "spoofing", "start_s": 100.0, "drift_ned_mps": [1.0, 0.0, 0.0]}],
    )
    out = _gnss_run(p)
    ts = np.array([o[1] for o in out])
    assert not np.any((ts >= 20.0) & (ts < 30.0))  # jammed: no fix
    normal = np.array([o[2] for o in out if o[1] < 20.0])
    degraded = np.array([o[2] for o in out if 40.0 <= o[1] < 100.0])
    assert np.std(normal[:, 0]) == pytest.approx(1.5, rel=0.25)
    assert np.std(degraded[:, 0]) == pytest.approx(7.5, rel=0.2)
    assert all(o[3].pos_sigma_m[0] == pytest.approx(7.5) for o in out if 40.0 <= o[1] < 100.0)
    spoof = [(o[1], o[2][0]) for o in out if o[1] >= 100.0]
    t_s, err_n = np.array(spoof).T
    slope = np.polyfit(t_s - 100.0, err_n, 1)[0]
    assert slope == pytest.approx(1.0, abs=0.1)  # a growing 1 m/s offset
    assert all(o[3].vel_ned_mps[0] == pytest.approx(11.0, abs=0.5) for o in out if o[1] >= 100.0)


def test_spoof_carry_off_ramps_the_drift_without_a_step():
    """A carry-off (accel_mps2) starts with no offset and no velocity step, reaches the drift
    speed at |drift| / accel and goes on at it; the offset is continuous there."""
    w = Spoofing(type="spoofing", start_s=10.0, drift_ned_mps=(0.0, 3.0, 0.0), accel_mps2=0.05)
    pos, vel = spoof_offset(w, 10.0)
    np.testing.assert_allclose([pos, vel], 0.0)
    pos, vel = spoof_offset(w, 30.0)  # 20 s in: 1 m/s, 10 m
    np.testing.assert_allclose(pos, [0.0, 10.0, 0.0])
    np.testing.assert_allclose(vel, [0.0, 1.0, 0.0])
    before, _ = spoof_offset(w, 10.0 + 60.0 - 1e-9)
    after, vel = spoof_offset(w, 10.0 + 60.0 + 1e-9)
    np.testing.assert_allclose(before, after, atol=1e-6)  # 90 m at the end of the ramp
    np.testing.assert_allclose(after, [0.0, 90.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(vel, [0.0, 3.0, 0.0])
    np.testing.assert_allclose(spoof_offset(w, 80.0)[0], [0.0, 120.0, 0.0])
    step = Spoofing(type="spoofing", start_s=10.0, drift_ned_mps=(1.0, 0.0, 0.0), offset_ned_m=(0.0, 5.0, 0.0))
    pos, vel = spoof_offset(step, 12.0)
    np.testing.assert_allclose(pos, [2.0, 5.0, 0.0])
    np.testing.assert_allclose(vel, [1.0, 0.0, 0.0])
    p = GnssParams(rate_hz=5.0, pos_sigma_ne_m=0.0, pos_sigma_d_m=0.0, pos_corr_sigma_m=0.0, vel_sigma_mps=0.0,
                   denial=[w.model_dump()])
    fixes = {round(o[1], 6): o for o in _gnss_run(p, duration_s=40.0)}
    np.testing.assert_allclose(fixes[30.0][2], [0.0, 10.0, 0.0], atol=1e-6)  # the receiver's fix, dragged
    np.testing.assert_allclose(fixes[30.0][3].vel_ned_mps, [10.0, 1.0, 0.0], atol=1e-9)


def test_gnss_latency():
    out = _gnss_run(GnssParams(rate_hz=5.0, latency_s=0.4), duration_s=10.0)
    assert all(t_deliver - t_valid == pytest.approx(0.4) for t_deliver, t_valid, _, _ in out)


def test_airspeed_and_ideal_state():
    ctx = BuildContext("uav0", ("uav0",), ORIGIN)
    a = Airspeed(AirspeedParams(bias_pa=0.0), ctx=ctx)
    rng = np.random.default_rng(0)
    v = np.array([a.measure(make_truth(k * 0.05, airspeed_mps=25.0), FakeWorld(), rng).airspeed_mps for k in range(2000)])
    rho = 1.2  # about; sigma_V = sigma_q / (rho V)
    assert np.mean(v) == pytest.approx(25.0, abs=0.02)
    assert np.std(v) == pytest.approx(2.0 / (rho * 25.0), rel=0.15)
    s = IdealState(IdealStateParams(), ctx=ctx)
    t = make_truth(0.01)
    obs = s.measure(t, FakeWorld(), rng)
    assert isinstance(obs, StateObservation) and obs.truth is t
