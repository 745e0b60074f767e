"""LaTeX: tables in the paper's style (vertical rules, the sensor name once per group), set to
fit the text width; with ``standalone``, a whole document that compiles with the packages of
every LaTeX installation. Every text from the data is escaped (kernel commands only)."""

from __future__ import annotations

import re
import textwrap

from slipbench.report.blocks import (
    BELOW_CONSTANT_MARK,
    LOW_MARK,
    UNESTIMABLE_MARK,
    Heading,
    Table,
    Text,
)
from slipbench.report.render import Drawn, Renderer

# one figure of a cell as ``figure_text`` writes it ("88.0 ± 0.4 [86.9, 89.1]†"), its marks after
# it ("*": without explicit training); a paired cell holds two, separated by a space
FIGURE = re.compile(
    r"(?P<value>-?\d+(?:\.\d+)?|NA|—|\w+)(?P<sd> ± \d+(?:\.\d+)?)?"
    r"(?: \[(?P<lo>-?\d+(?:\.\d+)?), (?P<hi>-?\d+(?:\.\d+)?)\])?(?P<mark>[*†‡§]*)"
)
LATEX_TABLE_SIZE = (
    r"\footnotesize"  # with intervals on a second line, the paper's tables fit the text width
)
LATEX_COLUMN_SEP = "3pt"
# a standalone page: tables taller than this many lines of \footnotesize break across pages
# (longtable); a page of the article class holds about 50 with the caption and a heading
LONG_TABLE_LINES = 40
CHARS_PER_LINE = 95  # \footnotesize characters on one \linewidth of the article class

LATEX_CHARS = {
    "\\": r"\textbackslash{}",
    "&": r"\&",
    "%": r"\%",
    "_": r"\_",
    "#": r"\#",
    "{": r"\{",
    "}": r"\}",
    "$": r"\$",
    "~": r"\textasciitilde{}",
    "^": r"\textasciicircum{}",
    "±": r"$\pm$",
    "—": "--",
    "–": "--",
    "−": "-",
    LOW_MARK: r"\dag{}",
    BELOW_CONSTANT_MARK: r"\ddag{}",
    UNESTIMABLE_MARK: r"\S{}",
    "χ": r"$\chi$",
    "²": r"$^2$",
    "α": r"$\alpha$",
    "≥": r"$\geq$",
    "≤": r"$\leq$",
    "×": r"$\times$",
    "µ": r"$\mu$",
    "≈": r"$\approx$",
    "→": r"$\rightarrow$",
    "<": r"$<$",
    ">": r"$>$",
}


def escape(text: str) -> str:
    """Plain text as LaTeX (kernel commands only), one character at a time so that no
    replacement is escaped again; on one line (a blank line would end a cell's paragraph),
    control characters as spaces."""
    return "".join(
        LATEX_CHARS.get(c, " " if c.isspace() or not c.isprintable() else c) for c in str(text)
    )


def _stacked(lines: list[str]) -> str:
    return (
        r"\begin{tabular}{@{}c@{}}" + r"\\".join(lines) + r"\end{tabular}"
        if len(lines) > 1
        else lines[0]
    )


def latex_cell(text: str) -> str:
    """A cell for LaTeX, stacked so that wide tables fit the text width: the interval (and the
    spread over seeds) on its own line in a smaller size (``88.0`` over ``86.9--89.1``), the
    two figures of a paired cell (with, without*) one above the other."""
    figures = list(FIGURE.finditer(text))
    if " ".join(m[0] for m in figures) != text or not (
        len(figures) > 1 or any(m["lo"] or m["sd"] for m in figures)
    ):
        named = re.fullmatch(r"(\S+) \((.+)\)", text)  # "Neoprene (-9.1)": the name over its figure
        return _stacked([escape(named[1]), escape(f"({named[2]})")]) if named else escape(text)
    lines = []
    for m in figures:
        lines.append(escape(m["value"] + m["mark"]))
        if m["sd"]:  # the spread over seeds on a line of its own, as the interval
            lines.append(rf"{{\scriptsize {escape(m['sd'].strip())}}}")
        if m["lo"]:
            lines.append(rf"{{\scriptsize {m['lo']}--{m['hi']}}}")
    return _stacked(lines)


def _latex_header(text: str) -> str:
    """A column label on several lines: a parenthesis on its own ("holweg (paper)"), a long
    hyphenated name broken after its hyphens ("material-" over "holdout")."""
    if text.startswith(r"\begin"):
        return text
    head, _, tail = text.partition(" (")
    lines = re.sub(r"(?<=-)(?=[a-z])", "\n", head).split("\n") if len(head) > 10 else [head]
    return _stacked(lines + (["(" + tail] if tail else []))


def _two_lines(text: str, limit: int = 44) -> str:
    """Escaped text, on two lines (at the space nearest its middle) when longer than ``limit``."""
    if len(text) <= limit or " " not in text:
        return escape(text)
    middle = min((i for i, c in enumerate(text) if c == " "), key=lambda i: abs(i - len(text) / 2))
    return _stacked([escape(text[:middle]), escape(text[middle + 1 :])])


def _values_width(table: Table) -> int:
    """About how many characters wide the value columns are set: per column its widest line
    (its label's, or a cell's figure or interval as :func:`latex_cell` stacks them), plus
    the gap between columns."""
    width = 0
    for j, label in enumerate(table.columns):
        lines = [label] if j not in table.superscripts else [v for v, _ in table.superscripts[j]]
        for cells in table.cells:
            for m in FIGURE.finditer(cells[j] if j < len(cells) else ""):
                lines += [m["value"] + m["mark"], f"{m['lo']}-{m['hi']}" if m["lo"] else ""]
        width += max(map(len, lines)) + 1
    return width


def _group_header(table: Table) -> str:
    """The header over the value columns, escaped, on as many lines as keep it within their
    width: a header wider than its columns would widen the last one alone."""
    width = _values_width(table)
    if len(table.group) <= width:
        return _two_lines(table.group)
    lines = textwrap.wrap(table.group, max(width, 20), break_long_words=False)
    return _stacked([escape(line) for line in lines])


def latex_lines(table: Table) -> int:
    """About how many lines of text ``table`` takes when set: per row, its tallest cell (stacked
    lines, or a wrapped paragraph's lines), plus the caption, header and notes."""

    def height(i: int, text: str) -> int:
        if i in table.wrap:
            return max(1, -(-len(text) // max(1, int(table.wrap[i] * CHARS_PER_LINE))))
        return latex_cell(text).count(r"\\") + 1

    body = sum(
        max(height(j, t) for j, t in enumerate([*labels, *cells]))
        for labels, cells in zip(table.rows, table.cells)
    )
    notes = sum(-(-len(n) // CHARS_PER_LINE) for n in table.notes)
    group = _group_header(table).count(r"\\") + 1 if table.group else 0
    return body + 4 + group + notes


def to_latex(table: Table, page: bool = False) -> str:
    """A LaTeX ``table`` float in the paper's style (vertical rules, sensor name on the first row
    of its group, ``\\cline`` between fingers). Uses only the LaTeX kernel: no packages.

    ``page``: for :func:`standalone_latex`'s document, where nothing may be larger than the
    page and a section's heading stays with its tables: the float is placed here (``[H]``,
    package float), a table wider than the text is scaled to its width (``\\resizebox``) and
    one taller than :data:`LONG_TABLE_LINES` lines breaks across pages (longtable, its header
    repeated).

    Wide tables fit the text width: the float is set in ``\\footnotesize`` with narrower column
    gaps, intervals go on a second line in ``\\scriptsize``, long column labels on two lines,
    and text columns (``Table.wrap``) wrap as paragraphs. Written by hand rather than with
    ``Styler.to_latex``: that needs booktabs and multirow, and has no way to express the
    per-sensor rate header of Table II.
    """
    n_rows, n_cols = len(table.row_headers), len(table.columns)
    first = n_rows + 1
    spec = "|" + "|".join("l" if i in table.wrap else "c" for i in range(n_rows + n_cols)) + "|"

    def wrapped(i: int, text: str) -> str:
        # a ragged-right paragraph: a justified p{} column stretches spaces across narrow lines
        return (
            rf"\parbox[t]{{{table.wrap[i]:.2f}\linewidth}}{{\raggedright {text}\strut}}"
            if i in table.wrap
            else text
        )

    caption = f"{table.caption} {table.subject}".strip()
    head: list[str] = []
    heads = " & ".join(rf"\textbf{{{escape(h)}}}" for h in table.row_headers)
    if table.group:
        head.append(
            rf"{heads} & \multicolumn{{{n_cols}}}{{c|}}{{\bfseries {_group_header(table)}}}\\"
        )
        head.append(rf"\cline{{{first}-{n_rows + n_cols}}}")
        heads = " & " * n_rows
    else:
        heads += " & "
    latex_cols = [
        _superscripted(table.superscripts[j]) if j in table.superscripts else escape(c)
        for j, c in enumerate(table.columns)
    ]
    head.append(
        heads
        + " & ".join(
            wrapped(n_rows + j, c) if n_rows + j in table.wrap else _latex_header(c)
            for j, c in enumerate(latex_cols)
        )
        + r"\\"
    )
    head.append(r"\hline")
    lines: list[str] = []
    previous: tuple[str, ...] | None = None
    for i, (labels, cells) in enumerate(zip(table.rows, table.cells)):
        shown = list(labels)
        if n_rows > 1 and previous is not None and labels[0] == previous[0]:
            shown[0] = ""  # the sensor name once per group, as the paper's multirow
        texts = [
            *(escape(x) for x in shown),
            *(
                escape(c) if n_rows + j in table.wrap else latex_cell(c)
                for j, c in enumerate(cells)
            ),
        ]
        lines.append(" & ".join(wrapped(j, t) for j, t in enumerate(texts)) + r"\\")
        nxt = table.rows[i + 1] if i + 1 < len(table.rows) else None
        lines.append(
            rf"\cline{{2-{n_rows + n_cols}}}"
            if n_rows > 1 and nxt is not None and nxt[0] == labels[0]
            else r"\hline"
        )
        previous = labels
    # a label is a key LaTeX reads raw: names from the data keep letters, digits, ":._-"
    label_ = [rf"\label{{{re.sub(r'[^A-Za-z0-9:._-]+', '-', table.label)}}}"] if table.label else []
    notes = [rf"\par {escape(note)}" for note in table.notes]
    size = [LATEX_TABLE_SIZE, rf"\setlength{{\tabcolsep}}{{{LATEX_COLUMN_SEP}}}"]
    if page and latex_lines(table) > LONG_TABLE_LINES:
        columns = n_rows + n_cols
        return "\n".join(
            [
                r"\begingroup",
                *size,
                rf"\begin{{longtable}}{{{spec}}}",
                rf"\caption{{{escape(caption)}}}{''.join(label_)}\\",
                r"\hline",
                *head,
                r"\endfirsthead",
                rf"\multicolumn{{{columns}}}{{l}}{{\emph{{Table \thetable{{}}, continued}}}}\\",
                r"\hline",
                *head,
                r"\endhead",
                rf"\multicolumn{{{columns}}}{{r}}{{\emph{{continued on the next page}}}}\\",
                r"\endfoot",
                r"\endlastfoot",
                *lines,
                r"\end{longtable}",
                *notes,
                r"\par\endgroup",
            ]
        )
    tabular = [rf"\begin{{tabular}}{{{spec}}}", r"\hline", *head, *lines, r"\end{tabular}"]
    if page:  # scaled to the text's width where wider: nothing larger than the page
        tabular = [
            r"\sbox{\slipbox}{%",
            *tabular,
            r"}%",
            r"\ifdim\wd\slipbox>\linewidth\resizebox{\linewidth}{!}{\usebox{\slipbox}}"
            r"\else\usebox{\slipbox}\fi",
        ]
    return "\n".join(
        [
            r"\begin{table}[H]" if page else r"\begin{table}[!htbp]",
            rf"\caption{{{escape(caption)}}}",
            r"\centering",
            *size,
            *tabular,
            *label_,
            *notes,
            r"\end{table}",
        ]
    )


def _superscripted(parts: list[tuple[str, str]]) -> str:
    """A column label of values each with its superscript, one above the other (the rates of
    the paper's Table II, numbered by sensor type)."""
    return _stacked([f"${value}^{{{mark}}}$" for value, mark in parts])


def standalone_latex(body: str) -> str:
    """Wrap tables (:func:`to_latex` with ``page``) in a minimal document that compiles with the
    packages of every LaTeX installation: graphicx (scaled tables, figures), float (tables
    placed under their headings) and longtable (tall tables across pages); and ``\\slipneed``,
    which keeps a heading off a page's foot."""
    return "\n".join(
        [
            r"\documentclass{article}",
            r"\usepackage[utf8]{inputenc}",
            r"\usepackage{graphicx}",
            r"\usepackage{float}",
            r"\usepackage{longtable}",
            r"\newsavebox{\slipbox}",
            # \slipneed{len}: a page break here unless len is left on the page (needspace's
            # definition, without the package: a heading never ends a page its table leaves)
            r"\makeatletter",
            r"\newcommand{\slipneed}[1]{\par\penalty-100\begingroup\setlength{\dimen@}{#1}"
            r"\dimen@ii\pagegoal\advance\dimen@ii-\pagetotal\ifdim\dimen@>\dimen@ii"
            r"\ifdim\dimen@ii>\z@\vfil\fi\penalty-\@M\fi\endgroup}",
            r"\makeatother",
            r"\begin{document}",
            body,
            r"\end{document}",
            "",
        ]
    )


def _one_line(text: str) -> str:
    return " ".join(text.splitlines())


class Latex(Renderer):
    """Tables as floats; headings and paragraphs as comments beside them, or, ``standalone``,
    as a document's sections (each after the first on a new page, so that its floats stay near
    it) and paragraphs; figures as floats of their PDF files (a figure not drawn to a file is
    left out)."""

    name, suffix = "latex", "tex"

    def __init__(self, standalone: bool = False) -> None:
        super().__init__(standalone)
        self.sections = 0  # level-2 headings so far

    def heading(self, block: Heading) -> str:
        if not self.standalone:
            return f"% {_one_line(block.text)}"
        if block.level == 1:
            return rf"{{\LARGE\bfseries {escape(block.text)}\par}}"
        if block.level == 2:  # a section per page: its floats stay near its heading
            self.sections += 1
            return (r"\clearpage" "\n" if self.sections > 1 else "") + (
                rf"\section*{{{escape(block.text)}}}"
            )
        # a heading at a page's foot goes to the next page, with its first table
        return rf"\slipneed{{0.25\textheight}}" "\n" rf"\subsection*{{{escape(block.text)}}}"

    def paragraph(self, block: Text) -> str:
        # a link shows its label: a LaTeX document links no other file
        text = block.text + ("" if block.link is None else block.link.label) + block.after
        return escape(text) if self.standalone else f"% {_one_line(text)}"

    def table(self, block: Table) -> str:
        return to_latex(block, page=self.standalone)

    def figure(self, drawn: Drawn) -> str:
        if ".pdf" not in drawn.paths:
            return ""
        return "\n".join(
            [
                r"\begin{figure}[H]" if self.standalone else r"\begin{figure}[!htbp]",
                r"\centering",
                # a tall figure shrinks to the page rather than run off it
                r"\includegraphics[width=\linewidth,height=0.8\textheight,keepaspectratio]"
                # its stem is file_stem's: letters, digits, dots, hyphens
                rf"{{{drawn.paths['.pdf']}}}",
                rf"\caption{{{escape(drawn.caption)}}}",
                r"\end{figure}",
            ]
        )

    def document(self, parts: list[str]) -> str:
        text = "\n\n".join(parts) + "\n"
        return standalone_latex(text) if self.standalone else text


RENDERER = Latex

__all__ = [
    "LATEX_CHARS",
    "LONG_TABLE_LINES",
    "RENDERER",
    "Latex",
    "escape",
    "latex_cell",
    "latex_lines",
    "standalone_latex",
    "to_latex",
]
