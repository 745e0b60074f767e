"""The blocks a report is made of besides tables and figures: headings, paragraphs, and a
detector's own blocks that a split report moves to its appendix."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class Heading:
    text: str
    level: int = 2


@dataclass
class Text:
    text: str


@dataclass
class Detail:
    """One detector's blocks of a section (its tables and figures): inline in a whole report,
    moved to the appendix where the report is split (:func:`slipbench.report.document.split_appendix`)."""

    section: str
    blocks: list
