"""`testbench report DIR [--pdf] [--out FILE]`: (re)write the report of a finished run."""

from __future__ import annotations

import argparse
from pathlib import Path

from testbench.core.errors import InputError


def register(subparsers) -> None:
    p = subparsers.add_parser("report", help="write the HTML (and PDF) report of a run directory")
    p.add_argument("run_dir", metavar="DIR", help="run directory written by `testbench run`")
    p.add_argument("--pdf", action="store_true", help="also write the PDF report (DIR/report.pdf)")
    p.add_argument("--out", metavar="FILE", help="HTML output path (default DIR/report.html)")
    p.add_argument("--no-html", action="store_true", help="with --pdf: write only the PDF")
    p.set_defaults(handler=report)


def report(args: argparse.Namespace) -> int:
    from testbench.reporting import write_html_report, write_pdf_report
    from testbench.scoring import score_run

    run_dir = Path(args.run_dir)
    if not (run_dir / "run.json").is_file():
        raise InputError(f"{run_dir}: not a run directory (no run.json); expected the --out folder of `testbench run`")
    if args.no_html and not args.pdf:
        raise InputError("--no-html: expected together with --pdf (otherwise nothing would be written)")
    result = score_run(run_dir)  # scored once, shared by both formats
    if not args.no_html:
        print(f"wrote {write_html_report(run_dir, args.out, result=result)}")
    if args.pdf:
        print(f"wrote {write_pdf_report(run_dir, run_dir / 'report.pdf', result=result)}")
    return 0
