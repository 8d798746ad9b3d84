"""The report as data: sections of tables and matplotlib figures, independent of the format.

`content.build_report` fills a `Report`; `html.py` and `pdf.py` render the same object, so the
HTML and PDF carry the same content.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from matplotlib.figure import Figure


@dataclass(frozen=True)
class Table:
    """A table of text cells. status_col: index of a PASS/FAIL column to colour (or None)."""

    title: str
    header: list[str]
    rows: list[list[str]]
    status_col: int | None = None


@dataclass(frozen=True)
class FigureItem:
    """One matplotlib figure with a title and a caption saying what is plotted and in what units."""

    title: str
    caption: str
    figure: Figure


@dataclass(frozen=True)
class Section:
    """A titled part of the report; anchor is its HTML id."""

    title: str
    anchor: str
    tables: list[Table] = field(default_factory=list)
    figures: list[FigureItem] = field(default_factory=list)
    note: str = ""


@dataclass(frozen=True)
class Report:
    """Everything a report shows. verdict: "PASSED", "FAILED" or "ABORTED"; warnings: lines shown first."""

    title: str
    verdict: str
    config: Table
    thresholds: Table | None
    sections: list[Section]
    scenario_text: str = ""
    metrics_flat: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
