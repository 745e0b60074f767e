"""The blocks a report is made of besides figures: headings, paragraphs, tables in no format
(with the marks a cell may carry and the notes that say what they mean), and a detector's own
blocks that a split report moves to its appendix."""

from __future__ import annotations

from dataclasses import dataclass, field

from slipbench.vocabulary import LOW_N


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


LOW_MARK = "†"  # a cell resting on few test trials
BELOW_CONSTANT_MARK = "‡"  # an accuracy not above what the constant answer scores there
UNESTIMABLE_MARK = "§"  # an interval that is the figure's whole range: a class of one trial
UNESTIMABLE_NOTE = (
    f"{UNESTIMABLE_MARK} the interval is not estimable: a class of the test set holds a single "
    "test trial, so nothing measures how its trials vary, and the interval shown is the "
    "figure's whole range (the row's ci_note), whatever the number of test trials."
)
LOW_NOTE = (
    f"{LOW_MARK} few test trials behind this cell (fewer than {LOW_N} of a class where the rows say, "
    f"else fewer than {LOW_N} in all): its interval is not to be trusted."
)
STREAM_LOW_NOTE = (
    f"{LOW_MARK} few events behind this cell (fewer than {LOW_N} test trials holding slip onsets, "
    f"fewer than {LOW_N} onsets, or fewer than {LOW_N} trials with non-slip time): its figures are "
    "not to be trusted."
)


@dataclass
class Table:
    """A table in no format: labels and cell texts, in plain text (each renderer escapes them)."""

    caption: str
    row_headers: list[str]
    group: str  # header spanning the value columns
    columns: list[str]  # plain-text column labels (Markdown)
    rows: list[tuple[str, ...]]
    cells: list[list[str]]
    label: str
    # a value column's label as values each with a superscript, (value, superscript) pairs by
    # the column's index (the rates of the paper's Table II, numbered by sensor type), for a
    # format that sets superscripts; ``columns`` holds the same label as plain text
    superscripts: dict[int, list[tuple[str, str]]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    # LaTeX: columns (counted over row headers, then value columns) set as wrapping paragraphs,
    # each this fraction of the line width; text columns need it, numbers do not
    wrap: dict[int, float] = field(default_factory=dict)
    subject: str = ""  # what the table is of ("Detector holweg, protocol window-size, paper split."): after the caption

    def __post_init__(self) -> None:
        # every table that marks a cell says what the mark means, whoever built it
        for mark, note in ((LOW_MARK, LOW_NOTE), (UNESTIMABLE_MARK, UNESTIMABLE_NOTE)):
            marked = any(mark in c for line in self.cells for c in line)
            if marked and not any(n.startswith(mark) for n in self.notes):
                self.notes.append(note)
