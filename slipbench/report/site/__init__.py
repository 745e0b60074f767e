"""A static results site that opens from ``file://`` with nothing from the network.

Pages: ``index.html`` (a filterable, sortable leaderboard of the latest run and the confirmed
steps, newest first), ``compare.html`` (any two detectors side by side, cell by cell),
``series.html`` (each judged series over commits, its confirmed steps marked, its segments'
means drawn) and, given a results folder, ``report.html`` (the run's report, as ``slipbench
report --format html`` writes it). Plots are plotly's; its JavaScript is written once, in
``assets/plotly.js``, which every page loads by a relative path.

plotly.min.js is 4.8 MB, the whole 5 MB a site of a long history may take; it is kept gzipped
and base64-encoded in ``assets/plotly.js`` (2.0 MB) and inflated in the page by the browser's
own ``DecompressionStream``. A history's points are many more than a page can hold (10,000 runs
x 900 series); each series shows its last ``POINT_BUDGET / series`` runs (at least
``MIN_POINTS``), and its segments' means over the whole history.
"""

from __future__ import annotations

import base64
import gzip
import json
import os
from importlib.resources import files
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from slipbench.atomic import make_folder, write_text_atomic
from slipbench.gate.gate import unit
from slipbench.history.series import POOLED
from slipbench.history.steps import JUDGED, Steps
from slipbench.report.steps import route_of, short_history, verdict_shown
from slipbench.stats.leaderboard import constant_accuracy
from slipbench.store.columns import ACCURACY, CELL_ROLE, ENTRANT, FIGURES, identity
from slipbench.vocabulary import cell_label

#: the points every series page holds together (values and standard errors)
POINT_BUDGET = 100_000
MIN_POINTS = 30
#: a cell (its protocol and key), then the detectors side by side in it
_CELL_ENTRANT = (*identity(CELL_ROLE, named=True), *identity(ENTRANT, named=True))
PAGES = {
    "index.html": "Leaderboard",
    "compare.html": "Side by side",
    "series.html": "Series",
    "report.html": "Report",
}


#: characters that could change how a browser parses a <script> element's text ("</script>"
#: ends it, "<!--<script>" makes the parser hold it open past its end): in JSON strings (the only
#: place JSON holds them) their escapes read back the same
_SCRIPT_ESCAPES = str.maketrans({"<": "\\u003c", ">": "\\u003e", "&": "\\u0026"})


def _script_data(data: dict) -> str:
    """JSON a <script> element holds safely: no ``<``, ``>`` or ``&`` in it at all."""
    return json.dumps(data, separators=(",", ":"), allow_nan=False).translate(_SCRIPT_ESCAPES)


def _page(name: str, about: str, body: str, data: dict, pages: list[str]) -> str:
    links = "".join(
        f'<a href="{p}"{" class=here" if p == name else ""}>{PAGES[p]}</a>' for p in pages
    )
    import html

    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<meta name="generator" content="slipbench">
<title>slipbench · {PAGES[name]}</title>
<link rel="stylesheet" href="assets/site.css">
</head>
<body>
<nav class="site">{links}</nav>
<h1>{PAGES[name]}</h1>
<p class="note">{html.escape(about)}</p>
{body}
<script>window.SITE = {_script_data(data)};</script>
<script src="assets/plotly.js"></script>
<script src="assets/site.js"></script>
</body>
</html>
"""


def plotly_loader() -> str:
    """``assets/plotly.js``: plotly's own JavaScript, gzipped in the file and inflated by the
    browser (module docstring), resolving ``window.plotlyReady`` to ``Plotly``."""
    from plotly.offline import get_plotlyjs

    packed = base64.b64encode(gzip.compress(get_plotlyjs().encode(), 9, mtime=0)).decode()
    return (
        "// plotly.js, gzipped and base64-encoded (slipbench.report.site)\n"
        f'window.plotlyReady = (async () => {{\n  const packed = "{packed}";\n'
        "  const bytes = Uint8Array.from(atob(packed), (c) => c.charCodeAt(0));\n"
        "  const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream('gzip'));\n"
        "  (0, eval)(await new Response(stream).text());\n"
        "  return window.Plotly;\n})();\n"
    )


def _round(x: Any, digits: int = 2) -> float | None:
    return round(float(x), digits) if x is not None and np.isfinite(float(x)) else None


def leaderboard(rows: pd.DataFrame) -> dict:
    """Per protocol and detector of finished cells: cells, and the mean over cells and seeds of
    accuracy, TN rate and TP rate in points; beside them what the constant answer ("never slip"
    or "always slip", whichever scores more on each test set) scores over the rows that give
    their test windows per class, and whether the accuracy there is above it."""
    ok = rows[rows["status"] == "ok"]
    ok = ok.assign(_constant=constant_accuracy(ok)["accuracy"])
    lines = []
    for (protocol, detector), part in ok.groupby(["protocol", "detector"], sort=True):
        means = [
            _round(100 * pd.to_numeric(part[f], errors="coerce").mean())
            for f in JUDGED
            if f in part
        ]
        known = part[part["_constant"].notna()]
        held = known[ACCURACY.name] if ACCURACY.name in known else pd.Series(dtype=float)
        accuracy = float(pd.to_numeric(held, errors="coerce").mean())
        constant = float(known["_constant"].mean()) if len(known) else np.nan
        above = (
            "—" if not np.isfinite(accuracy * constant) else "yes" if accuracy > constant else "no"
        )
        lines.append(
            [protocol, detector, int(part["cell"].nunique()), *means, _round(100 * constant), above]
        )
    columns = [
        "protocol",
        "detector",
        "cells",
        *(f"{FIGURES[f].label} (%)" for f in JUDGED),
        "Constant answer (%)",
        "Accuracy above it",
    ]
    return {"columns": columns, "rows": lines}


def _cells(rows: pd.DataFrame) -> dict:
    """Each finished cell's figures (mean over its seeds, in points) per detector, the cell
    named by its short label (:func:`slipbench.vocabulary.cell_label`)."""
    ok = rows[rows["status"] == "ok"]
    figures = [f for f in JUDGED if f in ok]
    cells = []
    for (protocol, cell, detector), part in ok.groupby(list(_CELL_ENTRANT), sort=True):
        cells.append(
            [protocol, cell_label(str(cell)), detector]
            + [_round(100 * pd.to_numeric(part[f], errors="coerce").mean()) for f in figures]
        )
    return {
        "figures": figures,
        "detectors": sorted(ok["detector"].astype(str).unique()),
        "cells": cells,
    }


def _step_rows(found: Steps) -> dict:
    confirmed = found.confirmed.sort_values("run", ascending=False)
    columns = [
        "commit",
        "date",
        "verdict",
        "figure",
        "series",
        "change (interval)",
        "what changed",
        "judged",
    ]
    rows = [
        [
            r["commit"],
            r["date"],
            verdict_shown(r),
            FIGURES[r["figure"]].label,
            r["series_label"],
            f"{r['change']:+.2f} [{r['change_lo']:+.2f}, {r['change_hi']:+.2f}] {unit(r['figure'])}",
            r["what_changed"],
            route_of(r),
        ]
        for r in confirmed.to_dict("records")
    ]
    ids = [f"{r['figure']}-{r['series']}" for r in confirmed.to_dict("records")]
    return {
        "columns": columns,
        "rows": rows,
        "link": {"column": 4, "href": "series.html#", "ids": ids},
        "none": short_history(found)
        or f"No confirmed step in {len(found.runs)} runs and {found.series} series.",
    }


#: the commits named on a plot's x axis at most (every step's commit besides)
MAX_TICKS = 12


def _ticks(runs: pd.DataFrame, shown: list[int], marked: list[int]) -> dict:
    """An x axis of runs named by commit and date: evenly spread over ``shown``, and every
    run in ``marked``."""
    picked = set(marked)
    if shown:
        step = max(1, -(-len(shown) // MAX_TICKS))
        picked |= set(shown[::step]) | {shown[-1]}
    vals = sorted(int(r) for r in picked if 0 <= r < len(runs))
    text = [f"{runs['commit'].iloc[r]}<br>{str(runs['date'].iloc[r])[:10]}" for r in vals]
    return {"tickvals": vals, "ticktext": text}


def _overview(found: Steps) -> list[dict]:
    """Per protocol, each detector's mean over the protocol's cells (the pooled series) of
    the first judged figure over commits, and every confirmed step of the protocol's series
    (cells' and pooled) marked at its commit: what a reviewer reads first."""
    pts = found.points
    if pts.empty:
        return []
    figure = next(f for f in JUDGED if f in set(pts["figure"]))
    pooled = pts[(pts["kind"] == "pooled") & (pts["figure"] == figure)]
    suffix = f" · {POOLED}"
    out = []
    parts = pooled["series_label"].str.removesuffix(suffix).str.split(" · ", n=1)
    by_protocol = pooled.assign(protocol=parts.str[0], detector=parts.str[1]).groupby("protocol")
    keep = max(MIN_POINTS, POINT_BUDGET // max(1, pooled["series"].nunique()))
    for protocol, part in by_protocol:
        traces = []
        for detector, one in part.groupby("detector", sort=True):
            one = one.sort_values("run").tail(keep)
            traces.append(
                {
                    "name": detector,
                    "x": [int(r) for r in one["run"]],
                    "y": [_round(v * FIGURES[figure].scale) for v in one["value"]],
                }
            )
        mine = found.confirmed[found.confirmed["series_label"].str.startswith(f"{protocol} · ")]
        steps = [
            {
                "run": int(run),
                "commit": str(found.runs["commit"].iloc[int(run)]),
                "regressed": int((g["verdict"] == "regressed").sum()),
                "improved": int((g["verdict"] == "improved").sum()),
                "judged": "; ".join(sorted({route_of(r) for r in g.to_dict("records")})),
            }
            for run, g in mine.groupby("run")
        ]
        shown = sorted({x for t in traces for x in t["x"]})
        out.append(
            {
                "protocol": protocol,
                "figure": f"{FIGURES[figure].label} ({unit(figure)}), mean over cells",
                "traces": traces,
                "steps": steps,
                "axis": _ticks(found.runs, shown, [int(r) for r in mine["run"].unique()]),
            }
        )
    return out


def _segments(pts: pd.DataFrame, runs: list[int]) -> list[list]:
    """Each stretch between confirmed steps: its first and last run and its weighted mean."""
    edges = [pts["run"].min(), *sorted(runs), pts["run"].max() + 1]
    out = []
    for lo, hi in zip(edges, edges[1:]):
        part = pts[(pts["run"] >= lo) & (pts["run"] < hi)]
        if part.empty:
            continue
        w = 1 / np.maximum(part["se"].to_numpy(float), 1e-9) ** 2
        mean = float(np.sum(w * part["value"].to_numpy(float)) / np.sum(w))
        out.append([int(part["run"].min()), int(part["run"].max()), _round(mean)])
    return out


def _series(found: Steps) -> dict:
    """Every judged series: its last points, segments and confirmed steps (values in the
    figure's units, points for rates)."""
    pts = found.points.copy()
    scale = pts["figure"].map(lambda f: FIGURES[f].scale).to_numpy(float)
    pts["value"], pts["se"] = pts["value"] * scale, pts["se"] * scale
    # grouped by the (categorical) texts, named once per series rather than once per point
    by = pts.groupby(["figure", "series"], sort=False, observed=True)
    groups = {f"{figure}-{series}": part for (figure, series), part in by}
    keep = max(MIN_POINTS, POINT_BUDGET // max(1, len(groups)))
    steps = {
        k: g
        for k, g in found.confirmed.assign(id=lambda s: s["figure"] + "-" + s["series"]).groupby(
            "id"
        )
    }
    out = []
    for sid, part in groups.items():
        part = part.sort_values("run")
        mine = steps.get(sid, pd.DataFrame(columns=["run", "verdict", "change"]))
        shown = part.tail(keep)
        figure, kind = part["figure"].iloc[0], part["kind"].iloc[0]
        out.append(
            {
                "id": sid,
                "label": part["series_label"].iloc[0],
                "figure": FIGURES[figure].label,
                "unit": unit(figure),
                "about": (
                    f"{FIGURES[figure].label} of {'the mean over the cells of ' if kind == 'pooled' else ''}"
                    f"{part['series_label'].iloc[0]}: {len(part)} runs, the last {len(shown)} shown "
                    "with 95 % intervals; lines: each stretch's weighted mean between confirmed steps."
                ),
                "points": [
                    [int(r), _round(v), _round(s, 3)]
                    for r, v, s in zip(shown["run"], shown["value"], shown["se"])
                ],
                "segments": _segments(part, list(mine["run"])),
                "axis": _ticks(found.runs, [int(r) for r in shown["run"]], list(mine["run"])),
                "steps": [
                    {
                        "run": int(r["run"]),
                        "verdict": r["verdict"],
                        "change": f"{r['change']:+.2f} {unit(figure)}",
                    }
                    for r in mine.to_dict("records")
                ],
            }
        )
    out.sort(key=lambda s: (-len(s["steps"]), s["figure"], s["label"]))
    return {"series": out, "runs": _runs(found)}


def _runs(found: Steps) -> list[list[str]]:
    """Each run's commit and date, oldest first: a run holding rows that entered unproven is
    named so wherever a point shows its commit."""
    commits = [
        f"{c} (unproven)" if n else c for c, n in zip(found.runs["commit"], found.runs["unproven"])
    ]
    return [[c, d] for c, d in zip(commits, found.runs["date"])]


BODIES = {
    "index.html": '<div id="protocols"></div>\n<h2>Latest run</h2>\n'
    '<div class="controls"><label>Filter <input id="filter" type="search" '
    'placeholder="protocol, detector, commit"></label></div>\n<div id="leaderboard"></div>\n'
    '<div id="overview" class="plot"></div>\n<h2>Confirmed steps, newest first</h2>\n'
    '<div id="steps"></div>',
    "compare.html": '<div class="controls"><label>Left <select id="left"></select></label>'
    '<label>Right <select id="right"></select></label><label>Figure <select id="figure">'
    '</select></label></div>\n<p class="note" id="shared"></p>\n'
    '<div id="difference" class="plot"></div>\n<div id="pairs"></div>',
    "series.html": '<div class="controls"><label>Filter <input id="filter" type="search" '
    'placeholder="detector, cell, figure"></label><label>Series <select id="series"></select>'
    '</label></div>\n<p class="note" id="about"></p>\n<div id="plot" class="plot"></div>',
}


def write_site(
    out: str | os.PathLike,
    latest: pd.DataFrame,
    found: Steps | None = None,
    report: str | None = None,
    about: str = "",
) -> list[Path]:
    """Write the site's pages into ``out``; returns the files written.

    Parameters
    ----------
    latest : the result rows of the run the leaderboard and side by side pages show.
    found : a history's steps (:func:`slipbench.history.steps.find_steps`): the series page and
        the steps on the index; None for one results folder.
    report : the run's report as one HTML page (``report.html``), where there is one.
    about : what the pages stand on, said under each title.
    """
    out = make_folder(out)
    pages = [
        "index.html",
        "compare.html",
        *(["series.html"] if found else []),
        *(["report.html"] if report else []),
    ]
    none = {"columns": [], "rows": [], "none": "No history given: no steps."}
    data = {
        "index.html": {
            "page": "index",
            "leaderboard": leaderboard(latest),
            "steps": _step_rows(found) if found else none,
            "protocols": _overview(found) if found else [],
            "runs": _runs(found) if found else [],
        },
        "compare.html": {"page": "compare", **_cells(latest)},
        **({"series.html": {"page": "series", **_series(found)}} if found else {}),
    }
    assets = make_folder(out / "assets")
    written = []
    for name, text in (
        ("plotly.js", plotly_loader()),
        *(
            (n, files("slipbench.report.site").joinpath(n).read_text())
            for n in ("site.js", "site.css")
        ),
    ):
        write_text_atomic(assets / name, text)
        written.append(assets / name)
    for name, page_data in data.items():
        write_text_atomic(out / name, _page(name, about, BODIES[name], page_data, pages))
        written.append(out / name)
    if report:
        write_text_atomic(out / "report.html", report)
        written.append(out / "report.html")
    return written
