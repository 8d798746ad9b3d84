"""Shared helpers for report figures: figure creation, colours, GNSS-denied spans, map preview.

Figures are built as `matplotlib.figure.Figure` objects (no pyplot, no global state), so they
render with the Agg canvas in any thread and are freed when dropped.
"""

from __future__ import annotations

import io
import logging
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from testbench.scoring.record_io import RunRecord, column

log = logging.getLogger(__name__)

DENIED_COLOR = "#f4a582"
SPOOFED_COLOR = "#b2abd2"  # GNSS spoofed: fixes still come, dragged off by a spoofer
MAX_DETAILED_VEHICLES = 4  # beyond this, per-vehicle panels are merged into one overlay


def new_figure(width_in: float = 9.0, height_in: float = 4.0) -> Figure:
    """A fresh figure with constrained layout (labels never overlap)."""
    return Figure(figsize=(width_in, height_in), dpi=100, layout="constrained")


def legend_or_note(ax: Any, empty_note: str = "no data", **legend_kw: Any) -> None:
    """The axes' legend, or, when nothing on it carries a label (a run without scene-matching
    fixes, a vehicle that never saw a neighbour), `empty_note` written in its middle: an empty
    panel says why it is empty, and matplotlib's "no artists with labels" warning does not
    reach the user's terminal."""
    handles, _ = ax.get_legend_handles_labels()
    if handles:
        ax.legend(**legend_kw)
    else:
        ax.text(0.5, 0.5, empty_note, transform=ax.transAxes, ha="center", va="center", fontsize=8, color="grey")


def vehicle_colors(ids: list[str]) -> dict[str, Any]:
    """A stable colour per vehicle id (tab10, then tab20 for bigger swarms)."""
    from matplotlib import colormaps

    cmap = colormaps["tab10" if len(ids) <= 10 else "tab20"]
    return {vid: cmap(i % cmap.N) for i, vid in enumerate(ids)}


def png_bytes(fig: Figure, dpi: int = 100) -> bytes:
    """The figure as PNG bytes (Agg)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def bool_spans(t: np.ndarray, mask: np.ndarray) -> list[tuple[float, float]]:
    """Contiguous [start, end] time spans where mask is True (t ascending)."""
    spans = []
    if t.size == 0:
        return spans
    m = np.asarray(mask, bool)
    edges = np.diff(np.concatenate([[False], m, [False]]).astype(int))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    for s, e in zip(starts, ends):
        spans.append((float(t[s]), float(t[e])))
    return spans


def denied_spans(record: RunRecord, vehicle_id: str) -> list[tuple[float, float]]:
    """GNSS-denied time spans of one vehicle: from gnss_available, else run.json windows."""
    tel = record.vehicle_telemetry(vehicle_id)
    if "gnss_available" in tel.columns and len(tel):
        return bool_spans(column(tel, "t_s"), ~tel["gnss_available"].to_numpy().astype(bool))
    windows = (record.run_info.get("gnss_denied_windows") or {}).get(vehicle_id, [])
    return [(float(a), float(b)) for a, b in windows]


def spoofed_spans(record: RunRecord, vehicle_id: str) -> list[tuple[float, float]]:
    """GNSS-spoofed time spans of one vehicle (run.json gnss_spoofed_windows)."""
    windows = (record.run_info.get("gnss_spoofed_windows") or {}).get(vehicle_id, [])
    return [(float(a), float(b)) for a, b in windows]


def shade_spans(ax, spans: list[tuple[float, float]], label: str = "GNSS denied", color: str = DENIED_COLOR) -> None:
    """Shade time spans on an axis; labels only the first so the legend shows it once."""
    for i, (a, b) in enumerate(spans):
        ax.axvspan(a, b, color=color, alpha=0.35, lw=0, label=label if i == 0 else None)


def map_preview(record: RunRecord) -> tuple[np.ndarray, tuple[float, float, float, float]] | None:
    """(RGB image, (n_min, n_max, e_min, e_max) in local NED metres) of run.json "map_image".

    Accepted forms: {"path": P, "bounds_ne_m": [n_min, n_max, e_min, e_max]} (or "bounds"),
    or a path string with the bounds in "map_bounds_ne_m". Relative paths are taken from the
    run directory. Returns None (and logs why) when absent or unreadable.
    """
    info = record.run_info
    spec = info.get("map_image")
    if not spec:
        return None
    if isinstance(spec, dict):
        path = spec.get("path")
        bounds = spec.get("bounds_ne_m", spec.get("bounds"))
    else:
        path, bounds = spec, info.get("map_bounds_ne_m", info.get("map_image_bounds_ne_m"))
    if not path or bounds is None or len(bounds) != 4:
        log.warning("run.json map_image needs a path and bounds [n_min, n_max, e_min, e_max]; got %r", spec)
        return None
    p = Path(path)
    if not p.is_absolute() and record.run_dir is not None:
        p = record.run_dir / p
    try:
        import cv2

        img = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise OSError("unreadable image")
        if img.ndim == 3:
            img = cv2.cvtColor(img, cv2.COLOR_BGRA2RGBA if img.shape[2] == 4 else cv2.COLOR_BGR2RGB)
    except OSError as exc:
        log.warning("map preview %s not shown: %s", p, exc)
        return None
    n_min, n_max, e_min, e_max = (float(b) for b in bounds)
    return img, (n_min, n_max, e_min, e_max)


def ecdf(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Empirical CDF (sorted finite values, cumulative fraction)."""
    v = np.sort(np.asarray(values, float)[np.isfinite(values)])
    return v, np.arange(1, v.size + 1) / max(v.size, 1)


def vehicle_rows(tel: pd.DataFrame, vehicle_id: str) -> pd.DataFrame:
    return tel[tel["vehicle_id"] == vehicle_id]
