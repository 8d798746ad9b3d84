"""Optical-flow velocity aiding of one navigator (flow_settings.OpticalFlowAiding): what the filter
needs beside a flow sample to fuse it, and the fusion.

A flow sample (core.messages.OpticalFlowSample) is the ground's move in the flow camera's image
over an interval, its rotation and its translation together. The navigator keeps

- its own rotation over that interval: the bias-corrected gyro rates of the IMU samples
  since, integrated (`accumulate`, after each INS propagation), less the Earth's rate, which
  turns the ground too;
- the distance to the ground: the latest range of a downward pencil-beam rangefinder
  (`take_range`), turned into the depth along the camera's axis with the filter's attitude
  (flat ground between the two footprints);

and fuses what is left of the flow, over the interval, as the camera's velocity over the
ground (measurements.optical_flow), through the gate like any other measurement.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from testbench.core import geodesy
from testbench.core.messages import CorrectionInfo, OpticalFlowSample, RadarAltSample
from testbench.navigation.ins import measurements as meas
from testbench.navigation.ins.ekf import chi2_threshold
from testbench.navigation.ins.flow_settings import OpticalFlowAiding

# How long the gyro history is kept (s): a flow interval is a frame or two (0.05-0.1 s).
_HISTORY_S = 2.0
# A camera axis more than 60 deg off the vertical sees ground too far off its centre's depth.
_MIN_AXIS_DOWN = 0.5


class FlowVelocityAiding:
    """The flow fusion's bookkeeping: per IMU sample its time, interval and bias-corrected
    delta angle (body, rad), and the latest usable range (t_s, m)."""

    def __init__(self, settings: OpticalFlowAiding):
        self.settings = settings
        self._dangles: deque[tuple[float, float, np.ndarray]] = deque()
        self._range: tuple[float, float] | None = None
        self.skipped = 0
        """Flow samples not fused: no range, too little texture, the IMU history short of the
        interval, the camera too oblique or too close to the ground."""
        window = settings.holdout.window if settings.holdout is not None else 1
        self._verdicts: deque[bool] = deque(maxlen=window)
        """The gate's verdicts on the last samples (settings.holdout)."""
        self._held_until_s = -math.inf

    def accumulate(self, ekf, t_prev_s: float) -> None:
        """Keep the IMU sample just propagated (ekf.t_s, since t_prev_s): its bias-corrected
        rate times its interval."""
        t = float(ekf.t_s)
        dt = t - float(t_prev_s)
        if dt <= 0.0:
            return
        self._dangles.append((t, dt, np.asarray(ekf.omega_ib_b_rps, float) * dt))
        while self._dangles and self._dangles[0][0] < t - _HISTORY_S:
            self._dangles.popleft()

    def take_range(self, m: RadarAltSample) -> None:
        """Keep a rangefinder's range if its beam is narrow enough to range along its axis."""
        if m.beam_half_angle_rad <= math.radians(self.settings.max_beam_half_angle_deg) and math.isfinite(m.range_m):
            self._range = (float(m.t_s), float(m.range_m))

    def _rotation_b_rad(self, t0_s: float, t1_s: float) -> np.ndarray | None:
        """The body's rotation over (t0, t1] from the kept IMU samples (rad, body axes; the
        increments are small, so they add), or None where the history does not cover it."""
        # Found newest first (an interval is the last few samples of two seconds of history),
        # summed oldest first.
        inside = []
        for t, dt, da in reversed(self._dangles):
            if t <= t0_s + 1e-9:
                break
            if t <= t1_s + 1e-9:
                inside.append((dt, da))
        total = np.zeros(3)
        covered = 0.0
        for dt, da in reversed(inside):
            total += da
            covered += dt
        return total if abs(covered - (t1_s - t0_s)) <= 1e-6 else None

    def correct(self, ekf, m: OpticalFlowSample) -> CorrectionInfo | None:
        """Fuse one flow sample ("optical_flow"); None where it cannot be (counted in skipped)."""
        s = self.settings
        t = float(m.t_s)
        rot_b = self._rotation_b_rad(t - float(m.dt_s), t)
        if (m.texture_dn2 < s.min_texture_dn2 or rot_b is None or self._range is None
                or t - self._range[0] > s.max_range_age_s or not m.dt_s > 0.0):
            self.skipped += 1
            return None
        C = ekf.C_nb
        # The Earth turns the ground under the camera too: the rotation that moves the image
        # is the body's relative to the Earth (omega_ib - C^T omega_ie; 7e-5 rad/s).
        rot_b = rot_b - C.T @ geodesy.earth_rate_ned_rps(ekf.ins.lat_rad) * float(m.dt_s)
        R_bc = np.asarray(m.R_bc, float)
        # The pencil beam ranges along body z: the height is its down part (flat ground;
        # measurements.optical_flow scales the flow by it and by the camera's axis).
        height_m = self._range[1] * float(C[2, 2])
        axis_down = float((C @ R_bc[:, 2])[2])
        if axis_down < _MIN_AXIS_DOWN or height_m < s.min_depth_m:
            self.skipped += 1
            return None
        # The camera's rotation as the sensor's fit reads it (rotation_c: at the image centre
        # (-a_y, +a_x), over the whole frame a little more): taken out, the rest is the
        # translation's flow. What the first-order reading leaves is a share of it
        # (rotation_sigma_fraction).
        rot_flow = np.asarray(m.rotation_c, float) @ (R_bc.T @ rot_b)
        flow_t = np.asarray(m.flow_c_rad, float) - rot_flow
        dt = float(m.dt_s)
        rot_sigma = s.rotation_sigma_fraction * float(np.linalg.norm(rot_flow)) / dt
        cov = (np.asarray(m.cov_c_rad2, float) * (s.sigma_scale / dt) ** 2
               + np.eye(2) * (s.sigma_floor_rad_s**2 + rot_sigma**2))
        # How fast the view passes over the ground: the flow's slow error decorrelates with it.
        ekf.flow_view_rate_rps = float(np.hypot(flow_t[0], flow_t[1])) / dt
        moments = m.moments_c if s.perspective else None
        y, H, R = meas.optical_flow(ekf, flow_t / dt, R_bc, self._range[1], cov, m.lever_arm_b_m,
                                    s.depth_sigma_fraction, moments)
        if s.holdout is None:
            return ekf.update("optical_flow", t, y, H, R)
        return self._fuse_or_hold(ekf, t, y, H, R)

    def _fuse_or_hold(self, ekf, t: float, y, H, R) -> CorrectionInfo:
        """Fuse through the gate, or only check while the flow is held out (settings.holdout);
        either way the gate's verdict enters the window that decides the next hold."""
        h = self.settings.holdout
        if t < self._held_until_s:
            info = ekf.check("optical_flow:held", t, y, H, R)
            passed = bool(np.isfinite(info.nis)) and info.nis <= chi2_threshold(ekf.gate_probability, y.size)
        else:
            info = ekf.update("optical_flow", t, y, H, R)
            passed = info.accepted
        self._verdicts.append(passed)
        if len(self._verdicts) >= h.window and self._verdicts.count(False) >= h.max_refused:
            self._held_until_s = max(self._held_until_s, t + h.hold_s)
        return info
