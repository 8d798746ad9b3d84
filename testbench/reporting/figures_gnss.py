"""GNSS sky figures: the satellites each receiver with a sky model saw, and their geometry
(event table gnss_sky, sensors/gnss_sky.py), where the record has that table."""

from __future__ import annotations

import numpy as np

from testbench.reporting.figures_common import MAX_DETAILED_VEHICLES, denied_spans, new_figure, shade_spans
from testbench.reporting.model import FigureItem
from testbench.scoring.record_io import RunRecord, column


def _sky_panels(record: RunRecord, sky, vid: str) -> FigureItem | None:
    rows = sky[sky["vehicle_id"].astype(str) == vid]
    if len(rows) == 0:
        return None
    t = column(rows, "t_s")
    fig = new_figure(9.0, 5.0)
    axes = fig.subplots(2, 1, sharex=True)
    ax = axes[0]
    shade_spans(ax, denied_spans(record, vid))
    ax.step(t, column(rows, "satellites_above_mask"), where="post", lw=0.9, color="0.5", label="above the mask")
    ax.step(t, column(rows, "satellites_visible"), where="post", lw=1.1, color="C0", label="in view")
    ax.axhline(4, color="C3", lw=0.8, ls="--", label="four: a fix at all")
    ax.set_ylabel("satellites")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="lower left")
    ax = axes[1]
    shade_spans(ax, denied_spans(record, vid))
    ax.plot(t, column(rows, "hdop_open_sky"), lw=0.9, color="0.5", label="open sky")
    ax.plot(t, column(rows, "hdop"), lw=1.1, color="C0", label="in view (where a fix)")
    ax.set_yscale("log")
    ax.set_ylabel("HDOP")
    ax.set_xlabel("time (s)")
    ax.grid(True, alpha=0.3, which="both")
    ax.legend(fontsize=7, loc="upper left")
    return FigureItem(
        f"GNSS satellites in view: {vid}",
        "Satellites above the elevation mask and those no obstacle or terrain hides; the HDOP of "
        "those in view against the open sky's (the fix's errors and claims scale by their ratio). "
        "Shaded: no GNSS fix fused.",
        fig,
    )


def gnss_sky_figures(record: RunRecord) -> list[FigureItem]:
    """Per-vehicle sky panels for the first MAX_DETAILED_VEHICLES vehicles; none without a
    gnss_sky table."""
    sky = record.event("gnss_sky")
    if sky is None:
        return []
    ids = record.vehicle_ids[:MAX_DETAILED_VEHICLES]
    return [f for f in (_sky_panels(record, sky, vid) for vid in ids) if f is not None]
