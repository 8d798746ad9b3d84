"""How the INS/EKF navigator fuses a position fix (scene matching, terrain-aided navigation):
the fix's white part against the shared fix error states, its coupling to the filter's
attitude, the appearance states, the camera's boresight, time offset and intrinsics
states, the image-only heading, and the gate with its reset after a run of refusals.

`PositionFixFusion` is a part of InsEkfNavigator (navigator.py), kept apart so that the
navigator reads as the dispatch of its measurements; it uses the navigator's `params`, `ekf`,
`ctx`, `fix_error_sigma_ned_m`, `_fix_refusals`, `_last_fix_ok_t_s`, `_last_gnss_ok_t_s` and
`_update_or_reset`.
"""

from __future__ import annotations

import numpy as np

from testbench.core.messages import CorrectionInfo, PositionFix
from testbench.core.units import DEG_TO_RAD
from testbench.navigation.fix_quality import appearance_gain
from testbench.navigation.ins import measurements as meas


class PositionFixFusion:
    """The position-fix half of InsEkfNavigator (see the module docstring)."""

    def appearance_gain(self, quality: float) -> float:
        """g(q) (dimensionless) of a fix of quality q on the appearance states
        (InsEkfParams.fix_appearance_sigma_m); 0 without them."""
        p = self.params
        if self.ekf.i_app is None:
            return 0.0
        return appearance_gain(quality, p.fix_appearance_ref_quality, p.fix_appearance_exponent, p.fix_appearance_max_gain)

    def fuse_fix_now(self, measurement: PositionFix):
        """A position fix fused at the filter's present time (a fix of now, or one the delayed
        fixes' handling has made one: delayed.py); its CorrectionInfo, or (position, heading)."""
        p, ekf = self.params, self.ekf
        t = float(measurement.t_s)
        if (ekf.i_cam is not None and measurement.image_pose_cov is not None
                and self._boresight_needs_image_pose()):
            return self._correct_image_pose(measurement, t)
        # A fix that declares how it leaned on our attitude is fused with that coupling
        # (H_phi = -M) and its covariance given the attitude; otherwise as independent.
        M = measurement.att_sensitivity_m_per_rad if p.fix_attitude_coupling else None
        base = measurement.cov_ned_m2 if M is None else measurement.cov_given_att_ned_m2
        white = self._white_fix_cov(base)
        offset = None if ekf.i_td is None or measurement.source != "ismn" else meas.TimeOffsetTerms.of(ekf, self.ctx.origin)
        pos, lag = measurement.pos_ned_m, measurement.vel_lag_s
        if offset is not None:
            pos, lag = offset.carried(pos, lag)
        y, H, R = meas.position_ned(ekf, pos, white, self.ctx.origin, M,
                                    appearance_gain=self.appearance_gain(measurement.quality), vel_lag_s=lag,
                                    from_map=measurement.source == "ismn")
        if offset is not None:
            H[:, ekf.i_td] = offset.position_column(M)
        if ekf.i_ci is not None and measurement.intrinsics_sensitivity is not None:
            # The fix was solved with the intrinsics corrected by the estimate (IsmnPipeline
            # _solve_K): what is left of their error moves it by S (error - estimate).
            H[:, ekf.i_ci] = measurement.intrinsics_sensitivity
        info = self._fuse_fix(f"position_fix:{measurement.source}", t, y, H, R)
        if p.use_fix_heading and measurement.heading_rad is not None and info is not None and info.accepted:
            # The image-only heading of the same solve: nearly uncorrelated with its centre in
            # a nadir view (a rotation about the vertical through the centre moves no point
            # near it), so fused as a measurement of its own after the position; only from a
            # fix the gate let through (a false match's heading is as false as its position).
            heading_rad = measurement.heading_rad if offset is None else offset.carried_heading(measurement.heading_rad)
            yh, Hh, Rh = meas.fix_heading(ekf, heading_rad, measurement.heading_sigma_rad)
            if offset is not None:
                Hh[0, ekf.i_td] = -offset.heading_rate_rps
            heading = ekf.update(f"heading_fix:{measurement.source}", t, yh, Hh, Rh)
            return info, heading
        return info

    def _white_fix_cov(self, cov_ned_m2, bound_ned_m2=None) -> np.ndarray:
        """(3, 3) the white part of a position fix's covariance (NED m^2), scaled by
        meas_sigma.position_fix_scale: the shared part is in the b_fix states. A fix claiming
        less than the shared error keeps 1 % of the smallest eigenvalue of bound_ned_m2 (its
        covariance given what else the same measurement holds; default the covariance itself)
        as white noise (never an exact measurement)."""
        scale2 = self.params.meas_sigma.position_fix_scale**2
        cov = np.asarray(cov_ned_m2, float) * scale2
        bound = cov if bound_ned_m2 is None else np.asarray(bound_ned_m2, float) * scale2
        lam_min = float(np.linalg.eigvalsh(0.5 * (bound + bound.T)).min())
        # (A diagonal below 0.99 lam_min I keeps the remainder positive definite.)
        return cov - np.diag(np.minimum(self.fix_error_sigma_ned_m**2, 0.99 * lam_min))

    def _fuse_fix(self, kind: str, t: float, y, H, R, reset=None) -> CorrectionInfo:
        """A position fix's measurement through the gate, or the position reset to it after
        fix_reset_after_s of refusals (Params.fix_reset_*)."""
        p = self.params
        # Short of fix_reset_min_refusals refusals in a row the reset is held off.
        may_reset = self._fix_refusals + 1 >= p.fix_reset_min_refusals
        info, self._last_fix_ok_t_s = self._update_or_reset(
            kind, t, y, H, R, self._last_fix_ok_t_s, self._last_gnss_ok_t_s, p.fix_reset_after_s if may_reset else 0.0,
            reset)
        self._fix_refusals = 0 if info.accepted else self._fix_refusals + 1
        return info

    def _boresight_needs_image_pose(self) -> bool:
        """Whether a fix's image-only pose is fused rather than its MAP position: while the
        boresight's largest 1-sigma is above camera_boresight.handover_sigma_deg (always
        without one). The states have no process noise: their covariance only shrinks."""
        h = self.params.camera_boresight.handover_sigma_deg
        if h is None:
            return True
        P_b = self.ekf.P[self.ekf.i_cam, self.ekf.i_cam]
        return float(np.sqrt(np.linalg.eigvalsh(0.5 * (P_b + P_b.T)).max())) > h * DEG_TO_RAD

    def _correct_image_pose(self, fix: PositionFix, t: float) -> CorrectionInfo:
        """A fix's image-only pose (position and attitude, one 6-dof measurement) with the
        camera's boresight states (Params.camera_boresight; measurements.image_pose); its
        position block's white part as a fix's. A reset re-acquires the position alone."""
        cov = np.array(fix.image_pose_cov, float)
        scale = self.params.meas_sigma.position_fix_scale
        # The position's covariance given the attitude bounds what may go to b_fix: taking no
        # more than that keeps the 6 x 6 positive definite.
        given_att = cov[:3, :3] - cov[:3, 3:] @ np.linalg.solve(cov[3:, 3:], cov[3:, :3])
        cov[:3, 3:] *= scale
        cov[3:, :3] *= scale
        cov[:3, :3] = self._white_fix_cov(cov[:3, :3], given_att)
        y, H, R = meas.image_pose(self.ekf, fix.image_pos_ned_m, fix.image_R_nb, cov, self.ctx.origin,
                                  appearance_gain=self.appearance_gain(fix.quality), from_map=fix.source == "ismn")

        def reset_position(kind, t_s, y, H, R, elapsed_s):
            return self.ekf.reset_position(kind, t_s, y[:3], H[:3], R[:3, :3], elapsed_s)

        return self._fuse_fix(f"image_pose:{fix.source}", t, y, H, R, reset_position)
