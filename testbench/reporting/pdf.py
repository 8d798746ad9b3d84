"""PDF report with the same content as the HTML one, through matplotlib's PdfPages.

Tables are typeset as monospaced text pages (paginated); every figure gets its own page with
its title and caption.
"""

from __future__ import annotations

import logging
import os
import textwrap
from pathlib import Path

from matplotlib.backends.backend_pdf import PdfPages

from testbench.reporting.content import build_report, fmt
from testbench.reporting.figures_common import new_figure
from testbench.reporting.model import Report, Table
from testbench.scoring import MetricsResult

log = logging.getLogger(__name__)

LINES_PER_PAGE = 70
PAGE_IN = (8.27, 11.69)  # A4 portrait


def table_lines(t: Table, max_col: int = 48) -> list[str]:
    """A table as fixed-width text lines (cells clipped to max_col characters)."""
    cells = [[str(c)[:max_col] for c in row] for row in [t.header] + t.rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(t.header))]
    lines = [t.title, ""]
    for k, row in enumerate(cells):
        lines.append("  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip())
        if k == 0:
            lines.append("  ".join("-" * w for w in widths))
    return lines + [""]


def _text_pages(pdf: PdfPages, heading: str, lines: list[str]) -> None:
    chunks = [lines[i:i + LINES_PER_PAGE] for i in range(0, max(len(lines), 1), LINES_PER_PAGE)]
    for k, chunk in enumerate(chunks):
        fig = new_figure(*PAGE_IN)
        fig.set_layout_engine(None)
        title = heading if k == 0 else f"{heading} (continued)"
        fig.text(0.06, 0.965, title, fontsize=14, weight="bold", va="top")
        fig.text(0.06, 0.93, "\n".join(chunk), family="monospace", fontsize=7.2, va="top")
        pdf.savefig(fig)


def _figure_page(pdf: PdfPages, section: str, item) -> None:
    fig = item.figure
    # Title and caption go above / below the plot through the suptitle and a footer text.
    fig.suptitle(f"{section}: {item.title}", fontsize=11, weight="bold")
    caption = "\n".join(textwrap.wrap(item.caption, 130))
    fig.supxlabel(caption, fontsize=7, ha="center")
    pdf.savefig(fig)


def write_pdf(report: Report, out: Path) -> None:
    """Render a Report into a PDF file."""
    with PdfPages(out) as pdf:
        first = [f"Verdict: {report.verdict}", ""]
        first += [f"WARNING: {w}" for w in report.warnings]
        first += table_lines(report.config)
        first += table_lines(report.thresholds) if report.thresholds else ["This scenario sets no thresholds.", ""]
        _text_pages(pdf, report.title, first)
        for s in report.sections:
            lines = [ln for t in s.tables for ln in table_lines(t)]
            if lines:
                _text_pages(pdf, s.title, lines)
            for item in s.figures:
                _figure_page(pdf, s.title, item)
        all_lines = [f"{k}  {fmt(v)}" for k, v in report.metrics_flat.items()]
        _text_pages(pdf, "All metrics", all_lines)
        if report.scenario_text:
            wrapped = [w for ln in report.scenario_text.splitlines() for w in (textwrap.wrap(ln, 110) or [""])]
            _text_pages(pdf, "Resolved scenario", wrapped)
        info = pdf.infodict()
        info["Title"] = report.title
        info["Subject"] = f"verdict {report.verdict}"


def write_pdf_report(run_dir: str | Path, out_path: str | Path | None = None, result: MetricsResult | None = None) -> Path:
    """Write the PDF report of the run in run_dir to out_path (default DIR/report.pdf), atomically."""
    run_dir = Path(run_dir)
    out = Path(out_path) if out_path is not None else run_dir / "report.pdf"
    tmp = out.with_name(out.name + ".part")
    write_pdf(build_report(run_dir, result=result), tmp)
    os.replace(tmp, out)
    log.info("wrote %s (%.1f kB)", out, out.stat().st_size / 1024)
    return out
