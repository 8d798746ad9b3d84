"""Wind figures: the wind each vehicle met (truth, with its turbulence) against its navigator's
estimate of it, where the record has the wind columns (sim/recorder TELEMETRY_WIND_COLUMNS)."""

from __future__ import annotations

import numpy as np

from testbench.reporting.figures_common import MAX_DETAILED_VEHICLES, denied_spans, new_figure, shade_spans
from testbench.reporting.model import FigureItem
from testbench.scoring.record_io import RunRecord, column


def _wind_panels(record: RunRecord, vid: str) -> FigureItem | None:
    tel = record.vehicle_telemetry(vid)
    if len(tel) == 0 or "truth_wind_n_mps" not in tel.columns:
        return None
    t = column(tel, "t_s")
    estimated = np.isfinite(column(tel, "nav_wind_n_mps")).any()
    fig = new_figure(9.0, 5.0)
    axes = fig.subplots(2, 1, sharex=True)
    for ax, a, name in ((axes[0], "n", "north"), (axes[1], "e", "east")):
        shade_spans(ax, denied_spans(record, vid))
        ax.plot(t, column(tel, f"truth_wind_{a}_mps"), lw=0.8, color="k", label="truth (with turbulence)")
        if estimated:
            w, s = column(tel, f"nav_wind_{a}_mps"), column(tel, f"nav_sigma_wind_{a}_mps")
            ax.plot(t, w, lw=1.0, color="C0", label="estimate")
            ax.fill_between(t, w - 3 * s, w + 3 * s, color="C0", alpha=0.15, lw=0, label="±3σ (reported)")
        ax.set_ylabel(f"wind {name} (m/s)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="upper left")
    axes[1].set_xlabel("time (s)")
    return FigureItem(
        f"Wind vs time: {vid}",
        "The air's velocity over the ground at the vehicle (north, east)"
        + (", and the navigator's estimate with its ±3σ." if estimated else "; its navigator estimates none.")
        + " Shaded: GNSS denied.",
        fig,
    )


def wind_figures(record: RunRecord) -> list[FigureItem]:
    """Per-vehicle wind panels for the first MAX_DETAILED_VEHICLES vehicles; none without wind
    columns."""
    ids = record.vehicle_ids[:MAX_DETAILED_VEHICLES]
    return [f for f in (_wind_panels(record, vid) for vid in ids) if f is not None]
