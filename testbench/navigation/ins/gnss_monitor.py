"""A GNSS spoofing monitor that needs no second position source: the receiver's velocity change
over a window against the change the INS integrated from its own accelerometers.

A spoofer that drags the fix away must accelerate it (a carry-off: Humphreys et al. 2008; the
test follows the inertial monitors of Tanil, Khanafseh and Pervan, IEEE TAES 2018). The INS
measures the vehicle's true accelerations, so over a window T the receiver's velocity change
Delta v_gnss = v_gnss(t) - v_gnss(t - T) and the INS's own Delta v_ins (the sum of its
propagation steps, without the filter's corrections) differ by the spoofer's acceleration times
T. Without a spoofer they differ by the receivers' velocity noise at both ends and by what the
INS gets wrong about the acceleration over T (tilt times g, heading error times the turn's
acceleration, bias, scale factor), modelled as a white `accel_sigma_mps2`:

  d = Delta v_gnss - Delta v_ins                                  (NED, m/s)
  q = sum_i d_i^2 / (var_gnss_i(t) + var_gnss_i(t - T) + (accel_sigma T)^2)     ~ chi2(3)

`n_consecutive` tests in a row beyond the chi-square quantile at `probability` raise the alarm.
The filter fusing the dragged fixes meanwhile tilts its attitude to explain the drag (about
5 mrad for 0.05 m/s^2), and the INS's steps then carry it: a drag the test above has not caught
within 10-15 s hides from it until a turn shows the tilt. So a second test compares the fixes
with free-running copies of the INS, one started at each fix from the filter's state then and
never corrected: over free_window_s, d = the mean of (v_gnss - v_copy) over the window's last
fixes less the same over its first, with the same variance model. A copy started before the
filter tilted keeps seeing the whole drag. (It is an option, off by default: it also sees the
filter's own tilt when that errs by more than its covariance says; see GnssMonitorParams.)
Each end's receiver velocity is the mean of its last `average_fixes` fixes (its claim divided
accordingly), and the INS's sum the mean of its values at those fixes' times. What it cannot
see: a spoofer that never accelerates faster than the INS's own error (an offset grown at
accel_sigma or less), or one that has finished its ramp by the time the monitor starts; a
position fix (scene matching) sees those.
"""

from __future__ import annotations

import copy
from collections import deque

import numpy as np
import pydantic
from scipy import stats

from testbench.core.registry import ParamsModel


class GnssMonitorParams(ParamsModel):
    """window_s: T (s) of the first test; average_fixes: fixes averaged at each end of a window;
    accel_sigma_mps2: 1-sigma of the INS's unexplained acceleration over a window (m/s^2; the
    paper IMU's tilt of 0.3 mrad is 0.003, a 1 mrad heading error in a 30 deg bank 0.006; with
    0.005 the first test's q had median 1.9-2.5 and 99th percentile 8.9-11.1 over six 600 s
    flights of the paper racetrack with GNSS throughout, chi2(3)'s being 2.37 and 11.3; a
    consumer MEMS IMU needs ten times more);
    probability: chi-square quantile one test must pass (per test: the tests overlap, so the
    false-alarm rate per hour is set by n_consecutive as much; docs/measurements.md gives the
    batches it was chosen on); n_consecutive: failed tests in a row (of either test) that raise
    the alarm;
    free_window_s (None: off): the second test's window, against free-running copies of the
    INS (module docstring). Off by default: over 20 carry-offs it caught all within 7-18 s
    (20 s; the first test alone 18 within 7-13 s, two in the first turn), but over 20 flights of
    600 s with true GNSS it also alarmed four times (the first test never) on spells in which
    the filter's own tilt erred by 5 sigma (1.8 mrad of pitch claimed as 0.34): it sees the
    filter's inconsistency as well as a spoofer. With it on, set rollback_s to its window plus 5 s;
    rollback_s: on the alarm the navigator goes back to its state before the GNSS fix this long
    before (the spoofer's acceleration began about a window plus the tests in a row before the
    alarm) and replays the IMU and the other aids since without GNSS (rollback.py): the fixes
    it fused meanwhile had put the spoofer's drag into its velocity and attitude;
    release_s: once raised, GNSS comes back only after the first test and the filter's own
    gate have both passed for this long (a spoofer that stops accelerating passes the first,
    not the second: its offset stays)."""

    window_s: float = pydantic.Field(10.0, gt=0)
    average_fixes: int = pydantic.Field(3, ge=1)
    accel_sigma_mps2: float = pydantic.Field(0.005, gt=0)
    probability: float = pydantic.Field(0.999, gt=0.5, lt=1.0)
    n_consecutive: int = pydantic.Field(3, ge=1)
    free_window_s: float | None = pydantic.Field(None, gt=0)
    release_s: float = pydantic.Field(30.0, ge=0)
    rollback_s: float = pydantic.Field(20.0, ge=0)


class GnssInertialMonitor:
    """Feed it every IMU propagation's velocity step (`add_inertial`) and every GNSS fix
    (`test`); `alarm` says whether GNSS is suspected now."""

    def __init__(self, p: GnssMonitorParams):
        self.p = p
        self.threshold = float(stats.chi2.ppf(p.probability, 3))
        self._dv_ins = np.zeros(3)  # running sum of the INS's propagation steps (NED m/s)
        self._fixes: deque[tuple[float, np.ndarray, np.ndarray, np.ndarray]] = deque()  # t, v, var, sum dv
        self._recent: deque[tuple[np.ndarray, np.ndarray, np.ndarray]] = deque(maxlen=p.average_fixes)
        self._n_failed = 0
        self._clean_since_s: float | None = None
        self.alarm = False
        self.alarm_t_s: float | None = None
        self.q = 0.0
        self.q_free = 0.0
        self._n_failed_free = 0
        # Free-running INS copies: [t0, ins copy, b_g, b_a, [(v_gnss - v_copy, var) per fix],
        # their acceleration error's variance at t0 (m^2/s^4), their heading error's (rad^2),
        # their velocity at t0 (3,)].
        self._copies: deque[list] = deque()

    def add_inertial(self, dv_ned_mps) -> None:
        """One propagation step's velocity change (3,) NED m/s (not a correction's)."""
        self._dv_ins += dv_ned_mps

    def start_copy(self, t_s: float, ins, b_g, b_a, accel_var_mps4: float = 0.0, heading_var_rad2: float = 0.0) -> None:
        """A free-running copy of the INS (a StrapdownINS, copied) with the filter's IMU bias
        estimates (3,) at t_s, the time of the fix just tested; accel_var_mps4: the variance of
        the acceleration error the filter's own covariance gives the copy at its start (its tilt
        times g, its accelerometer bias), added to accel_sigma's: early in a flight, before the
        filter has settled, a copy drifts by more than the settled figure; heading_var_rad2: the
        variance of its heading error, which turns the copy's horizontal velocity change (a
        turn's, up to twice the speed) by that angle."""
        if self.p.free_window_s is not None:
            self._copies.append([t_s, copy.copy(ins), tuple(float(x) for x in b_g), tuple(float(x) for x in b_a), [],
                                 float(accel_var_mps4), float(heading_var_rad2), np.asarray(ins.vel, float)])

    def propagate_copies(self, t_s: float, omega_ib_b_rps, f_ib_b_mps2) -> None:
        """Advance every copy to t_s with the raw IMU output (rad/s, m/s^2), less its biases."""
        w, f = omega_ib_b_rps, f_ib_b_mps2
        for c in self._copies:
            ins, bg, ba = c[1], c[2], c[3]
            dt = t_s - ins.t_s
            if dt > 0.0:
                ins.step_increments(((w[0] - bg[0]) * dt, (w[1] - bg[1]) * dt, (w[2] - bg[2]) * dt),
                                    ((f[0] - ba[0]) * dt, (f[1] - ba[1]) * dt, (f[2] - ba[2]) * dt), dt)
                ins.t_s = float(t_s)

    def _test_free(self, t_s: float, vel: np.ndarray, var: np.ndarray) -> None:
        """The second test, on the copies whose window ends at this fix (q_free: the largest)."""
        k, T = self.p.average_fixes, self.p.free_window_s
        for c in self._copies:
            c[4].append((vel - np.asarray(c[1].vel), var))
        self.q_free = 0.0
        while self._copies and t_s - self._copies[0][0] >= T - 1e-9:
            t0, ins, _, _, e, accel_var, heading_var, v0 = self._copies.popleft()
            if len(e) < 2 * k:
                continue
            d = sum(x for x, _ in e[-k:]) / k - sum(x for x, _ in e[:k]) / k
            dv = np.asarray(ins.vel, float) - v0
            turn_var = heading_var * float(dv[0] ** 2 + dv[1] ** 2)  # the heading error turns dv
            v = ((sum(s for _, s in e[-k:]) + sum(s for _, s in e[:k])) / (k * k)
                 + (self.p.accel_sigma_mps2 ** 2 + accel_var) * (t_s - t0) ** 2
                 + np.array([turn_var, turn_var, 0.0]))
            self.q_free = max(self.q_free, float(np.sum(d * d / v)))
        self._n_failed_free = self._n_failed_free + 1 if self.q_free > self.threshold else 0

    def test(self, t_s: float, vel_ned_mps, vel_sigma_mps) -> float:
        """Test a fix's velocity (3,) with its claimed sigma (3,): the first test against the
        window (returns its q, 0 until a window's worth of fixes is in), the second against the
        free-running copies whose window ends here (q_free); updates `alarm`."""
        # Both sides averaged over the same fixes: a mean of fixes lags the newest by half their
        # span, and in a turn's entry (5.7 m/s^2 at 30 deg of bank) the INS's sum taken at the
        # newest alone was metres per second off it.
        vel, var = np.asarray(vel_ned_mps, float), np.square(np.asarray(vel_sigma_mps, float))
        if self.p.free_window_s is not None:
            self._test_free(t_s, vel, var)
        self._recent.append((vel, var, self._dv_ins.copy()))
        n = len(self._recent)
        v_mean = sum(r[0] for r in self._recent) / n
        var_mean = sum(r[1] for r in self._recent) / (n * n)
        dv_mean = sum(r[2] for r in self._recent) / n
        self._fixes.append((t_s, v_mean, var_mean, dv_mean))
        while len(self._fixes) > 1 and self._fixes[1][0] <= t_s - self.p.window_s + 1e-9:
            self._fixes.popleft()
        t0, v0, var0, dv0 = self._fixes[0]
        T = t_s - t0
        self.q = 0.0
        if T >= self.p.window_s - 1e-9 and n >= self.p.average_fixes:
            d = (v_mean - v0) - (dv_mean - dv0)
            var = var_mean + var0 + (self.p.accel_sigma_mps2 * T) ** 2
            self.q = float(np.sum(d * d / var))
        self._n_failed = self._n_failed + 1 if self.q > self.threshold else 0
        if not self.alarm and max(self._n_failed, self._n_failed_free) >= self.p.n_consecutive:
            self.alarm, self.alarm_t_s, self._clean_since_s = True, t_s, None
        return self.q

    def consider_release(self, t_s: float, gate_passed: bool) -> bool:
        """While the alarm stands: count the time both the monitor's last test and the filter's
        gate (on the fix just tested) have passed; release the alarm after release_s of that.
        Returns whether the alarm was released now."""
        if not self.alarm:
            return False
        if self.q > self.threshold or not gate_passed:
            self._clean_since_s = None
            return False
        if self._clean_since_s is None:
            self._clean_since_s = t_s
        if t_s - self._clean_since_s >= self.p.release_s:
            self.alarm, self._n_failed, self._n_failed_free, self._clean_since_s = False, 0, 0, None
            self._copies.clear()  # started before or during the alarm: a fresh start
            return True
        return False
