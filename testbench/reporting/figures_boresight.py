"""Boresight figures: a navigator's estimate of its scene-matching camera's boresight against
the camera's true one (run.json camera_boresight_error_deg), per body axis with the ±3σ it
claims, where the record has the boresight columns (sim/recorder) and an estimate."""

from __future__ import annotations

import numpy as np

from testbench.reporting.figures_common import MAX_DETAILED_VEHICLES, denied_spans, new_figure, shade_spans
from testbench.reporting.model import FigureItem
from testbench.scoring.metrics_nav import boresight_errors_rad
from testbench.scoring.record_io import RunRecord, column


def _boresight_panels(record: RunRecord, vid: str, err_deg: np.ndarray, sig_deg: np.ndarray) -> FigureItem | None:
    """err_deg, sig_deg (n, 3): this vehicle's rows of the estimate's error and claimed sigma
    (deg, a rotation vector in body axes)."""
    if not np.isfinite(err_deg).all(axis=1).any():
        return None
    t = column(record.vehicle_telemetry(vid), "t_s")
    camera = (record.run_info.get("camera_boresight_estimated") or {}).get(vid, "camera")
    fig = new_figure(9.0, 6.5)
    axes = fig.subplots(3, 1, sharex=True)
    denied = denied_spans(record, vid)
    for k, (ax, name) in enumerate(zip(axes, ("x (roll)", "y (pitch)", "z (yaw)"))):
        shade_spans(ax, denied)
        e, s = err_deg[:, k], sig_deg[:, k]
        ax.plot(t, e, lw=1.0, color="C0", label="estimate − truth")
        ax.fill_between(t, -3 * s, 3 * s, color="C0", alpha=0.15, lw=0, label="±3σ (reported)")
        ax.axhline(0.0, color="k", lw=0.5)
        # The first fixes move the estimate by the whole boresight; the scale follows what it
        # settles to (the last 80 % of the estimated rows) so that the band stays readable.
        rows = np.flatnonzero(np.isfinite(e))
        late = rows[len(rows) // 5:]
        span = max(float(np.max(np.abs(e[late]))), float(np.max(3 * s[late])), 1e-3) if len(late) else 1.0
        ax.set_ylim(-1.5 * span, 1.5 * span)
        ax.set_ylabel(f"about body {name} (deg)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
    axes[2].set_xlabel("time (s)")
    return FigureItem(
        f"Camera boresight vs time: {vid}",
        f"The navigator's estimate of the {camera} camera's boresight (the rotation from its calibrated to its true "
        "mounting, body axes) minus the true one, with the ±3σ it claims; the scale follows the settled estimate, "
        "so the first fixes' large moves may leave it. Shaded: GNSS denied.",
        fig,
    )


def boresight_figures(record: RunRecord) -> list[FigureItem]:
    """Per-vehicle boresight panels for the first MAX_DETAILED_VEHICLES vehicles whose navigator
    estimates a camera boresight; none without such an estimate."""
    errors = boresight_errors_rad(record)
    if errors is None:
        return []
    err_deg, sig_deg = np.degrees(errors[0]), np.degrees(errors[1])
    vehicles = record.telemetry["vehicle_id"].astype(str).to_numpy()
    figs = []
    for vid in record.vehicle_ids[:MAX_DETAILED_VEHICLES]:
        rows = vehicles == vid
        fig = _boresight_panels(record, vid, err_deg[rows], sig_deg[rows])
        if fig is not None:
            figs.append(fig)
    return figs
