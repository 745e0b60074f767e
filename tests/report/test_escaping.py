"""Names from the data and the results (units, materials, scenarios, detector and protocol ids,
parameters, dataset paths) through every report format: each Markdown table row keeps its
header's cell count, and nothing executable survives in Markdown, HTML or LaTeX (issue 33)."""

from __future__ import annotations

import json
import re
from html.parser import HTMLParser

import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from markdown_it import MarkdownIt
from resultgen import fake_rows

from slipbench.gate.compare import compare
from slipbench.report.compare import comment_markdown
from slipbench.report.document import build_report, render
from slipbench.report.latex import LATEX_CHARS, escape

HOSTILE = [
    "a|b",
    "<script>alert(1)</script>",
    "[x](javascript:alert(1))",
    "x\n# heading\n|c|d|",
    "`code` **b** _i_ ~s~",
    r"\input{/etc/passwd} 100% & $x$ #1 ~^{}",
    '<img src=x onerror="alert(1)">',
    "- item\r\n> quote",
]
# where a name goes in the rows: unit, finger, material, detector, protocol, dataset path, a
# skipped cell's reason (a scenario), a parameter's value
SLOTS = (
    "sensor_type",
    "sensor_instance",
    "material",
    "detector",
    "protocol",
    "path",
    "scenario",
    "param",
)


def rows_named(names: list[str]) -> pd.DataFrame:
    """Material-holdout and window-size rows (one unit type, two fingers, two detectors, one
    of them named from the data) with the names in SLOTS; the window-size rows under the
    protocol name from the data (a protocol no registry knows: laid out from its cell keys)."""
    name = dict(zip(SLOTS, names))
    parts = []
    for protocol in ("material-holdout", "window-size"):
        for detector in ("holweg", name["detector"]):
            rows = fake_rows(protocol, detector)
            rows = rows[
                rows["sensor_type"].eq("Nano17") & rows["sensor_instance"].isin(["index", "middle"])
            ]
            if protocol == "window-size":
                rows = rows[rows["window"].isin([5, 50])].assign(protocol=name["protocol"])
            else:
                rows = rows[rows["material"].isin(["aluminum", "PVC"])]
                rows = rows.assign(material=rows["material"].replace("aluminum", name["material"]))
            rows = rows.assign(
                sensor_type=name["sensor_type"],
                sensor_instance=rows["sensor_instance"].replace("index", name["sensor_instance"]),
                dataset_path=name["path"],
                detector_params=json.dumps({"band": name["param"]}),
                key=rows["key"] + f"-{protocol}",
            )
            keys = [
                c
                for c in ("sensor_type", "sensor_instance", "material", "training", "window")
                if c in rows
            ]
            rows["cell"] = [
                json.dumps(dict(zip(keys, v))) for v in rows[keys].itertuples(index=False)
            ]
            parts.append(rows)
    out = pd.concat(parts, ignore_index=True)
    out.loc[0, ["status", "reason"]] = ["skipped", f"no windows of scenario {name['scenario']}"]
    return out


# ----------------------------------------------------------------------------- the checks
UNESCAPED_PIPE = re.compile(r"(?<!\\)(?:\\\\)*\|")


def check_markdown(text: str) -> None:
    """Every pipe table's rows have its header's cells (escaped pipes aside), and the text
    renders (CommonMark with tables) to HTML holding no raw HTML, no script and no link."""
    table: list[int] = []
    for line in [*text.splitlines(), ""]:
        if line.startswith("|"):
            table.append(len(UNESCAPED_PIPE.findall(line)))
        elif table:
            assert len(set(table)) == 1, f"a table row has another cell count: {table}"
            table = []
    md = MarkdownIt("commonmark").enable("table")
    tokens = md.parse(text)
    kinds = {t.type for t in tokens} | {c.type for t in tokens for c in t.children or []}
    assert not kinds & {"html_block", "html_inline"}, "raw HTML passed through"
    check_html(md.render(text), allowed=MD_TAGS)


MD_TAGS = {
    "h1", "h2", "h3", "p", "strong", "em", "code", "table", "thead", "tbody", "tr", "th", "td", "ul", "li",
}  # fmt: skip
PAGE_TAGS = MD_TAGS | {
    "html",
    "head",
    "meta",
    "title",
    "style",
    "body",
    "nav",
    "ol",
    "a",
    "div",
    "caption",
    "span",
}


class _Tags(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.tags: list[tuple[str, list]] = []
        self.rows: list[list[int]] = []  # per table, the cells of each body row

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, attrs))
        if tag == "table":
            self.rows.append([])
        elif tag == "tr" and self.rows:
            self.rows[-1].append(0)
        elif tag in ("td", "th") and self.rows and self.rows[-1]:
            self.rows[-1][-1] += 1


def check_html(text: str, allowed: set[str]) -> None:
    parser = _Tags()
    parser.feed(text)
    for tag, attrs in parser.tags:
        assert tag in allowed, f"tag <{tag}> from the data"
        for name, value in attrs:
            assert not name.startswith("on"), f"event handler {name}"
            if name in ("href", "src"):
                assert re.match(r"(#|data:image/png;base64,|[\w./%-]+(#|$))", value or ""), value


def check_page(text: str) -> None:
    check_html(text, PAGE_TAGS)
    parser = _Tags()
    parser.feed(text)
    for rows in parser.rows:  # the body rows of a table: each as many cells as the next
        body = rows[2:] if len(rows) > 2 else rows
        assert len(set(body)) <= 1, f"a table row has another cell count: {rows}"


LATEX_TOKEN = re.compile(r"\\(?:[A-Za-z]+|.)|[{}&%$]|[^\\{}&%$]+", re.S)


def check_latex(text: str, benign: str) -> None:
    """No command the benign names' report lacks; braces balanced; every tabular row with its
    columns' ``&``; no ``%`` or ``$`` from the data."""
    escapes = escape("".join(LATEX_CHARS))  # what escaping itself writes
    commands = {t for t in LATEX_TOKEN.findall(benign + escapes) if t.startswith("\\")}
    depth = 0
    for token in LATEX_TOKEN.findall(text):
        if token.startswith("\\"):
            assert token in commands, f"command {token!r} from the data"
        depth += {"{": 1, "}": -1}.get(token, 0)
        assert depth >= 0, "a closing brace from the data"
    assert depth == 0
    tokens = LATEX_TOKEN.findall(text)
    assert tokens.count("%") == LATEX_TOKEN.findall(benign).count("%"), "a comment from the data"
    assert tokens.count("$") % 2 == 0, "math mode left open"
    for spec, body in re.findall(
        r"\\begin\{tabular\}\{(\|[cl|]+)\}\n(.*?)\\end\{tabular\}", text, re.S
    ):
        for line in body.splitlines():
            if line.endswith("\\\\") and "\\multicolumn" not in line:
                flat = re.sub(r"\\begin\{tabular\}.*?\\end\{tabular\}", "x", line)
                cells = [t for t in LATEX_TOKEN.findall(flat) if t == "&"]
                assert len(cells) == spec.count("c") + spec.count("l") - 1, line


def check_every_format(names: list[str], tmp_path) -> None:
    rows = rows_named(names)
    benign = rows_named([f"n{i}" for i in range(len(names))])
    blocks = build_report(rows, paper=True)
    check_markdown(render(blocks, "md"))
    check_page(render(blocks, "html"))
    check_latex(
        render(blocks, "latex", standalone=True),
        render(build_report(benign, paper=True), "latex", standalone=True),
    )
    base, cand = tmp_path / "base.parquet", tmp_path / "cand.parquet"
    rows.to_parquet(base)
    rows.assign(accuracy=rows["accuracy"] - 0.2, key=rows["key"] + "c").to_parquet(cand)
    check_markdown(comment_markdown(compare(base, cand), max_rows=100))


@pytest.mark.slow
def test_hostile_names_through_every_format(tmp_path):
    check_every_format(HOSTILE, tmp_path)


CHARACTER = st.characters(codec="utf-8", exclude_categories=("Cs",)) | st.sampled_from(
    list("|<>[]()`*_#~&\\{}%$^!\n\r\t-+=.:")
)
NAME = st.lists(
    st.text(CHARACTER, min_size=1, max_size=4)
    | st.sampled_from(["javascript:", "<script>", "\\input"]),
    min_size=1,
    max_size=4,
).map("".join)


@pytest.mark.slow  # a whole report and a compare per example
@settings(
    max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(names=st.lists(NAME, min_size=len(SLOTS), max_size=len(SLOTS), unique=True))
def test_any_names_through_every_format(names, tmp_path):
    reserved = {"index", "middle", "PVC", "holweg", "material-holdout", "window-size"}
    if any(n.strip() in reserved or not n.strip() for n in names):
        return  # a name that is another value's: the rows would merge, not the point here
    check_every_format(names, tmp_path)
