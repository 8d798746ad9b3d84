"""The GNSS spoofing monitor (gnss_monitor.py): receiver velocity change against the INS's."""

import numpy as np
import pytest

from testbench.navigation.ins.gnss_monitor import GnssInertialMonitor, GnssMonitorParams

SIGMA_V = 0.1  # m/s, the receiver's velocity claim per axis


def _fly(mon, rng, duration_s, spoof_accel_mps2=0.0, spoof_start_s=np.inf, turn_accel_mps2=5.7, imu_hz=100):
    """A vehicle turning (its velocity vector rotating: the INS and the receiver see the same
    acceleration), a receiver at 1 Hz with white velocity noise, and from spoof_start_s a
    spoofer accelerating the fix east. Returns the (t, q) of every fix and the alarm time."""
    out = []
    dt = 1.0 / imu_hz
    omega = turn_accel_mps2 / 25.0  # 25 m/s
    for k in range(int(duration_s * imu_hz) + 1):
        t = k * dt
        v = 25.0 * np.array([np.cos(omega * t), np.sin(omega * t), 0.0])
        if k:
            mon.add_inertial(v - v_prev)
        v_prev = v
        if k % imu_hz == 0:
            tau = max(t - spoof_start_s, 0.0)
            fix_v = v + np.array([0.0, spoof_accel_mps2 * tau, 0.0]) + SIGMA_V * rng.standard_normal(3)
            out.append((t, mon.test(t, fix_v, np.full(3, SIGMA_V))))
    return out


def test_a_turning_flight_without_a_spoofer_stays_quiet_and_q_is_chi_square():
    rng = np.random.default_rng(1)
    mon = GnssInertialMonitor(GnssMonitorParams())
    qs = np.array([q for _, q in _fly(mon, rng, 3000.0)])[20:]
    assert not mon.alarm
    # Without the INS's own error in this test the model's accel term only adds caution: q is at
    # most chi2(3)'s (mean 3), and of the right size (the receivers' noise is modelled exactly).
    assert 1.0 < qs.mean() < 3.0
    assert qs.max() < mon.threshold


def test_a_carry_off_raises_the_alarm_within_seconds():
    rng = np.random.default_rng(2)
    mon = GnssInertialMonitor(GnssMonitorParams())
    _fly(mon, rng, 200.0, spoof_accel_mps2=0.05, spoof_start_s=100.0)
    assert mon.alarm
    # 0.05 m/s^2 over the 10 s window is 0.5 m/s against sigma_d ~0.1 m/s: q ~ 27 once the ramp
    # fills the window, beyond 16.3 (chi2(3) at 0.999) three tests in a row well before that.
    assert 100.0 + 5.0 <= mon.alarm_t_s <= 100.0 + 14.0


def test_a_slower_carry_off_than_the_ins_error_goes_unseen():
    """The monitor's stated limit: a drag accelerating at the INS's own unexplained level."""
    rng = np.random.default_rng(3)
    mon = GnssInertialMonitor(GnssMonitorParams())
    _fly(mon, rng, 300.0, spoof_accel_mps2=0.005, spoof_start_s=100.0)
    assert not mon.alarm


def test_release_needs_the_test_and_the_gate_for_release_s():
    mon = GnssInertialMonitor(GnssMonitorParams(release_s=10.0))
    mon.alarm, mon.q = True, 0.0
    assert not mon.consider_release(0.0, gate_passed=True)
    assert not mon.consider_release(5.0, gate_passed=False)  # the gate failed: the clock restarts
    assert not mon.consider_release(6.0, gate_passed=True)
    assert not mon.consider_release(15.0, gate_passed=True)
    assert mon.consider_release(16.0, gate_passed=True) and not mon.alarm


def test_params_reject_nonsense():
    with pytest.raises(Exception):
        GnssMonitorParams(window_s=0.0)
    with pytest.raises(Exception):
        GnssMonitorParams(probability=1.0)
