"""Terrain-aided navigation figure: each window's fix against truth with what it claimed, and
the terrain it ranged (event table tan, navigation/tan_aid.py), where the record has that table."""

from __future__ import annotations

import numpy as np

from testbench.reporting.figures_common import denied_spans, new_figure, shade_spans
from testbench.reporting.model import FigureItem
from testbench.scoring.metrics_events import fix_errors_ne_m
from testbench.scoring.metrics_tan import tan_window_errors_ne_m
from testbench.scoring.record_io import RunRecord, column


def tan_fix_figure(record: RunRecord) -> FigureItem | None:
    """Horizontal error of each window (the match's own, the fix less its velocity lag term, and
    as the fix the navigator got) against its claimed 1-sigma and 3-sigma, and each window's
    terrain roughness with the reason of the windows that gave no fix."""
    tan = record.event("tan")
    if tan is None or len(tan) == 0:
        return None
    t = column(tan, "t_s")
    fix = column(tan, "fix", dtype=bool).astype(bool)
    e_fix = np.hypot(*fix_errors_ne_m(tan).T)
    e_win = np.hypot(*tan_window_errors_ne_m(record, tan).T)
    sigma = np.hypot(column(tan, "sigma_north_m"), column(tan, "sigma_east_m"))  # the claim's radial RMS
    fig = new_figure(11.0, 4.0)
    ax, axr = fig.subplots(1, 2, width_ratios=[2, 1])
    vid = str(tan["vehicle_id"].iloc[0]) if "vehicle_id" in tan.columns else None
    for a in (ax, axr):
        shade_spans(a, denied_spans(record, vid) if vid is not None else [])
    ax.plot(t[fix], e_win[fix], "o", ms=4, color="C0", label="window (the fix less its velocity lag)")
    ax.plot(t[fix], e_fix[fix], "x", ms=4, color="C1", label="fix as fused (at the window's end)")
    ax.plot(t[fix], sigma[fix], "-", lw=0.9, color="0.4", label="claimed (radial 1 sigma)")
    ax.plot(t[fix], 3.0 * sigma[fix], "--", lw=0.9, color="0.4", label="claimed x 3")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("horizontal error (m)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    rough = column(tan, "roughness_m")
    axr.plot(t[fix], rough[fix], "o", ms=3.5, color="C2", label="fix")
    reasons = tan["reason"].astype(str).to_numpy()
    for i, why in enumerate(sorted(set(reasons[~fix]))):
        sel = ~fix & (reasons == why)
        axr.plot(t[sel], rough[sel], "x", ms=5, color=f"C{3 + i}", label=f"no fix: {why} ({int(sel.sum())})")
    axr.set_xlabel("time (s)")
    axr.set_ylabel("terrain profile SD, noise removed (m)")
    axr.grid(True, alpha=0.3)
    axr.legend(fontsize=7)
    return FigureItem(
        "Terrain-aided navigation fixes",
        "Left: each radar-altimeter window's horizontal error against truth: the point-mass filter's own "
        "(the fix less the velocity lag the navigator models, taken with the window's mean velocity error) "
        "and the fix as fused at the window's end, with the fix's claim. Right: the "
        "standard deviation of the terrain profile each window ranged (less the altimeter noise), and why windows gave no fix. "
        "Shaded: GNSS denied.",
        fig,
    )
