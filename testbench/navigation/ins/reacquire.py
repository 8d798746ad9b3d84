"""Re-acquisition of the INS/EKF from a source its gate keeps refusing: the reset of the
position (GNSS, position fixes), of the height (barometer) and of the wind (rotor drag,
airspeed), as PX4's EKF2 resets after a fusion timeout, and the gate-or-reset rule the
navigator and its air-relative aiding apply to each measurement.

`Reacquisition` is a mixin of ErrorStateEKF (it uses its flush, P and update): each reset sets
the covariance of the states the disagreement says are wrong from that disagreement, then fuses
the measurement without the gate, and returns the NIS the gate saw before the reset with
accepted=True.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from testbench.core.messages import CorrectionInfo
from testbench.core.units import STANDARD_GRAVITY_MPS2
from testbench.navigation.ins.error_model import IA, IP, IV, IW


class Reacquisition:
    """reset_position / reset_height / reset_wind of ErrorStateEKF (see the module docstring)."""

    def _reset_prologue(self, y, H, R):
        """(y (m,), H (m, n), R (m, m), the NIS the gate saw) with the covariance propagated."""
        self.flush()
        y = np.atleast_1d(np.asarray(y, float))
        H = np.atleast_2d(np.asarray(H, float))
        R = np.atleast_2d(np.asarray(R, float))
        return y, H, R, float(y @ np.linalg.solve(H @ self.P @ H.T + R, y))

    def _fuse_after_reset(self, kind: str, t_s: float, y, H, R, P: np.ndarray, nis_before: float) -> CorrectionInfo:
        """Install the reset covariance P (symmetrised) and fuse the measurement without the gate."""
        self.P = 0.5 * (P + P.T)
        info = self.update(kind, t_s, y, H, R, gate=False)
        return CorrectionInfo(t_s=info.t_s, kind=info.kind, innovation=info.innovation,
                              innovation_cov=info.innovation_cov, nis=nis_before, accepted=True)

    def reset_position(self, kind: str, t_s: float, y, H, R, elapsed_s: float) -> CorrectionInfo:
        """Re-acquire the position (and velocity) from a measurement the gate keeps rejecting,
        after elapsed_s seconds without an accepted one: a position fix (residual y (3,) in
        origin NED m) or a GNSS fix (y (6,): position, then velocity NED m/s); H (k, n),
        R (k, k).

        The position block of P becomes what the disagreement says, H_p^T (y y^T + R) H_p in
        the error frame, with its cross-covariances cleared (the old correlations described a
        filter that was wrong). Without a velocity measurement the velocity variance grows by
        (y / elapsed_s)^2, the velocity error that would explain the disagreement; with one the
        velocity block is set like the position's, and the tilt variance grows by the tilt that
        would have built that velocity error over elapsed_s (|dv_horizontal| / (g elapsed_s)):
        a filter that lost its velocity was wrong about its level too. Then the measurement is
        fused without the gate.
        """
        y, H, R, nis_before = self._reset_prologue(y, H, R)
        elapsed = max(float(elapsed_s), 1.0)
        P = self.P.copy()
        Hp = H[:3, IP]
        P[IP, :] = 0.0
        P[:, IP] = 0.0
        P[IP, IP] = Hp.T @ (np.outer(y[:3], y[:3]) + R[:3, :3]) @ Hp
        if len(y) >= 6:
            Hv = H[3:6, IV]
            P[IV, :] = 0.0
            P[:, IV] = 0.0
            P[IV, IV] = Hv.T @ (np.outer(y[3:6], y[3:6]) + R[3:6, 3:6]) @ Hv
            tilt_rad = float(np.hypot(y[3], y[4])) / (STANDARD_GRAVITY_MPS2 * elapsed)
            tilt = [IA.start, IA.start + 1]  # north and east attitude errors (diagonal entries)
            P[tilt, tilt] += tilt_rad**2
        else:
            dv_mps = (Hp.T @ y[:3]) / elapsed
            P[IV, IV] += np.diag(dv_mps**2)
        return self._fuse_after_reset(kind, t_s, y, H, R, P, nis_before)

    def reset_height(self, kind: str, t_s: float, y, H, R, elapsed_s: float) -> CorrectionInfo:
        """Re-acquire the height from a height measurement (barometer: residual y (1,) m, H (1, n)
        with its down-position entry, R (1, 1)) the gate has rejected for elapsed_s seconds.

        The vertical twin of reset_position, as PX4's EKF2 resets its height to the baro after a
        height fusion timeout: the down-position variance becomes (y^2 + R) / H_d^2 with its
        cross-covariances cleared, the down-velocity variance grows by (y / elapsed_s)^2 (the
        velocity error that would explain the disagreement), then the measurement is fused
        without the gate.
        """
        y, H, R, nis_before = self._reset_prologue(y, H, R)
        i_d, i_vd = IP.start + 2, IV.start + 2
        h_d = float(H[0, i_d])
        if h_d == 0.0:
            raise ValueError(f"{kind}: reset_height needs a measurement of the down position")
        P = self.P.copy()
        P[i_d, :] = 0.0
        P[:, i_d] = 0.0
        P[i_d, i_d] = (float(y[0]) ** 2 + float(R[0, 0])) / h_d**2
        P[i_vd, i_vd] += (float(y[0]) / max(float(elapsed_s), 1.0)) ** 2
        return self._fuse_after_reset(kind, t_s, y, H, R, P, nis_before)

    def reset_wind(self, kind: str, t_s: float, y, H, R, elapsed_s: float = 0.0) -> CorrectionInfo:
        """Re-acquire the wind from a measurement of the velocity through the air (rotor drag,
        airspeed and sideslip: residual y (m,), H (m, n) with its wind columns, R (m, m)) that
        the gate has kept refusing (for elapsed_s seconds; the reset does not depend on it):
        the wind moved further than its covariance allowed (a gust front, a change of wind),
        and a filter that refuses every such sample never learns it.

        The wind block of P grows by what the disagreement says, H_w^+ (y y^T + R) H_w^+T with
        H_w^+ the pseudo-inverse of H's wind columns (the wind change that would explain y, and
        the measurement's noise mapped alike); its cross-covariances are kept, since the
        velocity's error is still tied to the wind's through every drag sample fused before
        (clearing them made the velocity look known on its own: the filter overconfident, and
        lost in one of three runs). Then the measurement is fused without the gate. Needs the
        wind states."""
        if not self.wind_states:
            raise ValueError("reset_wind needs the filter's wind states")
        y, H, R, nis_before = self._reset_prologue(y, H, R)
        Hw_pinv = np.linalg.pinv(H[:, IW])
        P = self.P.copy()
        P[IW, IW] += Hw_pinv @ (np.outer(y, y) + R) @ Hw_pinv.T
        return self._fuse_after_reset(kind, t_s, y, H, R, P, nis_before)


def update_or_reset(ekf, kind: str, t: float, y, H, R, last_ok_t_s: float | None, reset_after_s: float,
                    reset: Callable[..., CorrectionInfo], other_ok_t_s: float | None = None,
                    ) -> tuple[CorrectionInfo, float | None]:
    """Fuse a measurement through the gate; when its source has been refused for reset_after_s
    (> 0; 0: never), re-acquire from it with `reset` (one of ekf's reset_* methods; the kind
    becomes "<kind>:reset"), unless another source (other_ok_t_s: its last accepted time; None:
    there is none) was accepted within that time: then the filter agrees with that one, and the
    source it keeps refusing is the faulty one (a spoofer, a matcher locked on the wrong place).
    Returns (info, the source's new last-accepted time)."""
    info = ekf.update(kind, t, y, H, R)
    if last_ok_t_s is None or info.accepted:
        return info, t
    refused_s = t - last_ok_t_s
    other_agrees = other_ok_t_s is not None and t - other_ok_t_s < reset_after_s
    if reset_after_s > 0.0 and refused_s >= reset_after_s and not other_agrees:
        return reset(f"{kind}:reset", t, y, H, R, refused_s), t
    return info, last_ok_t_s
