"""Event figures: scene-matching examples and latency, relative navigation, formation, NIS."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pandas as pd

from testbench.reporting.figures_common import (
    SPOOFED_COLOR,
    denied_spans,
    legend_or_note,
    new_figure,
    shade_spans,
    spoofed_spans,
    vehicle_colors,
)
from testbench.reporting.model import FigureItem
from testbench.scoring.metrics_events import ismn_fix_errors, pair_key, relnav_errors_m
from testbench.scoring.phases import event_turning
from testbench.scoring.record_io import RunRecord, column
from testbench.scoring.stats import chi2_bounds

log = logging.getLogger(__name__)

MAX_ISMN_EXAMPLES = 4
MAX_PAIR_LINES = 12


def _show(ax, img, title: str) -> None:
    a = np.asarray(img)
    if a.ndim == 3 and a.shape[2] == 1:
        a = a[:, :, 0]
    ax.imshow(a, cmap="gray" if a.ndim == 2 else None, interpolation="nearest")
    ax.set_title(title, fontsize=8)
    ax.set_xticks([])
    ax.set_yticks([])


def ismn_example_figures(record: RunRecord) -> list[FigureItem]:
    """Camera frame, orthorectified frame and matched map window of saved examples."""
    if record.run_dir is None:
        return []
    files = sorted(Path(record.run_dir, "ismn_examples").glob("*.npz"))[:MAX_ISMN_EXAMPLES]
    out = []
    for f in files:
        try:
            with np.load(f, allow_pickle=False) as z:
                panels = [(k, z[k]) for k in ("camera", "ortho", "map_window") if k in z.files]
                t = float(z["t_s"]) if "t_s" in z.files else float("nan")
                vid = str(z["vehicle_id"]) if "vehicle_id" in z.files else "?"
        except (OSError, ValueError) as exc:
            log.warning("ISMN example %s not shown: %s", f, exc)
            continue
        if not panels:
            continue
        fig = new_figure(3.2 * len(panels), 3.2)
        axes = fig.subplots(1, len(panels), squeeze=False)[0]
        names = {"camera": "camera frame", "ortho": "orthorectified frame", "map_window": "matched map window"}
        for ax, (k, img) in zip(axes, panels):
            _show(ax, img, f"{names[k]} {np.asarray(img).shape[1]}×{np.asarray(img).shape[0]}")
        out.append(FigureItem(f"Scene-matching example: {vid}, t = {t:.1f} s", f"From {f.name}.", fig))
    return out


def _no_fix_note(ismn: pd.DataFrame) -> str:
    """What an empty fix panel says: no fix, and the commonest reason the attempts gave."""
    reasons = ismn["reason"].astype(str) if "reason" in ismn.columns else pd.Series(dtype=str)
    reasons = reasons[(reasons != "") & (reasons != "None") & (reasons != "nan")]
    if reasons.empty:
        return "no scene-matching fix"
    top = reasons.value_counts()
    return f"no scene-matching fix: {top.index[0]} ({int(top.iloc[0])} of {len(ismn)} attempts)"


def ismn_fix_figure(record: RunRecord) -> FigureItem | None:
    """Fix error vs time (smooth / turning, accepted / rejected) and the latency histogram."""
    ismn = record.event("ismn")
    if ismn is None:
        return None
    eh, _ = ismn_fix_errors(ismn)
    turning = event_turning(record, ismn)
    accepted = column(ismn, "accepted", dtype=bool).astype(bool)
    t = column(ismn, "t_s")
    lat = column(ismn, "latency_ms")
    fig = new_figure(11.0, 4.0)
    ax, axh = fig.subplots(1, 2, width_ratios=[2, 1])
    for mask, color, name in ((~turning, "C0", "smooth"), (turning, "C3", "turning")):
        for acc, marker in ((True, "o"), (False, "x")):
            sel = mask & (accepted == acc) & np.isfinite(eh)
            if sel.any():
                ax.plot(t[sel], eh[sel], marker, color=color, ms=3.5, ls="none",
                        label=f"{name}, {'accepted' if acc else 'rejected'} (n={int(sel.sum())})")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("fix horizontal error (m)")
    ax.grid(True, alpha=0.3)
    legend_or_note(ax, _no_fix_note(ismn), fontsize=7)
    clouds_note = _cloud_share_axis(ax, ismn)
    v = lat[np.isfinite(lat)]
    if v.size:
        axh.hist(v, bins=min(40, max(5, v.size // 5)), color="C2", alpha=0.8)
        axh.axvline(np.mean(v), color="k", lw=1, label=f"mean {np.mean(v):.1f} ms")
        axh.axvline(np.percentile(v, 95), color="k", ls="--", lw=1, label=f"p95 {np.percentile(v, 95):.1f} ms")
        axh.legend(fontsize=7)
    axh.set_xlabel("matching latency (ms)")
    axh.set_ylabel("attempts")
    return FigureItem(
        "Scene-matching fixes and latency",
        "Left: horizontal error of each produced fix against truth (o accepted by the filter, x rejected)."
        f"{clouds_note} Right: histogram of the matching latency per attempt.",
        fig,
    )


def _cloud_share_axis(ax, ismn: pd.DataFrame) -> str:
    """Each frame's truth cloud share on a right-hand axis of ax, where the world has clouds,
    and the share in their shadows where they cast any; the caption's words for what it drew
    ("" for nothing)."""
    if "truth_cloud_fraction" not in ismn.columns:
        return ""
    share = column(ismn, "truth_cloud_fraction")
    if not np.any(share > 0.0):
        return ""
    t = column(ismn, "t_s")
    axc = ax.twinx()
    axc.fill_between(t, 100.0 * share, step="mid", color="0.6", alpha=0.3, lw=0)
    shade = column(ismn, "truth_shadow_fraction") if "truth_shadow_fraction" in ismn.columns else None
    drew_shadows = shade is not None and bool(np.any(shade > 0.0))
    if drew_shadows:
        axc.step(t, 100.0 * shade, where="mid", color="0.25", lw=0.8, alpha=0.7)
    axc.set_ylim(0.0, 100.0)
    axc.set_ylabel("ground hidden by cloud / in shadow (%)" if drew_shadows else "ground hidden by cloud (%)",
                   color="0.4")
    ax.set_zorder(axc.get_zorder() + 1)  # the fixes over the grey, not under it
    ax.patch.set_visible(False)
    note = " Grey: the share of the ground in the camera's view that clouds hide (truth), right axis."
    return note + (" Dark line: the share that shows in the clouds' shadows (truth)." if drew_shadows else "")


def relnav_figure(record: RunRecord) -> FigureItem | None:
    """Relative-navigation error vs time per observer -> peer pair, and RMS per pair."""
    rel = record.event("relnav")
    if rel is None:
        return None
    err = relnav_errors_m(rel)
    t = column(rel, "t_s")
    obs = rel["vehicle_id"].astype(str).to_numpy()
    peer = rel["peer_id"].astype(str).to_numpy()
    pairs = sorted(set(zip(obs, peer)))
    fig = new_figure(11.0, 4.5)
    ax, axb = fig.subplots(1, 2, width_ratios=[2, 1])
    rms = []
    for i, (a, b) in enumerate(pairs):
        sel = (obs == a) & (peer == b)
        rms.append(float(np.sqrt(np.nanmean(err[sel] ** 2))))
        if i < MAX_PAIR_LINES:
            ax.plot(t[sel], err[sel], lw=0.8, label=f"{a} → {b}")
    # One misattributed peer can be hundreds of metres off while the rest are decimetres:
    # a log scale keeps both readable.
    finite = err[np.isfinite(err) & (err > 0)]
    wide = finite.size > 0 and np.max(finite) > 30.0 * max(np.median(finite), 1e-6)
    if wide:
        ax.set_yscale("log")
        axb.set_xscale("log")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("relative position error (m)" + (" (log)" if wide else ""))
    ax.grid(True, alpha=0.3)
    title = "" if len(pairs) <= MAX_PAIR_LINES else f" (first {MAX_PAIR_LINES} of {len(pairs)} pairs)"
    legend_or_note(ax, "no neighbour estimates", fontsize=6, ncol=2, title=title or None, title_fontsize=7)
    order = np.argsort(rms)[::-1][:30]
    axb.barh([pair_key(*pairs[k]).replace("_to_", " → ") for k in order], [rms[k] for k in order], color="C1")
    axb.invert_yaxis()
    axb.tick_params(axis="y", labelsize=6)
    axb.set_xlabel("RMS error (m)")
    return FigureItem(
        "Relative navigation per pair",
        "|estimated − true| relative position of the peer, 3-D, per observer → peer pair (right: RMS, worst first).",
        fig,
    )


def formation_figure(record: RunRecord) -> FigureItem | None:
    """Formation: top view of the true positions at a few instants, and slot error vs time."""
    ids = record.vehicle_ids
    frm = record.event("formation")
    if len(ids) < 2 and frm is None:
        return None
    tel = record.telemetry
    colors = vehicle_colors(ids)
    fig = new_figure(11.0, 4.5)
    ax, axe = fig.subplots(1, 2)
    times = np.unique(column(tel, "t_s"))
    for k, ts in enumerate(times[np.linspace(0, times.size - 1, min(5, times.size)).astype(int)]):
        snap = tel[np.isclose(column(tel, "t_s"), ts)]
        e, n = column(snap, "truth_east_m"), column(snap, "truth_north_m")
        ax.plot(e, n, "-", color="grey", lw=0.5, alpha=0.6)
        for vid, ee, nn in zip(snap["vehicle_id"], e, n):
            ax.plot(ee, nn, "^", color=colors.get(vid, "k"), ms=6, label=vid if k == 0 else None)
        ax.annotate(f"{ts:.0f} s", (e[0], n[0]), fontsize=7, xytext=(4, 4), textcoords="offset points")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=6, ncol=2)
    if frm is not None:
        fe = np.sqrt(sum(column(frm, f"slot_error_{a}_m") ** 2 for a in ("north", "east", "down")))
        fid = frm["vehicle_id"].astype(str).to_numpy()
        ft = column(frm, "t_s")
        for vid in ids:
            sel = fid == vid
            if sel.any():
                axe.plot(ft[sel], fe[sel], lw=0.9, color=colors[vid], label=vid)
        axe.set_ylabel("slot error (m)")
        legend_or_note(axe, "no slot errors recorded", fontsize=6, ncol=2)
    else:
        axe.text(0.5, 0.5, "no formation events recorded", ha="center", va="center", transform=axe.transAxes)
    axe.set_xlabel("time (s)")
    axe.grid(True, alpha=0.3)
    return FigureItem(
        "Formation",
        "Left: true positions of all vehicles at a few instants (grey lines join each snapshot). "
        "Right: |true position − assigned slot| per vehicle (3-D).",
        fig,
    )


def nis_figure(record: RunRecord) -> FigureItem | None:
    """NIS / dof of each correction kind against time, with the 95 % chi-square band."""
    cor = record.event("corrections")
    if cor is None:
        return None
    kinds = sorted(cor["kind"].astype(str).unique())
    fig = new_figure(10.0, 1.9 * len(kinds) + 0.8)
    axes = fig.subplots(len(kinds), 1, sharex=True, squeeze=False)[:, 0]
    spans = denied_spans(record, record.vehicle_ids[0]) if record.vehicle_ids else []
    spoofed = spoofed_spans(record, record.vehicle_ids[0]) if record.vehicle_ids else []
    for ax, kind in zip(axes, kinds):
        sub = cor[cor["kind"].astype(str) == kind]
        t, nis, dim = column(sub, "t_s"), column(sub, "nis"), column(sub, "dim")
        acc = column(sub, "accepted", dtype=bool).astype(bool)
        shade_spans(ax, spans)
        shade_spans(ax, spoofed, label="GNSS spoofed", color=SPOOFED_COLOR)
        with np.errstate(divide="ignore", invalid="ignore"):
            y = nis / dim
        ax.plot(t[acc], y[acc], ".", ms=2.5, color="C0", label="accepted")
        if (~acc).any():
            ax.plot(t[~acc], y[~acc], "x", ms=3.5, color="C3", label="rejected")
        d = float(np.nanmedian(dim)) if np.isfinite(dim).any() else 1.0
        lo, hi = chi2_bounds(d)
        ax.axhspan(lo / d, hi / d, color="C2", alpha=0.12, lw=0, label=f"95 % χ²({d:g})/dof")
        ax.set_yscale("log")
        ax.set_ylabel(f"{kind}\nNIS/dof")
        ax.grid(True, alpha=0.3, which="both")
        ax.legend(fontsize=6, loc="upper right", ncol=4)
    axes[-1].set_xlabel("time (s)")
    return FigureItem(
        "Correction consistency (NIS)",
        "Normalised innovation squared divided by the measurement dimension, per correction kind and vehicle "
        "(log scale); the band holds 95 % of samples of a consistent filter."
        + (" Violet: GNSS spoofed (its fixes dragged off; rejected ones marked x)." if spoofed else ""),
        fig,
    )
