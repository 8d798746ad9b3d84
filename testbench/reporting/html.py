"""Self-contained HTML report: one file, figures embedded as base64 PNG, no scripts, no URLs."""

from __future__ import annotations

import base64
import datetime as _dt
import logging
import os
from dataclasses import dataclass
from pathlib import Path

import jinja2

from testbench.reporting.content import build_report, fmt
from testbench.reporting.figures_common import png_bytes
from testbench.reporting.model import Report
from testbench.scoring import MetricsResult

log = logging.getLogger(__name__)

_ENV = jinja2.Environment(
    loader=jinja2.PackageLoader("testbench.reporting", "templates"),
    autoescape=jinja2.select_autoescape(["html", "j2"]),
    undefined=jinja2.StrictUndefined,
    trim_blocks=True,
    lstrip_blocks=True,
)


@dataclass(frozen=True)
class _RenderedFigure:
    title: str
    caption: str
    png_b64: str
    width: int
    height: int


def _version() -> str:
    try:
        from importlib.metadata import version

        return version("testbench")
    except Exception:  # not installed as a distribution (a source checkout on sys.path)
        return "dev"


def render_html(report: Report, dpi: int = 100) -> str:
    """The report as one HTML document (string)."""
    sections = []
    for s in report.sections:
        figs = []
        for f in s.figures:
            w_in, h_in = f.figure.get_size_inches()
            png = png_bytes(f.figure, dpi=dpi)
            figs.append(_RenderedFigure(f.title, f.caption, base64.b64encode(png).decode("ascii"),
                                        int(round(w_in * dpi)), int(round(h_in * dpi))))
        sections.append({"title": s.title, "anchor": s.anchor, "note": s.note, "tables": s.tables, "figures": figs})
    template = _ENV.get_template("report.html.j2")
    return template.render(
        report=report,
        sections=sections,
        metric_rows=[(k, fmt(v)) for k, v in report.metrics_flat.items()],
        version=_version(),
        generated=_dt.datetime.now().astimezone().isoformat(timespec="seconds"),
    )


def write_html_report(run_dir: str | Path, out_path: str | Path | None = None, result: MetricsResult | None = None) -> Path:
    """Write the HTML report of the run in run_dir to out_path (default DIR/report.html).

    result: the MetricsResult already computed by the caller (else the run is scored here).
    Written atomically, so a failed report never leaves a partial file behind.
    """
    run_dir = Path(run_dir)
    out = Path(out_path) if out_path is not None else run_dir / "report.html"
    html = render_html(build_report(run_dir, result=result))
    tmp = out.with_name(out.name + ".part")
    tmp.write_text(html, encoding="utf-8")
    os.replace(tmp, out)
    log.info("wrote %s (%.1f kB)", out, out.stat().st_size / 1024)
    return out
