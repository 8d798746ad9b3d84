"""The batch's HTML report: status table, summary statistics, histograms and CDFs of the main
metrics, and each metric against each varied parameter. Self-contained (embedded PNGs)."""

from __future__ import annotations

import base64
import html
import io
import math
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from testbench.navigation.ins.consistency import average_nees_bounds  # noqa: E402

# Metrics worth a figure when present (the summary table lists every metric).
_HEADLINE = (
    "nav.horizontal_error_m.mean", "nav.horizontal_error_m.max",
    "ismn.smooth.horizontal_error_m.mean", "ismn.turning.horizontal_error_m.mean", "ismn.fix_rate",
    "relnav.error_m.max", "formation.error_m.rms",
    "control.altitude_error_m.rms", "control.cross_track_error_m.rms", "real_time_factor",
)


def _png(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _number(value: Any) -> float:
    """A row's value as a float; nan when absent or not a number (a varied map path, an
    aircraft name: those get no scatter plot)."""
    if not isinstance(value, (int, float, np.number)):
        return math.nan
    return float(value)


def _values(rows: list[dict[str, Any]], key: str) -> np.ndarray:
    return np.array([_number(r.get(key)) for r in rows], float)


def write_batch_report(out_dir: Path, rows: list[dict[str, Any]], summary: dict[str, Any], path: Path) -> None:
    figures: list[tuple[str, str]] = []
    varied = sorted({k for r in rows for k in r if k.startswith("vary.")})
    for key in _HEADLINE:
        x = _values(rows, key)
        x = x[np.isfinite(x)]
        if x.size == 0:
            continue
        fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3))
        a.hist(x, bins=min(30, max(5, x.size // 3)), color="#4477aa")
        a.set_xlabel(key)
        a.set_ylabel("runs")
        s = np.sort(x)
        b.step(s, np.arange(1, s.size + 1) / s.size, where="post", color="#aa3377")
        b.set_xlabel(key)
        b.set_ylabel("fraction of runs")
        b.grid(alpha=0.3)
        figures.append((f"{key}: histogram and CDF over {x.size} runs", _png(fig)))
        for v in varied:
            p = _values(rows, v)
            y = _values(rows, key)
            ok = np.isfinite(p) & np.isfinite(y)
            if ok.sum() < 2:
                continue
            fig, ax = plt.subplots(figsize=(5, 3))
            ax.plot(p[ok], y[ok], "o", ms=3)
            ax.set_xlabel(v[5:])
            ax.set_ylabel(key)
            ax.grid(alpha=0.3)
            figures.append((f"{key} against {v[5:]}", _png(fig)))
    stat_rows = "".join(
        f"<tr><td>{html.escape(k)}</td>" + "".join(f"<td>{_fmt(d.get(c))}</td>" for c in ("n", "mean", "ci95_low", "ci95_high", "std", "median", "p95", "max")) + "</tr>"
        for k, d in summary["metrics"].items()
    )
    run_rows = "".join(
        f"<tr><td>{r.get('run')}</td><td>{html.escape(str(r.get('status')))}</td><td>{html.escape(str(r.get('error') or ''))[:200]}</td></tr>"
        for r in rows if r.get("status") not in ("passed",)
    )
    pr = summary["threshold_pass_rate"]
    body = f"""<!DOCTYPE html><html><head><meta charset="utf-8"><title>Monte Carlo: {html.escape(out_dir.name)}</title>
<style>body{{font-family:sans-serif;margin:2em;max-width:70em}}table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:2px 6px;font-size:90%}}img{{max-width:100%}}</style></head><body>
<h1>Monte Carlo batch {html.escape(out_dir.name)}</h1>
<p>{summary['runs_done']} of {summary['runs_planned']} runs done; status: {html.escape(str(summary['status_counts']))}.
Threshold pass rate {_fmt(pr['value'])} (95 % CI {_fmt(pr['ci95_low'])} to {_fmt(pr['ci95_high'])}, n = {pr['n']}).</p>
{_nees_html(summary.get("nees_position"))}{_nees_figure_html(out_dir / "nees_position.parquet", summary.get("nees_position"))}
<h2>Runs that did not pass</h2><table><tr><th>run</th><th>status</th><th>error</th></tr>{run_rows or '<tr><td colspan=3>none</td></tr>'}</table>
<h2>Figures</h2>{''.join(f'<figure><img alt="{html.escape(t)}" src="data:image/png;base64,{b}"><figcaption>{html.escape(t)}</figcaption></figure>' for t, b in figures)}
<h2>Statistics</h2><table><tr><th>metric</th><th>n</th><th>mean</th><th>CI95 low</th><th>CI95 high</th><th>std</th><th>median</th><th>p95</th><th>max</th></tr>{stat_rows}</table>
</body></html>"""
    tmp = path.with_suffix(".html.part")
    tmp.write_text(body, encoding="utf-8")
    tmp.replace(path)


def _nees_html(nees: dict[str, Any] | None) -> str:
    """Paragraph on filter consistency (average position NEES over runs), empty without it."""
    if not nees:
        return ""
    return (
        f"<h2>Filter consistency</h2><p>Average position NEES over {nees['runs']} runs (3 dof): inside its 95 % "
        f"bounds [{_fmt(nees['bound_low'])}, {_fmt(nees['bound_high'])}] at {100 * nees['fraction_within']:.1f} % "
        f"of {nees['samples']} record times, above at {100 * nees['fraction_above']:.1f} %; time mean "
        f"{_fmt(nees['mean_of_average'])} (3 for a consistent filter).{_chance_html(nees)}</p>"
    )


def _nees_figure_html(series_path: Path, nees: dict[str, Any] | None) -> str:
    """The batch's average NEES against time with its 95 % band, and each axis's average squared
    whitened error with its own 1-dof band (which axis, when, over- or under-confident; east is
    whitened given north, which differs from east alone only by their correlation); empty
    without the series (batch.consistency.NeesConsistency.series)."""
    if not nees or not series_path.is_file():
        return ""
    series = pd.read_parquet(series_path)
    runs = int(nees["runs"])
    fig, (a, b) = plt.subplots(2, 1, figsize=(9, 5.5), sharex=True)
    for vid, g in series.groupby("vehicle_id", sort=True):
        label = f" {vid}" if series["vehicle_id"].nunique() > 1 else ""
        a.plot(g["t_s"], g["average_nees"], lw=0.8, label=f"average NEES{label}")
        for axis, colour in (("north", "#4477aa"), ("east", "#228833"), ("down", "#aa3377")):
            b.plot(g["t_s"], g[f"average_z2_{axis}"], lw=0.7, color=colour, label=f"{axis}{label}")
    a.axhspan(nees["bound_low"], nees["bound_high"], color="#cccccc", alpha=0.5, label="95 % band (3 dof)")
    lo1, hi1 = average_nees_bounds(1, runs)
    b.axhspan(lo1, hi1, color="#cccccc", alpha=0.5, label="95 % band (1 dof)")
    a.set_ylabel(f"average NEES ({runs} runs)")
    b.set_ylabel("per axis (1 dof)")
    b.set_xlabel("t (s)")
    for ax in (a, b):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
    title = f"average position NEES over {runs} runs against time, and per axis"
    return f'<figure><img alt="{html.escape(title)}" src="data:image/png;base64,{_png(fig)}"><figcaption>{html.escape(title)}</figcaption></figure>'


def _chance_html(nees: dict[str, Any]) -> str:
    """The sentence on what a consistent filter would show (batch.consistency.chance_shares)."""
    p05, p = nees.get("chance_share_p05"), nees.get("chance_p_value")
    if p05 is None or p is None or not (math.isfinite(p05) and math.isfinite(p)):
        return ""
    return (
        f" A consistent filter whose errors had this batch's time correlation would be inside "
        f"{100 * nees['chance_share_mean']:.1f} % of the time on average, above {100 * p05:.1f} % in 95 % of "
        f"batches, and inside at most this batch's share in {100 * p:.1f} % of them (small: worse than chance "
        f"allows)."
    )


def _fmt(v: Any) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return f"{v:.4g}" if isinstance(v, float) else str(v)
