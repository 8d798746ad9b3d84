"""Camera-state figures: a navigator's estimates of its scene-matching camera's calibration
against the camera's truth, each component with the ±3σ it claims, where the record has the
columns (sim/recorder) and an estimate: the boresight (run.json camera_boresight_error_deg,
per body axis), the time offset (camera_time_offset_s) and the intrinsics
(camera_intrinsics_error: principal point u, v and focal length)."""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from testbench.reporting.figures_common import MAX_DETAILED_VEHICLES, denied_spans, new_figure, shade_spans
from testbench.reporting.model import FigureItem
from testbench.scoring.metrics_nav import boresight_errors_rad, intrinsics_errors, time_offset_errors_s
from testbench.scoring.record_io import RunRecord, column


def _error_panels(record: RunRecord, vid: str, err: np.ndarray, sig: np.ndarray, labels: Sequence[str],
                  title: str, caption: str) -> FigureItem | None:
    """One panel per component of this vehicle's rows of an estimate's error err (n, k) and its
    claimed sigma sig (n, k), in the units the labels (k,) name; None without an estimate."""
    if not np.isfinite(err).all(axis=1).any():
        return None
    t = column(record.vehicle_telemetry(vid), "t_s")
    k = err.shape[1]
    fig = new_figure(9.0, 1.2 + 1.8 * k)
    axes = np.atleast_1d(fig.subplots(k, 1, sharex=True))
    denied = denied_spans(record, vid)
    for i, (ax, label) in enumerate(zip(axes, labels)):
        shade_spans(ax, denied)
        e, s = err[:, i], sig[:, i]
        ax.plot(t, e, lw=1.0, color="C0", label="estimate − truth")
        ax.fill_between(t, -3 * s, 3 * s, color="C0", alpha=0.15, lw=0, label="±3σ (reported)")
        ax.axhline(0.0, color="k", lw=0.5)
        # The first fixes move the estimate by the whole error; the scale follows what it
        # settles to (the last 80 % of the estimated rows) so that the band stays readable.
        rows = np.flatnonzero(np.isfinite(e))
        late = rows[len(rows) // 5:]
        span = max(float(np.max(np.abs(e[late]))), float(np.max(3 * s[late])), 1e-9) if len(late) else 1.0
        ax.set_ylim(-1.5 * span, 1.5 * span)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
    axes[-1].set_xlabel("time (s)")
    return FigureItem(f"{title}: {vid}", caption + " The scale follows the settled estimate, so the first fixes' "
                      "large moves may leave it. Shaded: GNSS denied.", fig)


def _per_vehicle(record: RunRecord, errors, scale: Sequence[float], make: Callable) -> list[FigureItem]:
    """make(vid, err (n, k), sig (n, k)) for the first MAX_DETAILED_VEHICLES vehicles, the errors
    (err, sig) scaled per component by scale (k,); none without errors."""
    if errors is None:
        return []
    err, sig = (np.asarray(x, float).reshape(len(x), -1) * np.asarray(scale, float) for x in errors)
    vehicles = record.telemetry["vehicle_id"].astype(str).to_numpy()
    figs = [make(vid, err[vehicles == vid], sig[vehicles == vid]) for vid in record.vehicle_ids[:MAX_DETAILED_VEHICLES]]
    return [f for f in figs if f is not None]


def boresight_figures(record: RunRecord) -> list[FigureItem]:
    """Per-vehicle boresight panels (deg, body axes) of the navigators that estimate one."""
    def make(vid, err, sig):
        camera = (record.run_info.get("camera_boresight_estimated") or {}).get(vid, "camera")
        return _error_panels(record, vid, err, sig, [f"about body {a} (deg)" for a in ("x (roll)", "y (pitch)", "z (yaw)")],
                             "Camera boresight vs time",
                             f"The navigator's estimate of the {camera} camera's boresight (the rotation from its "
                             "calibrated to its true mounting, body axes) minus the true one, with the ±3σ it claims.")

    return _per_vehicle(record, boresight_errors_rad(record), np.degrees(np.ones(3)), make)


def time_offset_figures(record: RunRecord) -> list[FigureItem]:
    """Per-vehicle time offset panels (ms) of the navigators that estimate one."""
    def make(vid, err, sig):
        camera = (record.run_info.get("camera_time_offset_estimated") or {}).get(vid, "camera")
        return _error_panels(record, vid, err, sig, ["time offset (ms)"], "Camera time offset vs time",
                             f"The navigator's estimate of the {camera} camera's time offset (its frames' stamp minus "
                             "their exposure) minus the true one, with the ±3σ it claims.")

    return _per_vehicle(record, time_offset_errors_s(record), [1e3], make)


def intrinsics_figures(record: RunRecord) -> list[FigureItem]:
    """Per-vehicle intrinsics panels (principal point px, focal length ppm) of the navigators
    that estimate them."""
    def make(vid, err, sig):
        camera = (record.run_info.get("camera_intrinsics_estimated") or {}).get(vid, "camera")
        return _error_panels(record, vid, err, sig, ["principal point u (px)", "principal point v (px)",
                                                     "focal length (ppm)"], "Camera intrinsics vs time",
                             f"The navigator's estimate of the {camera} camera's intrinsics error (its true principal "
                             "point minus the calibrated one; its focal length's relative error) minus the true one, "
                             "with the ±3σ it claims.")

    return _per_vehicle(record, intrinsics_errors(record), [1.0, 1.0, 1e6], make)
