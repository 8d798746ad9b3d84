"""What the INS/EKF navigator does with its GNSS spoofing monitor (`navigation.params.gnss_monitor`):
feeds it the INS's propagation and every fix, snapshots the navigator before each fix it fuses,
and on the monitor's alarm rewinds it and holds GNSS out.

The monitor's tests are in gnss_monitor.py, the snapshots and the inputs kept for a replay in
rollback.py; this module is the glue between them and InsEkfNavigator, kept out of the
navigator so that it reads as the filter's measurement dispatch.
"""

from __future__ import annotations

import logging

import numpy as np

from testbench.core.messages import CorrectionInfo, GnssFix, ImuSample
from testbench.core.units import STANDARD_GRAVITY_MPS2
from testbench.navigation.ins.ekf import chi2_threshold
from testbench.navigation.ins.error_model import IA, IBA
from testbench.navigation.ins.gnss_monitor import GnssInertialMonitor, GnssMonitorParams
from testbench.navigation.ins.rollback import RollbackBuffer, replay, restore

log = logging.getLogger(__name__)


class GnssSpoofGuard:
    """One navigator's monitor (`monitor`) and rollback buffer. `nav` is the InsEkfNavigator
    it guards: its `ekf`, `_gnss_residual`, `predict`, `correct`, and the attributes named in
    its ROLLBACK_ATTRS (the state a rewind restores)."""

    def __init__(self, p: GnssMonitorParams):
        self.monitor = GnssInertialMonitor(p)
        self.rollback = RollbackBuffer(p.rollback_s + 5.0)
        self.replaying = False

    def propagate(self, nav, imu: ImuSample) -> None:
        """The navigator's INS propagation with the monitor's bookkeeping: the sample kept for
        a replay, the INS's own velocity step summed (no correction's), the free-running copies
        advanced. During a replay, the propagation alone."""
        ekf = nav.ekf
        if self.replaying:
            ekf.propagate(float(imu.t_s), imu.omega_ib_b_rps, imu.f_ib_b_mps2)
            return
        self.rollback.record(imu)
        v0 = ekf.ins.vel
        ekf.propagate(float(imu.t_s), imu.omega_ib_b_rps, imu.f_ib_b_mps2)
        v1 = ekf.ins.vel
        self.monitor.add_inertial((v1[0] - v0[0], v1[1] - v0[1], v1[2] - v0[2]))
        self.monitor.propagate_copies(float(imu.t_s), imu.omega_ib_b_rps, imu.f_ib_b_mps2)

    def record(self, measurement) -> None:
        """A measurement of another aid, kept for a replay (GNSS fixes are not replayed)."""
        if not self.replaying and not isinstance(measurement, GnssFix):
            self.rollback.record(measurement)

    def screen(self, nav, fix: GnssFix, t: float, vel: np.ndarray, y, H, R) -> CorrectionInfo | None:
        """Test a GNSS fix (its residual y, H, R against the filter) with the monitor. While the
        alarm stands: the fix tested but not fused ("gnss:excluded"; no reset to it either),
        and on the alarm's first fix the navigator rewound first. Otherwise None: the caller
        fuses it, the navigator's state snapshotted before (and a free-running copy started)."""
        mon = self.monitor
        was_alarm = mon.alarm
        mon.test(t, vel, fix.vel_sigma_mps)
        if mon.alarm:
            if not was_alarm:
                log.warning("%s: GNSS excluded from t=%.1f s: the fixes' velocity change disagrees with the "
                            "INS's (spoofing monitor q=%.1f, free-running q=%.1f, threshold %.1f); the filter "
                            "goes back %.0f s and runs on without it", nav.ctx.vehicle_id, t, mon.q, mon.q_free,
                            mon.threshold, mon.p.rollback_s)
                self._rewind(nav, t - mon.p.rollback_s)
                nav._last_gnss_t = t
                y, H, R = nav._gnss_residual(fix, vel)
            info = nav.ekf.check("gnss:excluded", t, y, H, R)
            gate_ok = info.nis <= chi2_threshold(nav.params.gate_probability, y.size)
            if mon.consider_release(t, gate_ok):
                log.warning("%s: GNSS re-admitted at t=%.1f s (monitor and gate passed for %.0f s)",
                            nav.ctx.vehicle_id, t, mon.p.release_s)
            return info
        self.rollback.snapshot(t, {k: getattr(nav, k) for k in nav.ROLLBACK_ATTRS})
        if mon.p.free_window_s is not None:
            # The copy's errors from the filter's own covariance: its acceleration error (tilt
            # times g, and the accelerometer bias: means of the horizontal tilt and of the three
            # bias variances) and its heading error.
            ekf = nav.ekf
            P = ekf.covariance()
            accel_var = (STANDARD_GRAVITY_MPS2**2 * 0.5 * (P[IA, IA][0, 0] + P[IA, IA][1, 1])
                         + float(np.trace(P[IBA, IBA])) / 3.0)
            mon.start_copy(t, ekf.ins, ekf.b_g, ekf.b_a, accel_var, P[IA, IA][2, 2])
        return None

    def _rewind(self, nav, before_t_s: float) -> None:
        """Back to the navigator's state before the GNSS fix at or before before_t_s, then the
        IMU samples and the other aids' measurements since, replayed in order without GNSS."""
        back = self.rollback.rewind(before_t_s)
        if back is None:
            return
        state, items = back
        restore(nav, state)
        self.replaying = True
        try:
            for item in items:
                replay(nav, item)
        finally:
            self.replaying = False
        nav._estimate = None
