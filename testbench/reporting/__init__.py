"""Reports of a run: one self-contained HTML file and a PDF with the same content.

    from testbench.reporting import write_html_report, write_pdf_report
    write_html_report(run_dir)              # DIR/report.html
    write_pdf_report(run_dir, "out.pdf")

Modules: content (Report assembly), figures_nav / figures_events (matplotlib figures),
html (jinja2 template in templates/), pdf (PdfPages).
"""

from testbench.reporting.content import build_report
from testbench.reporting.html import render_html, write_html_report
from testbench.reporting.pdf import write_pdf_report

__all__ = ["build_report", "render_html", "write_html_report", "write_pdf_report"]
