"""Navigation and control figures: trajectory over the map, error vs time, error CDFs."""

from __future__ import annotations

import math

import numpy as np
from scipy import stats as sps

from testbench.reporting.figures_common import (
    MAX_DETAILED_VEHICLES,
    SPOOFED_COLOR,
    denied_spans,
    ecdf,
    legend_or_note,
    map_preview,
    new_figure,
    shade_spans,
    spoofed_spans,
    vehicle_colors,
)
from testbench.reporting.model import FigureItem
from testbench.scoring.metrics_control import cross_track_m
from testbench.scoring.metrics_events import ismn_fix_errors
from testbench.scoring.metrics_nav import denied_mask, horizontal_sigma_max_m, position_errors_ned_m
from testbench.scoring.phases import event_turning, telemetry_turning
from testbench.scoring.record_io import RunRecord, column

# |e_h| stays inside this many sigma(max) with 99.73 % probability: the 2-D equivalent of 3 sigma.
K_2D_3SIGMA = float(np.sqrt(sps.chi2.ppf(0.9973, 2)))


def trajectory_figure(record: RunRecord) -> FigureItem:
    """Top view (east right, north up) of truth and estimate over the map preview if any."""
    fig = new_figure(8.0, 7.0)
    ax = fig.add_subplot()
    preview = map_preview(record)
    if preview is not None:
        img, (n_min, n_max, e_min, e_max) = preview
        ax.imshow(img, extent=(e_min, e_max, n_min, n_max), origin="upper", interpolation="bilinear", zorder=0)
    ids = record.vehicle_ids
    colors = vehicle_colors(ids)
    for vid in ids:
        tel = record.vehicle_telemetry(vid)
        if len(tel) == 0:
            continue
        c = colors[vid]
        te, tn = column(tel, "truth_east_m"), column(tel, "truth_north_m")
        ax.plot(te, tn, "-", color=c, lw=1.6, label=f"{vid} truth")
        ax.plot(column(tel, "nav_east_m"), column(tel, "nav_north_m"), "--", color=c, lw=1.0, alpha=0.9, label=f"{vid} estimate")
        ax.plot(te[:1], tn[:1], "o", color=c, ms=5)
        denied = ~tel["gnss_available"].to_numpy().astype(bool) if "gnss_available" in tel.columns else None
        if denied is not None and denied.any():
            ax.plot(np.where(denied, te, np.nan), np.where(denied, tn, np.nan), "-", color="black", lw=3.5, alpha=0.25, zorder=1)
    ax.plot([], [], "-", color="black", lw=3.5, alpha=0.25, label="GNSS denied (truth)")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ncol = 1 if len(ids) <= 3 else 2
    ax.legend(fontsize=7, ncol=ncol, loc="best", framealpha=0.8)
    where = "over the map preview" if preview is not None else "(no map preview in run.json)"
    return FigureItem(
        "Trajectory",
        f"Truth (solid) and navigation estimate (dashed), local NED metres, {where}; circles mark the start.",
        fig,
    )


def _error_panels(record: RunRecord, vid: str) -> FigureItem | None:
    tel = record.vehicle_telemetry(vid)
    if len(tel) == 0:
        return None
    t = column(tel, "t_s")
    e = position_errors_ned_m(tel)
    sn, se = column(tel, "nav_sigma_north_m"), column(tel, "nav_sigma_east_m")
    sigma_h = horizontal_sigma_max_m(tel)  # the worst-direction sigma
    spans, spoofed = denied_spans(record, vid), spoofed_spans(record, vid)
    eh = np.hypot(e[:, 0], e[:, 1])
    # An error that spans decades (a start from a kilometre-wide prior, then metres) is drawn on
    # log scales, else the metres after the first fix are a flat line at zero.
    log = _spans_decades(eh)
    fig = new_figure(9.0, 7.0)
    axes = fig.subplots(3, 1, sharex=True)
    for ax, err, sig, name in ((axes[0], e[:, 0], sn, "north"), (axes[1], e[:, 1], se, "east")):
        shade_spans(ax, spans)
        shade_spans(ax, spoofed, label="GNSS spoofed", color=SPOOFED_COLOR)
        ax.plot(t, err, lw=1.0, color="C0", label=f"{name} error")
        if np.isfinite(sig).any():
            ax.fill_between(t, -3 * sig, 3 * sig, color="C0", alpha=0.15, lw=0, label="±3σ (reported)")
        ax.set_ylabel(f"{name} error (m)")
        if log:
            # Linear within the decade that holds 3 median sigmas: the ticks then fall on decades.
            three_sigma = 3.0 * float(np.nanmedian(sig)) if np.isfinite(sig).any() else 1.0
            ax.set_yscale("symlog", linthresh=10.0 ** math.ceil(math.log10(max(three_sigma, 0.1))))
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="upper left")
    ax = axes[2]
    shade_spans(ax, spans)
    shade_spans(ax, spoofed, label="GNSS spoofed", color=SPOOFED_COLOR)
    ax.plot(t, eh, lw=1.0, color="C3", label="horizontal error")
    if np.isfinite(sigma_h).any():
        ax.plot(t, K_2D_3SIGMA * sigma_h, "k--", lw=1.0, label="99.73 % bound (2-D 3σ)")
    ax.set_ylabel("horizontal error (m)")
    if log:
        ax.set_yscale("log")
    ax.set_xlabel("time (s)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")
    return FigureItem(
        f"Navigation error vs time: {vid}",
        "Estimate minus truth. North and east with the navigator's ±3σ; horizontal error with the radius "
        f"that holds it with 99.73 % probability ({K_2D_3SIGMA:.2f} × the largest horizontal σ). "
        "Shaded: GNSS denied" + (" (orange) and spoofed (violet)." if spoofed else ".")
        + (" Log scales (north and east linear within the decade of 3 × the median σ): the error spans more than two decades."
           if log else ""),
        fig,
    )


def _spans_decades(err_m: np.ndarray) -> bool:
    """Whether an error series (m) spans more than two decades: its largest value above 100
    times its median (a start far off, then metres)."""
    ok = err_m[np.isfinite(err_m)]
    return ok.size > 0 and float(np.max(ok)) > 100.0 * max(float(np.median(ok)), 1e-3)


def error_time_figures(record: RunRecord) -> list[FigureItem]:
    """Per-vehicle error panels (few vehicles) or one overlay of horizontal errors (swarm)."""
    ids = record.vehicle_ids
    if len(ids) <= MAX_DETAILED_VEHICLES:
        return [f for f in (_error_panels(record, vid) for vid in ids) if f is not None]
    fig = new_figure(9.0, 4.5)
    ax = fig.add_subplot()
    colors = vehicle_colors(ids)
    shade_spans(ax, denied_spans(record, ids[0]), label=f"GNSS denied ({ids[0]})")
    for vid in ids:
        tel = record.vehicle_telemetry(vid)
        e = position_errors_ned_m(tel)
        ax.plot(column(tel, "t_s"), np.hypot(e[:, 0], e[:, 1]), lw=0.9, color=colors[vid], label=vid)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("horizontal error (m)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    return [FigureItem("Horizontal navigation error vs time", "Estimate minus truth, every vehicle; shaded: GNSS denied.", fig)]


def cdf_figure(record: RunRecord) -> FigureItem | None:
    """CDFs of horizontal error per phase: navigation (left) and scene-matching fixes (right)."""
    tel = record.telemetry
    if len(tel) == 0:
        return None
    e = position_errors_ned_m(tel)
    eh = np.hypot(e[:, 0], e[:, 1])
    turning = telemetry_turning(record)
    denied = denied_mask(record)
    ismn = record.event("ismn")
    fig = new_figure(10.0, 4.0)
    axes = fig.subplots(1, 2 if ismn is not None else 1, squeeze=False)[0]
    groups = [("all", np.ones_like(turning)), ("smooth", ~turning), ("turning", turning), ("GNSS denied", denied)]
    log = _cdf_axes(axes[0], eh, groups, "navigation horizontal error (m)")
    if ismn is not None:
        fix_eh, _ = ismn_fix_errors(ismn)
        t_ism = event_turning(record, ismn)
        log |= _cdf_axes(axes[1], fix_eh, [("all", np.ones_like(t_ism)), ("smooth", ~t_ism), ("turning", t_ism)], "scene-matching fix horizontal error (m)")
    return FigureItem(
        "Error CDFs per phase",
        "Fraction of samples with horizontal error below x. Phases from the true bank and turn rate "
        f"(turning: |bank| > {record.phases['turn_bank_deg']:g}° or |turn rate| > {record.phases['turn_rate_deg_s']:g}°/s)."
        + (" Log x where the errors span more than two decades (a start far off, fixes far off)." if log else ""),
        fig,
    )


def _cdf_axes(ax, values, groups, xlabel) -> bool:
    """Step CDFs of values (m) per group mask on ax; a log x axis when the values span more than
    two decades, where a linear one would crush the metres against the kilometres. Returns
    whether it is log."""
    log = _spans_decades(values)
    if log:
        ax.set_xscale("log")
    for (name, mask), style in zip(groups, ("-", "-", "-", ":")):
        v, p = ecdf(values[mask])
        if v.size:
            ax.step(v, p, style, where="post", label=f"{name} (n={v.size})")
    ax.axhline(0.95, color="grey", lw=0.7, ls="--")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("fraction ≤ x")
    ax.set_ylim(0, 1.02)
    ax.grid(True, alpha=0.3)
    legend_or_note(ax, "no samples", fontsize=7, loc="lower right")
    return log


def control_figure(record: RunRecord) -> FigureItem | None:
    """Altitude error and cross-track error (truth vs guidance command) against time."""
    tel = record.telemetry
    if not np.isfinite(column(tel, "gd_alt_cmd_m")).any():
        return None
    ids = record.vehicle_ids
    colors = vehicle_colors(ids)
    fig = new_figure(9.0, 5.0)
    ax_alt, ax_xt = fig.subplots(2, 1, sharex=True)
    for vid in ids:
        v = record.vehicle_telemetry(vid)
        t = column(v, "t_s")
        ax_alt.plot(t, -column(v, "truth_down_m") - column(v, "gd_alt_cmd_m"), lw=0.9, color=colors[vid], label=vid)
        on_leg = column(v, "gd_on_leg", dtype=bool).astype(bool)
        xt = cross_track_m(column(v, "truth_north_m"), column(v, "truth_east_m"), column(v, "gd_line_start_n_m"),
                           column(v, "gd_line_start_e_m"), column(v, "gd_line_end_n_m"), column(v, "gd_line_end_e_m"))
        ax_xt.plot(t, np.where(on_leg, xt, np.nan), lw=0.9, color=colors[vid])
    ax_alt.set_ylabel("altitude error (m)")
    ax_xt.set_ylabel("cross-track (m)")
    ax_xt.set_xlabel("time (s)")
    for ax in (ax_alt, ax_xt):
        ax.grid(True, alpha=0.3)
    if len(ids) > 1:
        ax_alt.legend(fontsize=7, ncol=2)
    return FigureItem(
        "Guidance tracking (truth)",
        "True altitude minus commanded altitude; signed cross-track distance of the true position from the "
        "commanded leg (positive right of track), on legs only.",
        fig,
    )
