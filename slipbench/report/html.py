"""HTML: one self-contained page from a report's blocks: inline CSS, figures as base64 PNG, no
script and no external resource, so a lab can publish the file as it is."""

from __future__ import annotations

import base64
import html
import re

from slipbench.report.blocks import Heading, Table, Text
from slipbench.report.markdown import md_target
from slipbench.report.render import Drawn, Renderer

CSS = """
body { font: 15px/1.45 system-ui, -apple-system, "Segoe UI", sans-serif; color: #1b1b1b; margin: 0 auto;
       max-width: 72rem; padding: 1rem 1.5rem 4rem; }
h1 { font-size: 1.7rem; margin-bottom: .2rem; }
h2 { font-size: 1.35rem; margin-top: 2.4rem; border-bottom: 1px solid #ccc; padding-bottom: .2rem; }
h3 { font-size: 1.1rem; margin-top: 1.6rem; }
nav ol { columns: 2; font-size: .95rem; }
.table-wrap { overflow-x: auto; margin: 1rem 0 1.4rem; }
table { border-collapse: collapse; font-size: .85rem; font-variant-numeric: tabular-nums; }
caption { caption-side: top; text-align: left; font-weight: 600; padding-bottom: .35rem; max-width: 60rem; }
caption .subject { font-weight: 400; color: #444; }
th, td { border: 1px solid #bbb; padding: .2rem .45rem; }
table.numbers td { text-align: right; white-space: nowrap; }
table.text td { text-align: left; vertical-align: top; }
thead th { background: #f0f0f0; }
tbody th { text-align: left; font-weight: 500; white-space: nowrap; background: #fafafa; }
p.note { font-size: .8rem; color: #444; margin: .25rem 0; max-width: 60rem; }
figure { margin: 1rem 0 1.6rem; }
figure img { width: 100%; max-width: 36rem; height: auto; border: 1px solid #eee; }
figcaption { font-size: .85rem; color: #333; max-width: 36rem; }
"""


def _anchor(text: str, used: set[str]) -> str:
    base = re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-") or "section"
    anchor, n = base, 2
    while anchor in used:
        anchor, n = f"{base}-{n}", n + 1
    used.add(anchor)
    return anchor


def to_html(table: Table) -> str:
    """An HTML ``<table>`` with its caption, the group header over the value columns, one
    ``<th scope="row">`` per row label, and the notes after it."""
    n_rows = len(table.row_headers)
    esc = html.escape
    head = "".join(f'<th scope="col" rowspan="2">{esc(h)}</th>' for h in table.row_headers)
    group = (
        f'<th scope="colgroup" colspan="{len(table.columns)}">{esc(table.group)}</th>'
        if table.group
        else ""
    )
    columns = "".join(f'<th scope="col">{esc(c)}</th>' for c in table.columns)
    if table.group:
        thead = f"<tr>{head}{group}</tr><tr>{columns}</tr>"
    else:
        thead = (
            "<tr>"
            + "".join(f'<th scope="col">{esc(h)}</th>' for h in table.row_headers)
            + columns
            + "</tr>"
        )
    body = []
    for labels, cells in zip(table.rows, table.cells):
        row_heads = "".join(f'<th scope="row">{esc(x)}</th>' for x in labels)
        body.append(f"<tr>{row_heads}" + "".join(f"<td>{esc(c)}</td>" for c in cells) + "</tr>")
    ident = f' id="{esc(table.label)}"' if table.label else ""
    notes = "".join(f'<p class="note">{esc(n)}</p>' for n in table.notes)
    classes = "text" if table.wrap else "numbers"
    return (
        f'<div class="table-wrap"><table class="{classes}"{ident} data-row-headers="{n_rows}">'
        f"<caption>{esc(table.caption)}{f' <span class=subject>{esc(table.subject)}</span>' if table.subject else ''}"
        f"</caption><thead>{thead}</thead><tbody>{''.join(body)}</tbody></table>"
        f"{notes}</div>"
    )


class Html(Renderer):
    """One page: a contents list of the level-2 headings after the title, every table with its
    caption and notes, every figure embedded as PNG (drawn now where it has no file). The page
    keeps every table: it makes no appendix."""

    name, suffix, cross_links, appendix, embeds_figures = "html", "html", True, False, True

    def __init__(self, standalone: bool = False) -> None:
        super().__init__(standalone)  # a page is always whole
        self.used: set[str] = set()  # anchors given so far
        self.contents: list[str] = []
        self.title = "slipbench report"

    def heading(self, block: Heading) -> str:
        anchor = _anchor(block.text, self.used)
        text = html.escape(block.text)
        if block.level == 1:
            self.title = block.text
        elif block.level == 2:
            self.contents.append(f'<li><a href="#{anchor}">{text}</a></li>')
        level = min(block.level, 6)
        return f'<h{level} id="{anchor}">{text}</h{level}>'

    def paragraph(self, block: Text) -> str:
        esc, link = html.escape, block.link
        shown = (
            ""
            if link is None
            else f'<a href="{esc(md_target(link.target))}">{esc(link.label)}</a>'
            if link.target
            else esc(link.label)
        )
        return f"<p>{esc(block.text)}{shown}{esc(block.after)}</p>"

    def table(self, block: Table) -> str:
        return to_html(block)

    def figure(self, drawn: Drawn) -> str:
        png = drawn.png()
        if png is None:
            return ""
        esc, data = html.escape, base64.b64encode(png).decode("ascii")
        return (
            f'<figure id="fig-{esc(drawn.stem)}"><img src="data:image/png;base64,{data}" '
            f'alt="{esc(drawn.caption)}"><figcaption>{esc(drawn.caption)}</figcaption></figure>'
        )

    def document(self, parts: list[str]) -> str:
        body = list(parts)
        if body and body[0].startswith("<h1"):
            body.insert(1, f'<nav aria-label="contents"><ol>{"".join(self.contents)}</ol></nav>')
        return "\n".join(
            [
                "<!DOCTYPE html>",
                '<html lang="en">',
                "<head>",
                '<meta charset="utf-8">',
                '<meta name="viewport" content="width=device-width, initial-scale=1">',
                '<meta name="generator" content="slipbench">',
                f"<title>{html.escape(self.title)}</title>",
                f"<style>{CSS}</style>",
                "</head>",
                "<body>",
                *body,
                "</body>",
                "</html>",
                "",
            ]
        )


RENDERER = Html

__all__ = ["CSS", "RENDERER", "Html", "to_html"]
