"""The blocks a report is made of besides tables and figures: headings, paragraphs, and a
detector's own blocks that a split report moves to its appendix."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class Heading:
    text: str
    level: int = 2


@dataclass
class Link:
    """A link a report makes itself (to its appendix, its summary): never one from the data."""

    label: str
    target: str  # a relative path, with an optional #anchor


@dataclass
class Text:
    """A paragraph of plain text (every format escapes it), then an optional :class:`Link`
    (a label alone where its target is empty), then ``after``; no space is added between."""

    text: str
    link: Link | None = None
    after: str = ""


OWN = "each detector's own tables and figures"


@dataclass
class Detail:
    """Blocks of a section that a summary leaves out (one detector's tables and figures, every
    detector on a split the summary does not lead with, the published table): inline in a whole
    report, moved to the appendix where the report is split
    (:func:`slipbench.report.document.split_appendix`). ``what``: what they are, as the
    summary's link to them names it."""

    section: str
    blocks: list
    what: str = OWN
