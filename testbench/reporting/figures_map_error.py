"""The reference map's georeference error in a run's report, where the carried map was off
(world.reference_map_error): per vehicle, north and east, the map's displacement over each
fix's footprint (truth_map_error_*), the fix's own error, and, where the navigator estimates
the map's error (navigation.params.map_error), its estimate with the ±3σ it claims."""

from __future__ import annotations

import numpy as np

from testbench.reporting.figures_common import MAX_DETAILED_VEHICLES, denied_spans, new_figure, shade_spans
from testbench.reporting.model import FigureItem
from testbench.scoring.record_io import RunRecord, column, has_columns


def map_error_figures(record: RunRecord) -> list[FigureItem]:
    """One figure per vehicle (the first MAX_DETAILED_VEHICLES) whose scene-matching rows hold the
    map's displacement; none where the map was placed exactly."""
    ismn = record.event("ismn")
    if ismn is None or not has_columns(ismn, "truth_map_error_north_m"):
        return []
    figs = []
    for vid in record.vehicle_ids[:MAX_DETAILED_VEHICLES]:
        rows = ismn[(ismn["vehicle_id"].astype(str) == vid) & ismn["fix"].astype(bool)]
        if len(rows):
            figs.append(_vehicle_figure(record, vid, rows))
    return figs


def _vehicle_figure(record: RunRecord, vid: str, rows) -> FigureItem:
    t_fix = column(rows, "t_s")
    truth_cols = ("truth_exposure_north_m", "truth_exposure_east_m") if "truth_exposure_north_m" in rows.columns \
        else ("truth_north_m", "truth_east_m")
    tel = record.vehicle_telemetry(vid)
    estimated = has_columns(tel, "nav_map_error_n_m")
    fig = new_figure(9.0, 5.0)
    axes = fig.subplots(2, 1, sharex=True)
    denied = denied_spans(record, vid)
    for ax, axis, fix_col, truth_col, k in zip(axes, ("north", "east"), ("fix_north_m", "fix_east_m"), truth_cols, "ne"):
        shade_spans(ax, denied)
        ax.plot(t_fix, column(rows, fix_col) - column(rows, truth_col), ".", ms=3, color="0.55", label="fix − truth")
        ax.plot(t_fix, column(rows, f"truth_map_error_{axis}_m"), ".", ms=4, color="C3",
                label="the map's displacement over the footprint (truth)")
        if estimated:
            t = column(tel, "t_s")
            est, sig = column(tel, f"nav_map_error_{k}_m"), column(tel, f"nav_sigma_map_error_{k}_m")
            ax.plot(t, est, lw=1.0, color="C0", label="navigator's estimate")
            ax.fill_between(t, est - 3 * sig, est + 3 * sig, color="C0", alpha=0.15, lw=0, label="±3σ (reported)")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_ylabel(f"{axis} (m)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
    axes[-1].set_xlabel("time (s)")
    caption = ("Where the reference map shows the ground, minus where it is (the world's displacement field averaged "
               "over each fix's predicted footprint), beside each fix's error: a fix from a misplaced map errs with it, "
               "and no fix can tell the two apart.")
    if estimated:
        caption += " The navigator's map-error states, learnt while GNSS lasted, with the ±3σ they claim."
    return FigureItem(f"Reference map error vs time: {vid}", caption + " Shaded: GNSS denied.", fig)
