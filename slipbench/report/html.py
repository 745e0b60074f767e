"""One self-contained HTML page from a report's blocks: inline CSS, figures as base64 PNG, no
script and no external resource, so a lab can publish the file as it is."""

from __future__ import annotations

import html
import re
from typing import Any

from slipbench.report.render import md_target, to_html

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


def page(parts: list[tuple[str, Any]]) -> str:
    """An HTML document from (kind, block) pairs: ``heading``, ``text``, ``table`` blocks of
    :mod:`slipbench.report.document`, and ``figure`` as (stem, caption, base64 PNG). A contents list of
    the level-2 headings follows the title."""
    esc = html.escape
    used: set[str] = set()
    body, contents, title = [], [], "slipbench report"
    for kind, block in parts:
        if kind == "heading":
            anchor = _anchor(block.text, used)
            if block.level == 1:
                title = block.text
            elif block.level == 2:
                contents.append(f'<li><a href="#{anchor}">{esc(block.text)}</a></li>')
            level = min(block.level, 6)
            body.append(f'<h{level} id="{anchor}">{esc(block.text)}</h{level}>')
        elif kind == "text":
            link = block.link
            shown = (
                ""
                if link is None
                else f'<a href="{esc(md_target(link.target))}">{esc(link.label)}</a>'
                if link.target
                else esc(link.label)
            )
            body.append(f"<p>{esc(block.text)}{shown}{esc(block.after)}</p>")
        elif kind == "table":
            body.append(to_html(block))
        elif kind == "figure":
            stem, caption, data = block
            body.append(
                f'<figure id="fig-{esc(stem)}"><img src="data:image/png;base64,{data}" alt="{esc(caption)}">'
                f"<figcaption>{esc(caption)}</figcaption></figure>"
            )
    if body and body[0].startswith("<h1"):
        body.insert(1, f'<nav aria-label="contents"><ol>{"".join(contents)}</ol></nav>')
    return "\n".join(
        [
            "<!DOCTYPE html>",
            '<html lang="en">',
            "<head>",
            '<meta charset="utf-8">',
            '<meta name="viewport" content="width=device-width, initial-scale=1">',
            '<meta name="generator" content="slipbench">',
            f"<title>{esc(title)}</title>",
            f"<style>{CSS}</style>",
            "</head>",
            "<body>",
            *body,
            "</body>",
            "</html>",
            "",
        ]
    )
