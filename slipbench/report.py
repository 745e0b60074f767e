"""Result rows -> the paper's tables, in Markdown or LaTeX, optionally beside the paper's numbers.

Reads only result rows (``slipbench.results.read_results``). Every table is first built as a
:class:`Table` (row labels, column labels, cell texts), then rendered by :func:`to_markdown` or
:func:`to_latex`, so both formats always carry the same rows and columns.

Layouts follow Van Wyk & Falco: window size (Table I), sampling rate with its per-sensor rate
header (Table II), material and speed with two numbers per cell, the second starred for
"without explicit training" (Tables III and IV), training instance by test instance (Table V),
the Holweg baseline beside other detectors at window 50, and TP/TN rates per sensor type.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from functools import cache
from importlib import resources
from typing import Any

import numpy as np
import pandas as pd

SENSOR_NAMES = {"Nano17": "Nano17", "OptoForce20": "OptoForce20", "BioTacSP": "Biotac SP"}
SENSOR_ORDER = ("Nano17", "OptoForce20", "BioTacSP")
INSTANCE_ORDER = ("index", "middle", "little", "combined")
MATERIAL_ORDER = ("aluminum", "PVC", "neoprene", "cardboard", "plywood")
PROTOCOL_ORDER = ("window-size", "sampling-rate", "material-holdout", "speed-holdout", "cross-instance")
METRIC_NAMES = {
    "accuracy": "Classification Accuracy", "tp_rate": "TP Rate", "tn_rate": "TN Rate",
    "balanced_accuracy": "Balanced Accuracy", "auroc": "AUROC",
}
BASELINE_WINDOW = 50  # the paper's reference window for the Holweg baseline and the TP/TN rates


# ----------------------------------------------------------------------------- layouts
@dataclass(frozen=True)
class Layout:
    """How one protocol's cells make a table.

    ``rows`` and ``column`` are result columns; ``pair`` is a column with values "with" and
    "without" whose two results share one cell ("with without*"); ``split`` gives one table
    per value (sampling rate: plain and anti-aliased decimation).
    """

    caption: str
    group: str  # header over the value columns, after the metric name
    rows: tuple[str, ...]
    column: str
    pair: str | None = None
    split: str | None = None
    merge_rows: bool = False  # one label column "Nano17, Index" (Table V) instead of two


LAYOUTS: dict[str, Layout] = {
    "window-size": Layout(
        "Slip state classification at various window sizes across three types of sensors and fingers.",
        "at Window Size", ("sensor_type", "sensor_instance"), "window"),
    "sampling-rate": Layout(
        "Slip state classification at various sampling rates (Hz) across sensors and fingers, window 200 "
        "downsampled. Superscripts indicate the sensor type for the selected sampling rate.",
        "at Sampling Rate", ("sensor_type", "sensor_instance"), "downsample", split="decimation"),
    "material-holdout": Layout(
        "Slip state classification with and without (*) explicit training of indicated materials across sensors.",
        "with Material", ("sensor_type", "sensor_instance"), "material", pair="training"),
    "speed-holdout": Layout(
        "Slip state classification with and without (*) explicit training of indicated speeds across sensors.",
        "at Speed", ("sensor_type", "sensor_instance"), "speed_mm_s", pair="training"),
    "cross-instance": Layout(
        "Classification trained and tested on data from one or all fingers of a single sensor type.",
        "", ("sensor_type", "train_instance"), "test_instance", merge_rows=True),
}
ROW_HEADERS = {"sensor_type": "Sensor", "sensor_instance": "Finger", "train_instance": "Training Data"}


@dataclass
class Table:
    """A rendered-format-independent table: labels and cell texts."""

    caption: str
    row_headers: list[str]
    group: str  # header spanning the value columns
    columns: list[str]  # plain-text column labels (Markdown)
    rows: list[tuple[str, ...]]
    cells: list[list[str]]
    label: str
    latex_columns: list[str] | None = None  # LaTeX column labels where they differ from ``columns``
    notes: list[str] = field(default_factory=list)


# ----------------------------------------------------------------------------- ordering and labels
def _rank(values: Iterable[Any], order: Sequence[Any] = ()) -> list[Any]:
    """Known values in ``order`` first, then numbers ascending, then the rest alphabetically."""
    def key(v):
        if v in order:
            return (0, order.index(v), "")
        try:
            return (1, float(v), "")
        except (TypeError, ValueError):
            return (2, 0.0, str(v))
    return sorted(set(values), key=key)


ORDERS: dict[str, Sequence[Any]] = {
    "sensor_type": SENSOR_ORDER, "sensor_instance": INSTANCE_ORDER, "train_instance": INSTANCE_ORDER,
    "test_instance": INSTANCE_ORDER, "material": MATERIAL_ORDER,
}


def _ordered(values: Iterable[Any], column: str) -> list[Any]:
    out = _rank(values, ORDERS.get(column, ()))
    return out[::-1] if column == "downsample" else out  # the paper puts the lowest rate first


def label(column: str, value: Any) -> str:
    """How a key value reads in a table."""
    if column == "sensor_type":
        return SENSOR_NAMES.get(value, str(value))
    if column in ("sensor_instance", "train_instance", "test_instance", "material"):
        text = str(value)
        return text if text.isupper() else text.capitalize()
    if column == "speed_mm_s":
        return f"{float(value):g} mm/s"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def _as_printed(percent: float) -> str:
    """One decimal, or two where the paper printed two (its TN rate 89.79)."""
    return f"{percent:.1f}" if abs(percent - round(percent, 1)) < 1e-9 else f"{percent:.2f}"


def _rate(value: float) -> str:
    return f"{value:.2f}".rstrip("0").rstrip(".")


# ----------------------------------------------------------------------------- figures per cell
def summarize(rows: pd.DataFrame, keys: list[str], metric: str = "accuracy") -> pd.DataFrame:
    """One line per combination of ``keys``: the mean of ``metric`` over seeds (``--repeats``),
    its standard deviation across seeds, the number of seeds, the mean interval bounds, and a
    status ("ok", or the status of the cell when no seed finished)."""
    if metric not in rows.columns:
        rows = rows.assign(**{metric: np.nan})
    lo_col, hi_col = f"{metric}_lo", f"{metric}_hi"
    out = []
    for values, group in rows.groupby(keys, sort=False, dropna=False):
        ok = group[group["status"] == "ok"] if "status" in group else group
        vals = ok[metric].astype(float)
        out.append({
            **dict(zip(keys, values if isinstance(values, tuple) else (values,))),
            "mean": vals.mean() if len(vals) else np.nan,
            "sd": vals.std(ddof=1) if len(vals) > 1 else np.nan,
            "n": len(vals),
            "lo": ok[lo_col].astype(float).mean() if lo_col in ok and len(ok) else np.nan,
            "hi": ok[hi_col].astype(float).mean() if hi_col in ok and len(ok) else np.nan,
            "status": "ok" if len(ok) else str(group["status"].iloc[0]),
        })
    return pd.DataFrame(out, columns=[*keys, "mean", "sd", "n", "lo", "hi", "status"])


def figure_text(mean: float, sd: float = np.nan, n: int = 1, lo: float = np.nan, hi: float = np.nan,
                status: str = "ok", intervals: bool = False) -> str:
    """``88.0``; ``88.0 ± 0.4`` over seeds; ``88.0 [86.9, 89.1]`` with intervals; 'NA' if absent."""
    if status != "ok":
        return status
    if pd.isna(mean):
        return "NA"
    text = f"{100 * mean:.1f}"
    if n > 1 and not pd.isna(sd):
        text += f" ± {100 * sd:.1f}"
    if intervals and not (pd.isna(lo) or pd.isna(hi)):
        text += f" [{100 * lo:.1f}, {100 * hi:.1f}]"
    return text


# ----------------------------------------------------------------------------- the paper's numbers
@cache
def paper_data() -> dict[str, Any]:
    """The published numbers of Van Wyk & Falco (package data ``slipbench/paper/van_wyk_falco.json``)."""
    text = resources.files("slipbench").joinpath("paper", "van_wyk_falco.json").read_text()
    return json.loads(text)


def paper_frame(name: str) -> pd.DataFrame:
    """One published table as rows, values as fractions (0.880 for 88.0 %).

    ``name`` is a protocol (``window-size``, ``sampling-rate``, ``material-holdout``,
    ``speed-holdout``, ``cross-instance``), ``holweg`` or ``rates_window_50``. The sampling-rate
    table gains the full-rate column (downsample 1) from Table I at window 200, the same setting.
    """
    data = paper_data()
    spec = data["tables"].get(name) or data.get(name)
    if spec is None:
        return pd.DataFrame()
    frame = pd.DataFrame(spec["rows"], columns=spec["columns"])
    for col in ("accuracy", "tp_rate", "tn_rate"):
        if col in frame:
            frame[col] = frame[col] / 100
    if name == "sampling-rate":
        full = paper_frame("window-size").query("window == 200").drop(columns="window")
        full = full.assign(downsample=1, rate_hz=full["sensor_type"].map({"BioTacSP": 850.0}).fillna(1000.0))
        frame = pd.concat([frame, full[frame.columns]], ignore_index=True)
    return frame


# ----------------------------------------------------------------------------- building tables
def _key_columns(rows: pd.DataFrame) -> list[str]:
    """The cell-key columns of rows (from their ``cell`` JSON), in first-seen order."""
    keys: list[str] = []
    for text in rows["cell"].dropna().unique() if "cell" in rows else ():
        for k in json.loads(text):
            if k not in keys:
                keys.append(k)
    return keys


def layout_for(rows: pd.DataFrame, protocol: str, fallback: dict | None = None) -> Layout:
    """The paper layout of a known protocol, else the protocol's own ``table`` dict, else the
    cell keys: all but the last as rows, the last as columns."""
    if protocol in LAYOUTS:
        return LAYOUTS[protocol]
    if fallback and fallback.get("rows") and fallback.get("columns"):
        return Layout(fallback.get("title", protocol), "", tuple(fallback["rows"]), fallback["columns"])
    keys = [k for k in _key_columns(rows) if k in rows] or ["protocol"]
    if len(keys) == 1:
        return Layout(f"Protocol {protocol}.", "", tuple(keys), "detector")
    return Layout(f"Protocol {protocol}.", "", tuple(keys[:-1]), keys[-1])


def _column_labels(layout: Layout, rows: pd.DataFrame, columns: list[Any]) -> tuple[list[str], list[str], list[str]]:
    """Plain and LaTeX column labels, and notes. Sampling rate: the effective rate per sensor
    type, numbered by superscripts as in the paper's Table II."""
    if layout.column != "downsample" or "rate_hz" not in rows:
        plain = [label(layout.column, c) for c in columns]
        return plain, [_escape(p) for p in plain], []
    sensors = _ordered(rows["sensor_type"].unique(), "sensor_type")
    number = {s: i + 1 for i, s in enumerate(sensors)}
    plain, latex = [], []
    for c in columns:
        rates = rows[rows["downsample"] == c].groupby("rate_hz", sort=True)["sensor_type"].unique()
        parts = sorted(((sorted(number[s] for s in types), _rate(r)) for r, types in rates.items()), key=lambda p: p[0])
        plain.append(" / ".join(f"{r} ({','.join(map(str, ns))})" for ns, r in parts) if len(parts) > 1
                     else _rate(rates.index[0]) if len(parts) else label("downsample", c))
        latex.append(r"\begin{tabular}{@{}c@{}}" + r"\\".join(f"${r}^{{{','.join(map(str, ns))}}}$" for ns, r in parts)
                     + r"\end{tabular}" if len(parts) > 1 else plain[-1])
    notes = ["Rates in Hz; " + ", ".join(f"({n}) {SENSOR_NAMES.get(s, s)}" for s, n in number.items()) + "."]
    return plain, latex, notes


def build_table(rows: pd.DataFrame, layout: Layout, metric: str = "accuracy", intervals: bool = False,
                values: str = "ours", paper: pd.DataFrame | None = None, label_: str = "") -> Table:
    """One table of one detector's rows in ``layout``.

    ``values``: "ours" (the results), "paper" (the published numbers from ``paper``), or
    "difference" (ours minus paper, in percentage points).
    """
    keys = [*layout.rows, layout.column] + ([layout.pair] if layout.pair else [])
    keys = [k for k in keys if k in rows]
    summary = summarize(rows, keys, metric)
    row_values = summary[list(layout.rows)].drop_duplicates()
    for col in reversed(layout.rows):  # stable sorts, last key first: lexicographic order
        ordered = _ordered(row_values[col], col)
        row_values = row_values.iloc[np.argsort([ordered.index(v) for v in row_values[col]], kind="stable")]
    row_keys = list(row_values.itertuples(index=False, name=None))
    columns = _ordered(summary[layout.column].unique(), layout.column)
    by_key = {tuple(r[k] for k in keys): r for r in summary.to_dict("records")}
    ref = {}
    if paper is not None and len(paper) and metric in paper and set(keys) <= set(paper.columns):
        ref = {tuple(r[k] for k in keys): r[metric] for r in paper.to_dict("records")}

    def one(key: tuple) -> str:
        r = by_key.get(key)
        if values == "paper":
            return f"{100 * ref[key]:.1f}" if key in ref else "—"
        if r is None:
            return "NA"
        if values == "difference":
            if key not in ref or r["status"] != "ok" or pd.isna(r["mean"]):
                return "—"
            return f"{100 * (r['mean'] - ref[key]):+.1f}"
        return figure_text(r["mean"], r["sd"], r["n"], r["lo"], r["hi"], r["status"], intervals)

    cells = []
    for rk in row_keys:
        line = []
        for c in columns:
            if layout.pair:
                with_, without = one((*rk, c, "with")), one((*rk, c, "without"))
                line.append(f"{with_} {without}*")
            else:
                line.append(one((*rk, c)))
        cells.append(line)
    plain, latex, notes = _column_labels(layout, rows, columns)
    if layout.merge_rows:
        row_labels = [(", ".join(label(k, v) for k, v in zip(layout.rows, rk)),) for rk in row_keys]
        headers = [ROW_HEADERS.get(layout.rows[-1], layout.rows[-1])]
    else:
        row_labels = [tuple(label(k, v) for k, v in zip(layout.rows, rk)) for rk in row_keys]
        headers = [ROW_HEADERS.get(k, k) for k in layout.rows]
    unit = " (%)" if metric != "auroc" else " (%, 50 = chance)"
    group = f"{METRIC_NAMES.get(metric, metric)}{unit} {layout.group}".strip()
    if values == "difference":
        group = f"Difference, ours - paper (points), {METRIC_NAMES.get(metric, metric)} {layout.group}".strip()
    if (summary["n"] > 1).any() and values == "ours":
        notes.append("Mean ± standard deviation across seeds.")
    if intervals and values == "ours":
        notes.append("[95 % interval: bootstrap over recordings; mean of the seeds' bounds with repeats].")
    return Table(layout.caption, headers, group, plain, row_labels, cells, label_, latex, notes)


def _averaged(rows: pd.DataFrame, metrics: Sequence[str], by: Sequence[str], intervals: bool) -> dict[tuple, list[str]]:
    """Figures averaged over fingers (mean of the per-finger figures, each averaged over seeds).

    The interval of an average combines the fingers' interval half-widths as independent
    errors (root of the summed squares, over the number of fingers): fingers are different
    recordings, so their bootstrap errors are independent.
    """
    out: dict[tuple, list[str]] = {}
    for metric in metrics:
        per = summarize(rows, [*by, "sensor_instance"], metric)
        per = per[per["status"] == "ok"]
        for key, g in per.groupby(list(by), sort=False):
            key = key if isinstance(key, tuple) else (key,)
            half = np.sqrt((((g["hi"] - g["lo"]) / 2) ** 2).sum()) / len(g)
            mean = g["mean"].mean()
            out.setdefault(key, []).append(figure_text(mean, lo=mean - half, hi=mean + half, intervals=intervals))
    return out


def baseline_table(rows: pd.DataFrame, intervals: bool = False, paper: bool = False) -> Table | None:
    """Accuracy at window 50 per sensor type (mean over fingers), one column per detector; with
    ``paper``, the published Holweg accuracies and the LSTM's Table I means beside them."""
    rows = rows[(rows["protocol"] == "window-size") & (rows["window"] == BASELINE_WINDOW)]
    if rows.empty:
        return None
    detectors = _rank(rows["detector"].unique(), ("holweg", "lstm"))
    sensors = _ordered(rows["sensor_type"].unique(), "sensor_type")
    columns, cells = list(detectors), [[] for _ in sensors]
    for det in detectors:
        avg = _averaged(rows[rows["detector"] == det], ["accuracy"], ["sensor_type"], intervals)
        for i, s in enumerate(sensors):
            cells[i].append(avg.get((s,), ["NA"])[0])
    if paper:
        holweg = paper_frame("holweg").set_index("sensor_type")["accuracy"]
        lstm = paper_frame("window-size").query(f"window == {BASELINE_WINDOW}").groupby("sensor_type")["accuracy"].mean()
        columns += ["holweg (paper)", "lstm (paper)"]
        for i, s in enumerate(sensors):
            cells[i] += [f"{100 * ref[s]:.1f}" if s in ref else "—" for ref in (holweg, lstm)]
    notes = ["Mean over fingers of each finger's accuracy at window 50, full sampling rate."]
    if paper:
        notes.append("Paper: Holweg's threshold 71.4 / 80.9 / 76.4 % (thresholds 0.0015 N, 3.5 units, 25 units); "
                     "LSTM: mean of Table I at window 50.")
    return Table("The Holweg baseline beside the other detectors at window 50.", ["Sensor"],
                 "Classification Accuracy (%) by Detector", columns, [(label("sensor_type", s),) for s in sensors],
                 cells, "tab:baseline", notes=notes)


def rates_table(rows: pd.DataFrame, detector: str, intervals: bool = False, paper: bool = False) -> Table | None:
    """TP and TN rates at window 50 per sensor type, averaged over fingers (paper, section VI.A)."""
    rows = rows[(rows["protocol"] == "window-size") & (rows["window"] == BASELINE_WINDOW) & (rows["detector"] == detector)]
    if rows.empty:
        return None
    sensors = _ordered(rows["sensor_type"].unique(), "sensor_type")
    avg = _averaged(rows, ["tp_rate", "tn_rate"], ["sensor_type"], intervals)
    cells = [avg.get((s,), ["NA", "NA"]) for s in sensors]
    columns = ["TP rate", "TN rate"]
    if paper:
        ref = paper_frame("rates_window_50").set_index("sensor_type")
        columns += ["TP rate (paper, LSTM)", "TN rate (paper, LSTM)"]
        for i, s in enumerate(sensors):
            cells[i] = cells[i] + ([_as_printed(100 * ref.loc[s, c]) for c in ("tp_rate", "tn_rate")]
                                   if s in ref.index else ["—", "—"])
    return Table(f"TP and TN rates at window 50 averaged across fingers ({detector}).", ["Sensor"], "Rate (%)",
                 columns, [(label("sensor_type", s),) for s in sensors], cells, f"tab:rates-{detector}",
                 notes=["TP: slip detected while slipping; TN: non-slip passed while not slipping."])


# ----------------------------------------------------------------------------- rendering
def _escape(text: str) -> str:
    for a, b in (("\\", r"\textbackslash{}"), ("&", r"\&"), ("%", r"\%"), ("_", r"\_"), ("#", r"\#"),
                 ("±", r"$\pm$"), ("—", "--")):
        text = text.replace(a, b)
    return text


def to_markdown(table: Table) -> str:
    """Markdown: caption in bold, one pipe table, notes in italics."""
    header = [*table.row_headers, *table.columns]
    frame = pd.DataFrame([[*r, *c] for r, c in zip(table.rows, table.cells)], columns=header)
    body = frame.to_markdown(index=False, stralign="right", disable_numparse=True)
    parts = [f"**{table.caption}** {table.group}.", "", body]
    parts += [""] + [f"_{n}_" for n in table.notes] if table.notes else []
    return "\n".join(parts)


def to_latex(table: Table) -> str:
    """A LaTeX ``table`` float in the paper's style (vertical rules, sensor name on the first row
    of its group, ``\\cline`` between fingers). Uses only the LaTeX kernel: no packages.

    Written by hand rather than with ``Styler.to_latex``: that needs booktabs and multirow, and
    has no way to express the per-sensor rate header of Table II.
    """
    n_rows, n_cols = len(table.row_headers), len(table.columns)
    first = n_rows + 1
    spec = "|" + "|".join(["c"] * (n_rows + n_cols)) + "|"
    lines = [r"\begin{table}[!t]", rf"\caption{{{_escape(table.caption)}}}", r"\centering",
             rf"\begin{{tabular}}{{{spec}}}", r"\hline"]
    heads = " & ".join(rf"\textbf{{{_escape(h)}}}" for h in table.row_headers)
    lines.append(rf"{heads} & \multicolumn{{{n_cols}}}{{c|}}{{\textbf{{{_escape(table.group)}}}}}\\")
    lines.append(rf"\cline{{{first}-{n_rows + n_cols}}}")
    latex_cols = table.latex_columns or [_escape(c) for c in table.columns]
    lines.append(" & " * n_rows + " & ".join(latex_cols) + r"\\")
    lines.append(r"\hline")
    previous: tuple[str, ...] | None = None
    for i, (labels, cells) in enumerate(zip(table.rows, table.cells)):
        shown = list(labels)
        if n_rows > 1 and previous is not None and labels[0] == previous[0]:
            shown[0] = ""  # the sensor name once per group, as the paper's multirow
        lines.append(" & ".join(_escape(x) for x in [*shown, *cells]) + r"\\")
        nxt = table.rows[i + 1] if i + 1 < len(table.rows) else None
        lines.append(rf"\cline{{2-{n_rows + n_cols}}}" if n_rows > 1 and nxt is not None and nxt[0] == labels[0] else r"\hline")
        previous = labels
    lines.append(r"\end{tabular}")
    if table.label:
        lines.append(rf"\label{{{table.label}}}")
    for note in table.notes:
        lines.append(rf"\par\footnotesize {_escape(note)}")
    lines.append(r"\end{table}")
    return "\n".join(lines)


def standalone_latex(body: str) -> str:
    """Wrap table floats in a minimal document that compiles with the LaTeX kernel alone."""
    return "\n".join([r"\documentclass{article}", r"\usepackage[utf8]{inputenc}", r"\begin{document}", body,
                      r"\end{document}", ""])


# ----------------------------------------------------------------------------- whole reports
def _sections(rows: pd.DataFrame) -> list[tuple[str, str, str, pd.DataFrame]]:
    """(protocol, detector, split, rows) in the paper's order of protocols."""
    out = []
    for protocol in _rank(rows["protocol"].unique(), PROTOCOL_ORDER):
        prows = rows[rows["protocol"] == protocol]
        for detector in _rank(prows["detector"].unique(), ("holweg", "lstm")):
            drows = prows[prows["detector"] == detector]
            for split in _rank(drows["split"].unique() if "split" in drows else ["paper"], ("paper", "grouped")):
                out.append((protocol, detector, split, drows[drows["split"] == split] if "split" in drows else drows))
    return out


def protocol_tables(rows: pd.DataFrame, protocol: str, detector: str, metric: str = "accuracy",
                    intervals: bool = False, paper: bool = False, fallback: dict | None = None) -> list[tuple[str, Table]]:
    """The tables of one protocol and detector: one per ``split`` value of the layout (e.g.
    decimation), each followed, with ``paper``, by the published table and the difference."""
    layout = layout_for(rows, protocol, fallback)
    ref = paper_frame(protocol) if paper else None
    parts = [(None, rows)]
    if layout.split and layout.split in rows:
        parts = [(v, rows[rows[layout.split] == v]) for v in _rank(rows[layout.split].unique(), ("plain", "antialias"))]
    out = []
    for value, part in parts:
        tag = f"{protocol}-{detector}" + (f"-{value}" if value is not None else "")
        suffix = f" ({layout.split}: {value})" if value is not None else ""
        table = build_table(part, layout, metric, intervals, label_=f"tab:{tag}")
        if value is not None:
            table.caption += f" {layout.split.capitalize()}: {value}."
        out.append((f"{detector}{suffix}", table))
        if ref is not None and len(ref) and metric == "accuracy":
            cap = "Published (Van Wyk & Falco, LSTM): " + layout.caption[0].lower() + layout.caption[1:]
            pt = build_table(part, layout, metric, values="paper", paper=ref, label_=f"tab:{tag}-paper")
            pt.caption = cap
            if protocol == "sampling-rate":
                pt.notes.append("The full-rate column is Table I at window 200, the same setting.")
            dt = build_table(part, layout, metric, values="difference", paper=ref, label_=f"tab:{tag}-difference")
            dt.caption = f"Ours ({detector}) minus published (LSTM)."
            out += [(f"paper{suffix}", pt), (f"{detector} - paper{suffix}", dt)]
    return out


def render_report(rows: pd.DataFrame, fmt: str = "md", metric: str = "accuracy", intervals: bool = False,
                  paper: bool = False, standalone: bool = False) -> str:
    """Every table the rows allow, in the paper's order, as one Markdown or LaTeX text."""
    render = to_markdown if fmt == "md" else to_latex
    blocks: list[str] = []
    for protocol, detector, split, part in _sections(rows):
        tables = protocol_tables(part, protocol, detector, metric, intervals, paper)
        if fmt == "md":
            blocks.append(f"## {protocol}: {detector} (split {split})")
        else:
            blocks.append(f"% {protocol}: {detector} (split {split})")
        blocks += [render(t) for _, t in tables]
    if "window" in rows and "window-size" in set(rows["protocol"]):
        extra = [baseline_table(rows, intervals, paper)]
        extra += [rates_table(rows, d, intervals, paper) for d in _rank(rows["detector"].unique(), ("holweg", "lstm"))]
        extra = [t for t in extra if t is not None]
        if extra:
            blocks.append("## At window 50: baseline and TP/TN rates" if fmt == "md" else "% at window 50")
            blocks += [render(t) for t in extra]
    text = "\n\n".join(blocks) + "\n"
    return standalone_latex(text) if fmt == "latex" and standalone else text


def protocol_table(rows: pd.DataFrame, layout: dict | None = None, intervals: bool = False) -> str:
    """The Markdown table(s) of one protocol's rows for one detector (what ``evaluate`` prints).

    ``layout`` is the protocol's own ``table`` dict, used only for protocols without a paper layout.
    """
    rows = pd.DataFrame(rows)
    if rows.empty:
        return "(no cells)"
    protocol, detector = str(rows["protocol"].iloc[0]), str(rows["detector"].iloc[0])
    tables = protocol_tables(rows, protocol, detector, intervals=intervals, fallback=layout)
    return "\n\n".join(to_markdown(t) for _, t in tables)
