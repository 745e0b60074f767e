"""The HTML page: one self-contained file with every table and figure, its structure pinned by a
golden outline; opened in headless Chromium where one is installed."""

from __future__ import annotations

import base64
import json
import shutil
import struct
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import pytest
from goldens import check_golden
from resultgen import all_rows

from slipbench.report.blocks import Table
from slipbench.report.document import build_report, flatten, render
from slipbench.report.plots import FigureSpec

CHROMIUM = next(
    (shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome") if shutil.which(n)),
    None,
)


class Outline(HTMLParser):
    """Headings, tables (id, caption, header and body rows, cells per row) and figures (id, PNG
    size) of a page, and anything that would fetch a resource from outside it."""

    def __init__(self) -> None:
        super().__init__()
        self.items: list[str] = []
        self.external: list[str] = []
        self.images: list[tuple[str, int, int]] = []
        self._text: list[str] | None = None
        self._table: dict | None = None
        self._row: int | None = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag in ("script", "link", "iframe", "object", "embed"):
            self.external.append(tag)
        for key in ("src", "href"):
            value = a.get(key, "")
            if value and not value.startswith(("data:image/png;base64,", "#")):
                self.external.append(value)
        if tag in ("h1", "h2", "h3", "caption", "figcaption"):
            self._text = []
        elif tag == "table":
            self._table = {
                "id": a.get("id", ""),
                "caption": "",
                "head": 0,
                "body": 0,
                "widths": set(),
                "section": "",
            }
        elif tag in ("thead", "tbody") and self._table is not None:
            self._table["section"] = tag
        elif tag == "tr" and self._table is not None:
            self._row = 0
            self._table["head" if self._table["section"] == "thead" else "body"] += 1
        elif tag in ("td", "th") and self._row is not None:
            self._row += int(a.get("colspan", 1))
        elif tag == "img":
            data = (
                base64.b64decode(a["src"].split(",", 1)[1])
                if a.get("src", "").startswith("data:")
                else b""
            )
            ok = data[:8] == b"\x89PNG\r\n\x1a\n"
            width, height = struct.unpack(">II", data[16:24]) if ok else (0, 0)
            self.images.append((a.get("alt", ""), width, height))
            self.items.append(f"img {width}x{height}" if ok else "img BROKEN")

    def handle_endtag(self, tag):
        if tag in ("h1", "h2", "h3") and self._text is not None:
            self.items.append(f"{tag} {''.join(self._text).strip()}")
            self._text = None
        elif tag == "caption" and self._table is not None:
            self._table["caption"] = "".join(self._text or []).strip()
            self._text = None
        elif tag == "figcaption":
            self.items.append(f"figure: {''.join(self._text or []).strip()}")
            self._text = None
        elif tag == "tr" and self._row is not None and self._table is not None:
            if self._table["section"] == "tbody":
                self._table["widths"].add(self._row)
            self._row = None
        elif tag == "table" and self._table is not None:
            t = self._table
            widths = ",".join(map(str, sorted(t["widths"])))
            self.items.append(
                f"table #{t['id']} [{t['head']} head, {t['body']} rows x {widths} cells] {t['caption']}"
            )
            self._table = None

    def handle_data(self, data):
        if self._text is not None:
            self._text.append(data)


def _page(tmp_path: Path) -> tuple[str, list]:
    blocks = flatten(build_report(all_rows(), intervals=True, paper=True, with_figures=True))
    return render(blocks, "html"), blocks


@pytest.mark.slow
def test_page_has_every_table_and_figure_and_nothing_external(tmp_path):
    text, blocks = _page(tmp_path)
    outline = Outline()
    outline.feed(text)
    tables = [b for b in blocks if isinstance(b, Table)]
    figures = [b for b in blocks if isinstance(b, FigureSpec)]
    shown = [i for i in outline.items if i.startswith("table ")]
    assert len(shown) == len(tables) > 20
    for table, item in zip(tables, shown):
        assert (
            item.endswith(f"{table.caption} {table.subject}".strip()) and f"#{table.label} " in item
        )
        assert f"{len(table.rows)} rows" in item
    assert len(outline.images) == len(figures) >= 7
    assert all(w > 300 and h > 200 for _, w, h in outline.images), outline.images
    assert not outline.external, outline.external
    assert text.startswith("<!DOCTYPE html>") and "<nav" in text
    check_golden("report-html.outline", "\n".join(outline.items) + "\n")


def test_report_command_writes_html(tmp_path, cli):
    rows = all_rows().assign(protocol_params="{}")
    folder = tmp_path / "res"
    folder.mkdir()
    rows.to_parquet(folder / "results.parquet")
    code, out, err = cli(
        [
            "report",
            str(folder),
            "--format",
            "html",
            "--leaderboard",
            "--out",
            str(tmp_path / "r.html"),
        ]
    )
    assert code == 0, err
    page = (tmp_path / "r.html").read_text()
    outline = Outline()
    outline.feed(page)
    assert [i for i in outline.items if i.startswith("h2")] == [
        "h2 What this report stands on",
        "h2 Leaderboard",
    ]
    assert len(outline.images) == 1  # the critical-difference diagram


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium installed")
def test_page_opens_in_headless_chromium(tmp_path):
    text, _ = _page(tmp_path)
    page = tmp_path / "report.html"
    page.write_text(text)
    shot = tmp_path / "report.png"
    args = [
        CHROMIUM,
        "--headless=new",
        "--no-sandbox",
        "--disable-gpu",
        "--hide-scrollbars",
        "--enable-logging=stderr",
        "--v=0",
        "--virtual-time-budget=10000",
    ]
    done = subprocess.run(
        [*args, "--window-size=1280,3000", f"--screenshot={shot}", page.as_uri()],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert shot.exists() and shot.stat().st_size > 50_000, done.stderr[-2000:]
    assert "CONSOLE" not in done.stderr, [
        line for line in done.stderr.splitlines() if "CONSOLE" in line
    ]
    # images checked in the browser: a copy of the page reports each image's decoded size
    probe = tmp_path / "probe.html"
    probe.write_text(
        text.replace(
            "</body>",
            "<script>window.addEventListener('load', () => document.body.setAttribute("
            "'data-check', JSON.stringify([...document.images].map(i => i.complete ? i.naturalWidth : 0))))"
            ";</script></body>",
        )
    )
    done = subprocess.run(
        [*args, "--dump-dom", probe.as_uri()], capture_output=True, text=True, timeout=120
    )
    assert "CONSOLE" not in done.stderr
    marker = done.stdout.split('data-check="', 1)[1].split('"', 1)[0].replace("&quot;", '"')
    widths = json.loads(marker)
    assert len(widths) >= 7 and all(w > 300 for w in widths), widths
    import matplotlib.image

    pixels = matplotlib.image.imread(shot)
    assert pixels.std() > 0.05  # not a blank page
