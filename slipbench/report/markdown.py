"""Markdown: a report as GitHub and mkdocs show it, every text from the data escaped so that it
shows as it is (a name holding ``|`` adds no table cell, ``<script>`` stays text)."""

from __future__ import annotations

import re
from urllib.parse import quote

import pandas as pd

from slipbench.report.blocks import Heading, Table, Text
from slipbench.report.render import Drawn, Renderer

# what Markdown reads as markup inside a line: code, emphasis, links, HTML, tables, entities
MD_MARKUP = re.compile(r"([\\`*_\[\]<>|#~&])")
# what it reads as markup at a line's start: lists, quotes, headings, rules, setext underlines
MD_LINE_START = re.compile(r"^(\s*)([-+=>]|\d+(?=[.)]))")


def md_text(text: object, paragraph: bool = False) -> str:
    """Plain text as Markdown that shows it as it is, on one line: every character Markdown
    reads as markup backslash-escaped (so a name holding ``|`` adds no table cell, and
    ``<script>`` or ``[x](javascript:...)`` stays text), line breaks made spaces. A
    ``paragraph`` starts a line: a list, quote or heading marker there is escaped too."""
    escaped = MD_MARKUP.sub(r"\\\1", " ".join(str(text).splitlines()))
    if not paragraph:
        return escaped
    return MD_LINE_START.sub(
        lambda m: f"{m[1]}{m[2]}\\" if m[2][0].isdigit() else f"{m[1]}\\{m[2]}", escaped
    )


def md_code(text: object) -> str:
    """Text as one Markdown code span, whatever backticks it holds (its fence is longer than
    any run of them inside), on one line."""
    one_line = " ".join(str(text).splitlines())
    fence = "`" * (max((len(r) for r in re.findall(r"`+", one_line)), default=0) + 1)
    pad = " " if one_line.startswith("`") or one_line.endswith("`") else ""
    return f"{fence}{pad}{one_line}{pad}{fence}"


def md_target(target: str) -> str:
    """A link target the report makes (a relative path and anchor) as Markdown takes it:
    percent-encoded, and never read as a scheme (``javascript:`` becomes ``./javascript:``)."""
    if re.match(r"[A-Za-z][A-Za-z0-9+.-]*:", target):
        target = "./" + target
    return quote(target, safe="/#.-_~")


def md_table(header: list[str], rows: list[list[str]], align: str = "right") -> str:
    """A pipe table of plain texts: each escaped (:func:`md_text`), so every row keeps the
    header's number of cells."""
    frame = pd.DataFrame(
        [[md_text(c) for c in row] for row in rows], columns=[md_text(h) for h in header]
    )
    return frame.to_markdown(index=False, stralign=align, disable_numparse=True)


def to_markdown(table: Table) -> str:
    """Markdown: caption in bold, one pipe table, notes in italics; every text escaped."""
    body = md_table(
        [*table.row_headers, *table.columns],
        [[*r, *c] for r, c in zip(table.rows, table.cells)],
        "left" if table.wrap else "right",
    )
    rest = (f" {table.group}." if table.group else "") + (
        f" {table.subject}" if table.subject else ""
    )
    parts = [f"**{md_text(table.caption)}**{md_text(rest)}", "", body]
    parts += [""] + [f"_{md_text(n)}_" for n in table.notes] if table.notes else []
    return "\n".join(parts)


class Markdown(Renderer):
    """Headings as ``#``, tables as pipe tables, figures as images of their PNG files with the
    caption under them (a figure not drawn to a file is left out), links to another file's
    sections."""

    name, suffix, cross_links = "md", "md", True

    def heading(self, block: Heading) -> str:
        return "#" * block.level + " " + md_text(block.text)

    def paragraph(self, block: Text) -> str:
        link = block.link
        shown = (
            ""
            if link is None
            else f"[{md_text(link.label)}]({md_target(link.target)})"
            if link.target
            else md_text(link.label)
        )
        return md_text(block.text, paragraph=True) + shown + md_text(block.after)

    def table(self, block: Table) -> str:
        return to_markdown(block)

    def figure(self, drawn: Drawn) -> str:
        if ".png" not in drawn.paths:
            return ""
        caption = md_text(drawn.caption)
        return f"![{caption}]({md_target(drawn.paths['.png'])})\n\n_{caption}_"

    def document(self, parts: list[str]) -> str:
        return "\n\n".join(parts) + "\n"


RENDERER = Markdown

__all__ = ["RENDERER", "Markdown", "md_code", "md_table", "md_target", "md_text", "to_markdown"]
