"""Aiding from the velocity through the air: a multirotor's rotor drag and a fixed wing's pitot
airspeed with zero sideslip, fused into the INS/EKF (measurements.drag_specific_force,
true_airspeed, zero_sideslip), with the wind states' settings and the wind's re-acquisition
after a spell of refused samples (ErrorStateEKF.reset_wind).

Both measure v - w, the velocity over the ground less the wind: with the filter's wind states
(airspeed aiding always, drag aiding with wind_states) the wind is estimated; without them (drag
aiding in calm air) w = 0. The navigator owns one `AirRelativeAiding` and hands it its filter at
each call (a rewind of the spoofing monitor swaps the filter, and restores this object's
bookkeeping with it).
"""

from __future__ import annotations

import logging
import math

import numpy as np

from testbench.core.messages import CorrectionInfo
from testbench.core.rotor_drag import momentum_drag_per_s
from testbench.core.units import DEG_TO_RAD, STANDARD_GRAVITY_MPS2
from testbench.navigation.ins import measurements as meas
from testbench.navigation.ins.reacquire import update_or_reset
from testbench.navigation.ins.settings import AirspeedAiding, DragAiding, InsEkfParams

log = logging.getLogger(__name__)


def wind_settings(params: InsEkfParams) -> AirspeedAiding | DragAiding | None:
    """The aiding whose wind_sigma_mps / wind_rw_mps_sqrt_s / wind_reset_after_s set the wind
    states (airspeed aiding, or drag aiding with wind_states), or None: no wind states."""
    if params.airspeed_aiding is not None:
        return params.airspeed_aiding
    if params.drag_aiding is not None and params.drag_aiding.wind_states:
        return params.drag_aiding
    return None


class AirRelativeAiding:
    """Rotor-drag and airspeed aiding of one navigator (params: its InsEkfParams; aircraft: the
    aircraft's sidecar, for the drag coefficient when drag_aiding.coefficient_per_s is None;
    vehicle_id: for the log)."""

    def __init__(self, params: InsEkfParams, aircraft: dict | None, vehicle_id: str = ""):
        self.drag = params.drag_aiding
        self.airspeed = params.airspeed_aiding
        self.vehicle_id = vehicle_id
        d = self.drag
        self.drag_mu_per_s = None if d is None else (d.coefficient_per_s or momentum_drag_per_s(
            aircraft or {}, "navigation.params.drag_aiding", "give drag_aiding.coefficient_per_s instead"))
        """mu (1/s) of the rotor-drag model; None: no drag aiding."""
        self._drag_acc = [0.0, 0.0, 0.0, 0.0, 0, 0.0]  # sums over the interval: f_bx, f_by, v_bx, v_by; count; f_bz
        self._drag_t0_s: float | None = None
        self._last_drag_ok_t_s: float | None = None  # last drag sample the gate took
        self._last_airspeed_fused_t_s = -np.inf
        self._last_airspeed_ok_t_s: float | None = None  # last airspeed sample the gate took
        self.wind_resets = 0
        """How many times the wind was re-acquired from refused drag or airspeed samples."""

    def accumulate_drag(self, ekf, t_s: float, f_ib_b_mps2) -> None:
        """Sum the raw body x, y specific force (m/s^2) and the nominal body x, y velocity
        through the air (m/s; over the ground without wind states); every drag.interval_s fuse
        their means (measurements.drag_specific_force). Call after each INS propagation."""
        ins = ekf.ins
        qw, qx, qy, qz = ins.q
        vn, ve, vd = ins.vel
        if ekf.wind_states:  # the velocity through the air
            vn -= float(ekf.wind_ne_mps[0])
            ve -= float(ekf.wind_ne_mps[1])
        acc = self._drag_acc
        acc[0] += float(f_ib_b_mps2[0])
        acc[1] += float(f_ib_b_mps2[1])
        # v_b = C_nb^T v: dot products with C_nb's first two columns (body x and y in NED).
        acc[2] += (1 - 2 * (qy * qy + qz * qz)) * vn + 2 * (qx * qy + qw * qz) * ve + 2 * (qx * qz - qw * qy) * vd
        acc[3] += 2 * (qx * qy - qw * qz) * vn + (1 - 2 * (qx * qx + qz * qz)) * ve + 2 * (qy * qz + qw * qx) * vd
        acc[4] += 1
        acc[5] += float(f_ib_b_mps2[2])
        if self._drag_t0_s is None:
            self._drag_t0_s = t_s
        d = self.drag
        if t_s - self._drag_t0_s < d.interval_s - 1e-9:
            return
        n = acc[4]
        mu = self.drag_mu_per_s
        if d.thrust_scaled:
            # The rotors drag c omega_i v each, omega_i = sqrt(T_i / k_T), and the thrust is the
            # only body-z force: T / m = -f_bz, so mu = mu_hover sqrt(-f_bz / g). The floor at
            # 0.1 g keeps the root real through a near-free-fall (a cut throttle, a tumble).
            mu *= math.sqrt(max(-acc[5] / n, 0.1 * STANDARD_GRAVITY_MPS2) / STANDARD_GRAVITY_MPS2)
        y, H, R = meas.drag_specific_force(ekf, (acc[0] / n, acc[1] / n), (acc[2] / n, acc[3] / n), mu, d.sigma_mps2)
        reset_after_s = d.wind_reset_after_s if ekf.wind_states and d.wind_reset_after_s else 0.0
        self._last_drag_ok_t_s = self._fuse(ekf, "drag", t_s, y, H, R, self._last_drag_ok_t_s, reset_after_s)[1]
        self._drag_acc = [0.0, 0.0, 0.0, 0.0, 0, 0.0]
        self._drag_t0_s = None

    def correct_airspeed(self, ekf, airspeed_mps: float, t: float) -> CorrectionInfo | None:
        """Fuse the true airspeed (m/s) and, unless sideslip_sigma_deg is None, zero sideslip as
        one measurement ("airspeed", 1 or 2 dof), at most every airspeed.interval_s and only
        above min_airspeed_mps (measured and estimated)."""
        a = self.airspeed
        if t - self._last_airspeed_fused_t_s < a.interval_s - 1e-9:
            return None
        if airspeed_mps < a.min_airspeed_mps or np.linalg.norm(meas.air_velocity_ned(ekf)) < a.min_airspeed_mps:
            return None
        self._last_airspeed_fused_t_s = t
        y, H, R = meas.true_airspeed(ekf, airspeed_mps, a.sigma_mps)
        if a.sideslip_sigma_deg is not None:
            yb, Hb, Rb = meas.zero_sideslip(ekf, a.sideslip_sigma_deg * DEG_TO_RAD)
            y, H, R = np.concatenate([y, yb]), np.vstack([H, Hb]), np.diag([R[0, 0], Rb[0, 0]])
        info, self._last_airspeed_ok_t_s = self._fuse(ekf, "airspeed", t, y, H, R, self._last_airspeed_ok_t_s,
                                                      a.wind_reset_after_s or 0.0)
        return info

    def _fuse(self, ekf, kind: str, t: float, y, H, R, last_ok_t_s: float | None,
              reset_after_s: float) -> tuple[CorrectionInfo, float | None]:
        """Fuse through the gate; after reset_after_s (> 0; 0: never) of refusals re-acquire the
        wind from the sample (reacquire.update_or_reset with ErrorStateEKF.reset_wind, kind
        "<kind>:reset"). Returns (info, the new last-accepted time)."""
        info, ok_t_s = update_or_reset(ekf, kind, t, y, H, R, last_ok_t_s, reset_after_s, ekf.reset_wind)
        if info.kind.endswith(":reset"):
            self.wind_resets += 1
            log.info("%s: t=%.1f s: wind re-acquired from the %s after %.1f s of refused samples (NIS %.1f)",
                     self.vehicle_id, t, kind, t - last_ok_t_s, info.nis)
        return info, ok_t_s
