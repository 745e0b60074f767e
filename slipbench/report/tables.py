"""Result rows -> tables in a protocol's layout: labels, ordering, figures per cell, and the
paper's extra tables at window 50. In no format: a renderer (:mod:`slipbench.report.render`)
writes them out.

Layouts follow Van Wyk & Falco where the protocol declares the paper's: window size (Table I),
sampling rate with its per-sensor rate header (Table II), material and speed with two numbers
per cell, the second starred for "without explicit training" (Tables III and IV), training
instance by test instance (Table V); every detector's accuracy at window 50, the baseline named,
and TP/TN rates per sensor type.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from slipbench.protocol import Layout
from slipbench.report.blocks import LOW_MARK, STREAM_LOW_NOTE, UNESTIMABLE_MARK, Table
from slipbench.report.notes import any_repeated, data_notes, interval_note, seeds_notes
from slipbench.report.order import ordered, rank
from slipbench.report.paper import paper_frame
from slipbench.report.presentation import ShownLayout
from slipbench.stats.contrast import (
    SINGLE_CLUSTER,
)
from slipbench.stats.factors import setting_labels
from slipbench.stats.metrics import classes_low_n_of, seeds_from_rows, stream_low_n
from slipbench.store.columns import (
    AUROC,
    ENTRANT_CELL,
    FIGURES,
    WINDOWED,
    figure_of,
    figures,
)
from slipbench.vocabulary import (
    DETECTOR_ORDER,
    LOW_N,
    SENSOR_NAMES,
    SENSOR_TYPE,
    label,
)

#: the rates of one class each (TP, then TN), as the paper's Table II gives them
CLASS_RATES = [f.name for f in figures(WINDOWED) if f.one_class]


def figure_label(metric: str) -> str:
    """How a table heads a figure: the paper's word (``TN Rate``), else the column's name."""
    return FIGURES[metric].label if metric in FIGURES else metric


BASELINE_WINDOW = 50  # the paper's reference window for the Holweg baseline and the TP/TN rates


ROW_HEADERS = {
    SENSOR_TYPE: "Sensor",
    "sensor_instance": "Finger",
    "train_instance": "Training Data",
}
COLUMN_UNITS = {
    "rate_hz": "Rates in Hz",
    "window_ms": "Window in ms",
    "window": "Window in samples",
}


# ----------------------------------------------------------------------------- ordering and labels


def _as_printed(percent: float) -> str:
    """One decimal, or two where the paper printed two (its TN rate 89.79)."""
    return f"{percent:.1f}" if abs(percent - round(percent, 1)) < 1e-9 else f"{percent:.2f}"


def _rate(value: float) -> str:
    return f"{value:.2f}".rstrip("0").rstrip(".")


# ----------------------------------------------------------------------------- captions
PLACEHOLDER = re.compile(r"\{(\w+)\}")


def _value_text(value: Any) -> str:
    if isinstance(value, (bool, np.bool_, str)):
        return str(value)
    try:
        return _rate(float(value))
    except (TypeError, ValueError):
        return str(value)


COUNTS = ("no", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine", "ten")


def sensors_text(rows: pd.DataFrame) -> str:
    """What units ``rows`` hold, for a caption: "three types of sensors and fingers", "the
    fingers of one sensor type (Biotac SP)", "one sensor (Biotac SP, ff)"."""
    if SENSOR_TYPE not in rows or rows[SENSOR_TYPE].dropna().empty:
        return "sensors and fingers"
    types = ordered(rows[SENSOR_TYPE].dropna().unique(), SENSOR_TYPE)
    if len(types) > 1:
        count = COUNTS[len(types)] if len(types) < len(COUNTS) else f"{len(types):,}"
        return f"{count} types of sensors and fingers"
    name = label(SENSOR_TYPE, types[0])
    fingers = rows["sensor_instance"].dropna().unique() if "sensor_instance" in rows else []
    if len(fingers) == 1:
        return f"one sensor ({name}, {label('sensor_instance', fingers[0])})"
    return f"the fingers of one sensor type ({name})"


#: a caption's placeholders that name no column: what the rows hold, in words
DESCRIBED = {"sensors": sensors_text}


def caption_of(caption: str, rows: pd.DataFrame) -> str:
    """``caption`` with each ``{column}`` it names (:class:`~slipbench.protocol.Presentation`)
    replaced by the values ``rows`` hold there: "window {window}" -> "window 200", or per sensor
    type where they differ, "window 200 (Nano17, OptoForce20), 170 (Biotac SP)"; ``{sensors}``
    by what units they are (:func:`sensors_text`). A name the rows do not give stays as
    written."""

    def values(match: re.Match) -> str:
        column = match.group(1)
        if column in DESCRIBED and column not in rows:
            return DESCRIBED[column](rows)
        if column not in rows or rows[column].dropna().empty:
            return match.group(0)
        if SENSOR_TYPE in rows and rows[column].nunique() > 1:
            per: dict[tuple[str, ...], list[str]] = {}
            for sensor in ordered(rows[SENSOR_TYPE].dropna().unique(), SENSOR_TYPE):
                mine = rows.loc[rows[SENSOR_TYPE] == sensor, column].dropna().unique()
                if len(mine):
                    texts = tuple(_value_text(v) for v in rank(mine))
                    per.setdefault(texts, []).append(SENSOR_NAMES.get(sensor, sensor))
            if len(per) > 1:
                return ", ".join(f"{'/'.join(t)} ({', '.join(n)})" for t, n in per.items())
        return ", ".join(_value_text(v) for v in rank(rows[column].dropna().unique()))

    return PLACEHOLDER.sub(values, caption)


# ----------------------------------------------------------------------------- figures per cell
def low_n(rows: pd.DataFrame) -> pd.Series:
    """(n_rows,) bool: rows whose cell rests on few test trials, from the counts the rows give:
    trials per class where they give them (:func:`~slipbench.stats.metrics.classes_low_n`: a
    class the test set lacks is absent, not few), a streaming cell's test trials and onsets
    (:func:`~slipbench.stats.metrics.stream_low_n`: the trials holding its onsets, the
    onsets, the trials with non-slip time); else the rows' own ``low_n``; else
    ``n_test_trials < LOW_N``; False where none is known."""

    def column(name: str) -> np.ndarray:
        if name not in rows:
            return np.full(len(rows), np.nan)
        return pd.to_numeric(rows[name], errors="coerce").to_numpy(dtype=float)

    out = np.zeros(len(rows), bool)
    slip, nonslip = column("n_test_clusters_slip"), column("n_test_clusters_nonslip")
    trials, onsets = column("n_test_trials"), column("n_onsets")
    known = ~np.isnan(slip) & ~np.isnan(nonslip)
    out[known] = classes_low_n_of(slip[known].astype(int), nonslip[known].astype(int))
    # the trials holding onsets where the rows count them (older rows: every test trial)
    onset_trials, quiet_trials = column("n_onset_trials"), column("n_nonslip_trials")
    onset_trials = np.where(np.isnan(onset_trials), trials, onset_trials)
    quiet_trials = np.where(np.isnan(quiet_trials), np.inf, quiet_trials)
    streamed = ~known & ~np.isnan(onsets)
    for i in np.flatnonzero(streamed):
        out[i] = stream_low_n(onset_trials[i], onsets[i], quiet_trials[i])
    known |= streamed
    if "low_n" in rows:
        own = rows["low_n"].to_numpy(dtype=object)
        given = ~known & pd.notna(own)
        out[given] = own[given].astype(bool)
        known |= given
    rest = ~known & ~np.isnan(trials)
    out[rest] = trials[rest] < LOW_N
    return pd.Series(out, index=rows.index)


def _seed_interval(ok: pd.DataFrame, metric: str) -> tuple[float, float]:
    """The interval of the mean over the seeds ``ok`` (finished rows of one cell) of ``metric``:
    the row's own with one seed, else :func:`~slipbench.stats.metrics.seeds_from_rows` from the
    rows' standard errors (``<metric>_se``, else their 95 % bounds over 2 x 1.96)."""
    lo_col, hi_col, se_col = f"{metric}_lo", f"{metric}_hi", f"{metric}_se"
    if lo_col not in ok or hi_col not in ok or not len(ok):
        return np.nan, np.nan
    lo, hi = ok[lo_col].astype(float).to_numpy(), ok[hi_col].astype(float).to_numpy()
    if len(ok) == 1:
        return float(lo[0]), float(hi[0])
    from_bounds = (hi - lo) / (2 * 1.959964)  # a 95 % interval's half-width over z
    se = ok[se_col].astype(float).to_numpy() if se_col in ok else from_bounds
    se = np.where(np.isnan(se), from_bounds, se)
    shown = figure_of(metric)
    fraction = shown is not None and shown.unit == "fraction"
    _, lo_, hi_ = seeds_from_rows(
        ok[metric].astype(float).to_numpy(),
        se,
        bounds=(0.0, 1.0) if fraction else (-np.inf, np.inf),
    )
    return lo_, hi_


def summarize(rows: pd.DataFrame, keys: list[str], metric: str = "accuracy") -> pd.DataFrame:
    """One line per combination of ``keys``: the mean of ``metric`` over seeds (``--repeats``),
    its standard deviation across seeds, the number of seeds, its interval (the row's; over
    several seeds, :func:`_seed_interval`, with retraining noise inside), a status ("ok", or the
    status of the cell when no seed finished) and ``low_n`` (a finished seed rests on few test
    trials)."""
    keys = list(dict.fromkeys(keys))  # a key named twice (a layout by detector) groups once
    if metric not in rows.columns:
        rows = rows.assign(**{metric: np.nan})
    rows = rows.assign(_low=low_n(rows), _lone=unestimable(rows, metric))
    out = []
    for values, group in rows.groupby(keys, sort=False, dropna=False):
        ok = group[group["status"] == "ok"] if "status" in group else group
        vals = ok[metric].astype(float)
        lo, hi = _seed_interval(ok, metric)
        out.append(
            {
                **dict(zip(keys, values if isinstance(values, tuple) else (values,))),
                "mean": vals.mean() if len(vals) else np.nan,
                "sd": vals.std(ddof=1) if len(vals) > 1 else np.nan,
                "n": len(vals),
                "lo": lo,
                "hi": hi,
                "status": "ok" if len(ok) else str(group["status"].iloc[0]),
                "low_n": bool(ok["_low"].any()),
                "unestimable": bool(ok["_lone"].any()),
            }
        )
    columns = [*keys, "mean", "sd", "n", "lo", "hi", "status", "low_n", "unestimable"]
    return pd.DataFrame(out, columns=columns)


def unestimable(rows: pd.DataFrame, metric: str) -> pd.Series:
    """(n_rows,) bool: rows whose interval of ``metric`` is not estimable, as their
    ``ci_note`` says (a class of a single test trial: the interval is the whole range)."""
    if "ci_note" not in rows:
        return pd.Series(False, index=rows.index)
    figures = rows["ci_note"].fillna("").astype(str).str.split(":").str[0].str.split(", ")
    said = rows["ci_note"].fillna("").astype(str).str.contains(SINGLE_CLUSTER, regex=False)
    return said & figures.map(lambda named: metric in named)


@dataclass(frozen=True)
class CellFigure:
    """One figure of a cell as a table shows it: its mean over seeds, their sd and count, its
    interval, the cell's status, and whether it rests on few test trials or onsets (``low``)."""

    mean: float
    sd: float = np.nan
    n: int = 1
    lo: float = np.nan
    hi: float = np.nan
    status: str = "ok"
    low: bool = False
    unestimable: bool = False  # an interval behind it is the figure's whole range

    @classmethod
    def of(cls, r: dict) -> CellFigure:
        """From a record of :func:`summarize`."""
        lone = bool(r.get("unestimable", False))
        return cls(
            r["mean"], r["sd"], r["n"], r["lo"], r["hi"], r["status"], bool(r["low_n"]), lone
        )


def figure_text(figure: CellFigure, intervals: bool = False) -> str:
    """``88.0``; ``88.0 ± 0.4`` over seeds; ``88.0 [86.9, 89.1]`` with intervals (over seeds the
    interval holds their spread, so no ± beside it); 'NA' if absent; ``LOW_MARK`` appended where
    the cell rests on few test trials."""
    return metric_text("", figure, intervals)


def _column_labels(
    layout: ShownLayout, rows: pd.DataFrame, columns: list[Any]
) -> tuple[list[str], dict[int, list[tuple[str, str]]], list[str]]:
    """Plain column labels, the same with superscripts (:attr:`Table.superscripts`), and notes.
    With ``layout.column_label``, the label's value per sensor type, numbered by superscripts
    as the rates of the paper's Table II; with ``layout.note_column``, a note listing that
    column's values per sensor type."""
    notes = _note_column(layout, rows, columns)
    if not layout.column_label or layout.column_label not in rows or SENSOR_TYPE not in rows:
        return [label(layout.column, c) for c in columns], {}, notes
    sensors = ordered(rows[SENSOR_TYPE].unique(), SENSOR_TYPE)
    number = {s: i + 1 for i, s in enumerate(sensors)}
    plain, marked = [], {}
    for j, c in enumerate(columns):
        rates = (
            rows[rows[layout.column] == c]
            .groupby(layout.column_label, sort=True)[SENSOR_TYPE]
            .unique()
        )
        parts = sorted(
            ((sorted(number[s] for s in types), _rate(r)) for r, types in rates.items()),
            key=lambda p: p[0],
        )
        plain.append(
            " / ".join(f"{r} ({','.join(map(str, ns))})" for ns, r in parts)
            if len(parts) > 1
            else _rate(rates.index[0])
            if len(parts)
            else label(layout.column, c)
        )
        if len(parts) > 1:
            marked[j] = [(r, ",".join(map(str, ns))) for ns, r in parts]
    notes.insert(
        0,
        f"{COLUMN_UNITS.get(layout.column_label, layout.column_label)}; "
        + ", ".join(f"({n}) {SENSOR_NAMES.get(s, s)}" for s, n in number.items())
        + ".",
    )
    return plain, marked, notes


def _note_column(layout: ShownLayout, rows: pd.DataFrame, columns: list[Any]) -> list[str]:
    """ "Window (ms): Nano17, OptoForce20: 5, 10, ...; Biotac SP: 5.9, ..." for ``note_column``."""
    col = layout.note_column
    if not col or col not in rows or SENSOR_TYPE not in rows:
        return []
    per_sensor: dict[tuple, list[str]] = {}
    for sensor in ordered(rows[SENSOR_TYPE].unique(), SENSOR_TYPE):
        part = rows[rows[SENSOR_TYPE] == sensor]
        values = tuple(
            _rate(float(part.loc[part[layout.column] == c, col].iloc[0]))
            if (part[layout.column] == c).any()
            else "—"
            for c in columns
        )
        per_sensor.setdefault(values, []).append(SENSOR_NAMES.get(sensor, sensor))
    text = "; ".join(
        f"{', '.join(names)}: {', '.join(values)}" for values, names in per_sensor.items()
    )
    return [f"{COLUMN_UNITS.get(col, col)} per column: {text}."]


def table_keys(rows: pd.DataFrame, layout: Layout) -> list[str]:
    """The columns that name one figure of ``layout``'s table: its rows, column and pair."""
    return [k for k in (*layout.rows, layout.column, layout.pair) if k and k in rows]


@dataclass(frozen=True)
class TableValues:
    """What a table's cells hold. ``kind``: "ours" (the results), "paper" (the published numbers
    from ``paper``), or "difference" (ours minus paper, in percentage points). ``pooled`` (keyed
    by the values of :func:`table_keys`, from :func:`slipbench.stats.joint.joint_means`): the
    interval of a figure run under several seeds, one bootstrap over the recordings the seeds
    share, in place of the mean of the seeds' bounds."""

    kind: str = "ours"
    paper: pd.DataFrame | None = None
    pooled: dict[tuple, dict] | None = None


def build_table(
    rows: pd.DataFrame,
    layout: ShownLayout,
    metric: str = "accuracy",
    intervals: bool = False,
    shown: TableValues = TableValues(),
) -> Table:
    """One table of one detector's rows in ``layout``, its cells ``shown`` (:class:`TableValues`;
    its label is the caller's to set). A layout with ``metrics`` gives :func:`metrics_table`
    (``metric`` and ``shown.kind`` do not apply)."""
    if layout.metrics:
        return metrics_table(rows, layout, layout.metrics, intervals)
    values, paper = shown.kind, shown.paper
    keys = table_keys(rows, layout)
    pooled = shown.pooled or {}
    summary = summarize(rows, keys, metric)
    row_values = summary[list(layout.rows)].drop_duplicates()
    for col in reversed(layout.rows):  # stable sorts, last key first: lexicographic order
        order = ordered(row_values[col], col)
        row_values = row_values.iloc[
            np.argsort([order.index(v) for v in row_values[col]], kind="stable")
        ]
    row_keys = list(row_values.itertuples(index=False, name=None))
    columns = ordered(summary[layout.column].unique(), layout.column)
    by_key = {tuple(r[k] for k in keys): r for r in summary.to_dict("records")}
    ref = _published(paper, metric, keys)

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
        lo, hi = r["lo"], r["hi"]
        if r["n"] > 1 and key in pooled:
            lo, hi = pooled[key][f"{metric}_lo"], pooled[key][f"{metric}_hi"]
        return figure_text(CellFigure.of({**r, "lo": lo, "hi": hi}), intervals)

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
    plain, marked, notes = _column_labels(layout, rows, columns)
    row_labels: list[tuple[str, ...]]
    if layout.merge_rows:
        row_labels = [(", ".join(label(k, v) for k, v in zip(layout.rows, rk)),) for rk in row_keys]
        headers = [ROW_HEADERS.get(layout.rows[-1], layout.rows[-1])]
    else:
        row_labels = [tuple(label(k, v) for k, v in zip(layout.rows, rk)) for rk in row_keys]
        headers = [ROW_HEADERS.get(k, k) for k in layout.rows]
    unit = " (%)" if metric != AUROC.name else " (%, 50 = chance)"
    group = f"{figure_label(metric)}{unit} {layout.group}".strip()
    if values == "difference":
        group = f"Ours - paper (points) {layout.group}".strip()
    if values == "ours":
        repeated = {k: int(r["n"]) for k, r in by_key.items() if r["n"] > 1}
        notes += seeds_notes(repeated, pooled, intervals, rows, keys)
        notes += data_notes(rows)
    caption = caption_of(layout.caption, paper if values == "paper" and paper is not None else rows)
    caption = caption_of(caption, rows)  # what the published table does not give, the rows do
    return Table(caption, headers, group, plain, row_labels, cells, "", marked, notes)


def _published(paper: pd.DataFrame | None, metric: str, keys: list[str]) -> dict[tuple, float]:
    """The published figure of each key of a table, where the paper's table gives them."""
    if paper is None or not len(paper) or metric not in paper or not set(keys) <= set(paper):
        return {}
    return {tuple(r[k] for k in keys): r[metric] for r in paper.to_dict("records")}


def _averaged(
    rows: pd.DataFrame,
    metrics: Sequence[str],
    by: Sequence[str],
    intervals: bool,
    joint: dict[tuple, dict] | None = None,
) -> dict[tuple, list[str]]:
    """Figures averaged over fingers (mean of the per-finger figures, each averaged over seeds).

    ``joint`` (from :func:`slipbench.stats.joint.joint_means`, keyed by the values of ``by``): the
    mean and interval of one bootstrap over the trials the fingers share. A group without it
    combines the fingers' half-widths as independent (root of the summed squares over the
    number of fingers), which understates the interval where fingers share trials.
    """
    joint = joint or {}
    out: dict[tuple, list[str]] = {}
    for metric in metrics:
        per = summarize(rows, [*by, "sensor_instance"], metric)
        per = per[per["status"] == "ok"]
        for key, g in per.groupby(list(by), sort=False):
            key = key if isinstance(key, tuple) else (key,)
            if key in joint:
                j = joint[key]
                mean, lo, hi = j[metric], j[f"{metric}_lo"], j[f"{metric}_hi"]
            else:
                half = np.sqrt((((g["hi"] - g["lo"]) / 2) ** 2).sum()) / len(g)
                mean = g["mean"].mean()
                lo, hi = mean - half, mean + half
            out.setdefault(key, []).append(
                figure_text(
                    CellFigure(
                        mean,
                        lo=lo,
                        hi=hi,
                        low=bool(g["low_n"].any()),
                        unestimable=key not in joint and bool(g["unestimable"].any()),
                    ),
                    intervals,
                )
            )
    return out


def _of(joint: dict[tuple, dict] | None, detector: str) -> dict[tuple, dict]:
    """One detector's entries of a ``(detector, sensor_type)``-keyed joint mapping, by sensor type."""
    return {k[1:]: v for k, v in (joint or {}).items() if k[0] == detector}


def _baseline_title(baseline: list[str], paper: bool) -> str:
    ran = (
        f"baseline: {' and '.join(baseline)}"
        if baseline
        else "no baseline ran: none of them is the registered reference"
    )
    beside = ", with the paper's Holweg threshold and LSTM" if paper else ""
    return f"Each detector's accuracy at window 50 ({ran}){beside}."


def baseline_table(
    rows: pd.DataFrame,
    intervals: bool = False,
    paper: bool = False,
    joint: dict[tuple, dict] | None = None,
    reference: Sequence[str] = (),
) -> Table | None:
    """Accuracy at window 50 per sensor type (mean over fingers), one column per detector, from
    the rows of the protocol laid out as the paper's Table I; with ``paper``, the published
    Holweg accuracies and the LSTM's Table I means beside them. The title names the baseline
    (the ``reference`` detectors among the columns) or says that none ran, in the words of the
    leaderboard's note: the paper's Holweg threshold is a column, not the baseline."""
    rows = rows[rows["window"] == BASELINE_WINDOW]
    if rows.empty:
        return None
    detectors = rank(rows["detector"].unique(), DETECTOR_ORDER)
    sensors = ordered(rows[SENSOR_TYPE].unique(), SENSOR_TYPE)
    cells: list[list[str]] = [[] for _ in sensors]
    columns, shown = list(detectors), []
    for det in detectors:
        avg = _averaged(
            rows[rows["detector"] == det], ["accuracy"], [SENSOR_TYPE], intervals, _of(joint, det)
        )
        shown += [(det, *k) for k in avg]
        for i, s in enumerate(sensors):
            cells[i].append(avg.get((s,), ["NA"])[0])
    if paper:
        holweg = paper_frame("holweg").set_index(SENSOR_TYPE)["accuracy"]
        lstm = (
            paper_frame("window-size")
            .query(f"window == {BASELINE_WINDOW}")
            .groupby(SENSOR_TYPE)["accuracy"]
            .mean()
        )
        columns += ["holweg (paper)", "lstm (paper)"]
        for i, s in enumerate(sensors):
            cells[i] += [f"{100 * ref[s]:.1f}" if s in ref else "—" for ref in (holweg, lstm)]
    notes = [
        "Mean over fingers of each finger's accuracy at window 50, full sampling rate.",
        *interval_note(joint, intervals, shown, any_repeated(rows)),
    ]
    if paper:
        notes.append(
            "Paper: Holweg's threshold 71.4 / 80.9 / 76.4 % (thresholds 0.0015 N, 3.5 units, 25 units); "
            "LSTM: mean of Table I at window 50."
        )
    notes += data_notes(rows)
    return Table(
        _baseline_title([r for r in reference if r in detectors], paper),
        ["Sensor"],
        "Classification Accuracy (%) by Detector",
        columns,
        [(label(SENSOR_TYPE, s),) for s in sensors],
        cells,
        "tab:baseline",
        notes=notes,
    )


def rates_table(
    rows: pd.DataFrame,
    detector: str,
    intervals: bool = False,
    paper: bool = False,
    joint: dict[tuple, dict] | None = None,
) -> Table | None:
    """TP and TN rates at window 50 per sensor type, averaged over fingers (paper, section VI.A),
    from the rows of the protocol laid out as the paper's Table I."""
    rows = rows[(rows["window"] == BASELINE_WINDOW) & (rows["detector"] == detector)]
    if rows.empty:
        return None
    sensors = ordered(rows[SENSOR_TYPE].unique(), SENSOR_TYPE)
    avg = _averaged(rows, CLASS_RATES, [SENSOR_TYPE], intervals, _of(joint, detector))
    cells = [avg.get((s,), ["NA", "NA"]) for s in sensors]
    columns = ["TP rate", "TN rate"]
    if paper:
        ref = paper_frame("rates_window_50").set_index(SENSOR_TYPE)
        columns += ["TP rate (paper, LSTM)", "TN rate (paper, LSTM)"]
        for i, s in enumerate(sensors):
            cells[i] = cells[i] + (
                [_as_printed(100 * ref.loc[s, c]) for c in CLASS_RATES]
                if s in ref.index
                else ["—", "—"]
            )
    return Table(
        f"TP and TN rates at window 50 averaged across fingers ({detector}).",
        ["Sensor"],
        "Rate (%)",
        columns,
        [(label(SENSOR_TYPE, s),) for s in sensors],
        cells,
        f"tab:rates-{detector}",
        notes=[
            "TP: slip detected while slipping; TN: non-slip passed while not slipping.",
            *interval_note(joint, intervals, [(detector, *k) for k in avg], any_repeated(rows)),
            *data_notes(rows),
        ],
    )


# ----------------------------------------------------------------------------- one column per metric
def metric_header(metric: str) -> str:
    """A value column's heading: the figure's (``Detection rate (%)``), else the column's name."""
    shown = figure_of(metric)
    return shown.header if shown is not None else metric


def metric_text(metric: str, figure: CellFigure, intervals: bool = False) -> str:
    """A figure in its own unit and decimals (the results schema's; others as fractions in %):
    ``49.1``; ``49.1 ± 0.4`` over seeds; ``49.1 [45.0, 52.3]`` with intervals (over seeds, the
    interval holds their spread, so no ± beside it); 'NA' if absent; ``LOW_MARK`` appended
    where the cell rests on few test trials or onsets (``low``)."""
    mean, sd, lo, hi = figure.mean, figure.sd, figure.lo, figure.hi
    if figure.status != "ok":
        return figure.status
    if pd.isna(mean):
        return "NA"
    declared = figure_of(metric)
    scale, digits = (declared.scale, declared.decimals) if declared is not None else (100.0, 1)
    text = f"{scale * mean:.{digits}f}"
    shown = intervals and not (pd.isna(lo) or pd.isna(hi))
    if figure.n > 1 and not pd.isna(sd) and not shown:
        text += f" ± {scale * sd:.{digits}f}"
    if shown:
        text += f" [{scale * lo:.{digits}f}, {scale * hi:.{digits}f}]"
        text += UNESTIMABLE_MARK if figure.unestimable else ""
    return text + (LOW_MARK if figure.low else "")


def metrics_table(
    rows: pd.DataFrame,
    layout: ShownLayout,
    metrics: Sequence[str],
    intervals: bool = False,
    prefix: str = "",
) -> Table:
    """One detector's rows in ``layout``, one value column per metric of ``metrics`` (result
    columns ``prefix + metric``, e.g. "op_" for the streaming operating point), each averaged
    over seeds as :func:`summarize` does; its label (and another group header) are the
    caller's to set."""
    keys = [k for k in layout.rows if k in rows]
    per = {
        m: {
            tuple(r[k] for k in keys): r
            for r in summarize(rows, keys, prefix + m).to_dict("records")
        }
        for m in metrics
    }
    row_keys = ordered_keys(rows, keys)
    cells = [
        [metric_text(m, CellFigure.of(per[m][rk]), intervals) for m in metrics] for rk in row_keys
    ]
    row_labels: list[tuple[str, ...]]
    if layout.merge_rows:
        row_labels = [(", ".join(label(k, v) for k, v in zip(keys, rk)),) for rk in row_keys]
        headers = [ROW_HEADERS.get(keys[-1], keys[-1])]
    else:
        row_labels = [tuple(label(k, v) for k, v in zip(keys, rk)) for rk in row_keys]
        headers = [ROW_HEADERS.get(k, k) for k in keys]
    repeated = {rk: int(r["n"]) for m in metrics for rk, r in per[m].items() if r["n"] > 1}
    notes = seeds_notes(repeated, {}, intervals, rows, keys)
    if any(LOW_MARK in c for line in cells for c in line):
        notes.append(STREAM_LOW_NOTE)
    notes += data_notes(rows)
    columns = [metric_header(m) for m in metrics]
    return Table(
        caption_of(layout.caption, rows),
        headers,
        layout.group,
        columns,
        row_labels,
        cells,
        "",
        notes=notes,
    )


def ordered_keys(rows: pd.DataFrame, keys: list[str]) -> list[tuple]:
    """The distinct values of ``keys`` in ``rows``, in the tables' order."""
    row_values = rows[keys].drop_duplicates()
    for col in reversed(keys):  # stable sorts, last key first: lexicographic order
        order = ordered(row_values[col], col)
        row_values = row_values.iloc[
            np.argsort([order.index(v) for v in row_values[col]], kind="stable")
        ]
    return list(row_values.itertuples(index=False, name=None))


def compute_table(rows: pd.DataFrame, layout: ShownLayout, label_: str = "") -> Table | None:
    """A streaming detector's compute time per hop against its real-time budget, one line per
    row of ``layout``: the compute time (mean over seeds), the budget (the hop period) and
    whether it was met ("yes", "no", or in how many seeds). None where the rows hold no compute
    time of their own (rows written while delays still held it)."""
    ok = rows[rows["status"].eq("ok")] if "status" in rows else rows
    if "compute_ms_per_hop" not in ok or ok["compute_ms_per_hop"].isna().all():
        return None
    ok = ok[ok["compute_ms_per_hop"].notna()]
    keys = [k for k in layout.rows if k in ok]
    cells, groups = (
        [],
        {
            (k if isinstance(k, tuple) else (k,)): g
            for k, g in ok.groupby(keys, sort=False, dropna=False)
        },
    )
    order = ordered_keys(ok, keys)
    for rk in order:
        g = groups[rk]
        met = g["realtime"].astype(bool) if "realtime" in g else pd.Series(dtype=bool)
        cells.append(
            [
                f"{g['compute_ms_per_hop'].astype(float).mean():.3f}",
                f"{g['compute_budget_ms'].astype(float).mean():.2f}",
                "yes"
                if len(met) and met.all()
                else "no"
                if not met.any()
                else f"in {int(met.sum())} of {len(met)} seeds",
            ]
        )
    machines = sorted(set(ok.get("compute_processor", pd.Series(dtype=str)).dropna()) - {""})
    on = f" ({'; '.join(machines)})" if machines else ""
    return Table(
        f"Compute time per hop on the machine that ran the cells{on}, against the real-time "
        "budget: the hop period (hop / sampling rate).",
        [ROW_HEADERS.get(k, k) for k in keys],
        "Real-time check (this machine's, unlike the delays)",
        ["Compute per hop (ms)", "Budget (ms)", "Real time"],
        [tuple(label(k, v) for k, v in zip(keys, rk)) for rk in order],
        cells,
        label_,
        notes=[
            "Compute per hop: the median time a push that completes a score took on that machine "
            "(another machine gives another figure); real time: it is within the hop period, so "
            "the detector keeps up with the sensor. The delays do not include it: they are "
            "counted on the stream's samples and are the same on every machine."
        ],
    )


def side_by_side(
    rows: pd.DataFrame,
    layout: ShownLayout,
    detectors: Sequence[str],
    metric: str = "accuracy",
    label_: str = "",
) -> Table | None:
    """Every detector of one protocol's table in one table: a row per detector, the layout's
    value columns (and pair), each figure the mean over the layout's row keys (sensor units)
    of each unit's figure (mean over seeds). None with fewer than two detectors or no finished
    cell."""
    if len(detectors) < 2:
        return None
    if layout.metrics:
        return _metrics_side_by_side(rows, layout, detectors, label_)
    keys = [k for k in (*layout.rows, layout.column, layout.pair) if k and k in rows]
    if "detector" in keys:  # a layout by detector (from cell keys) sets them side by side itself
        table = build_table(rows, layout, metric)
        table.label = label_
        table.caption = f"{layout.title or 'Protocol'}: every detector side by side."
        return table
    per = summarize(rows, ["detector", *keys], metric)
    per = per[per["status"] == "ok"]
    if per.empty:  # every cell skipped or failed: each detector's own table says why
        return None
    by = ["detector", layout.column] + ([layout.pair] if layout.pair else [])
    avg = per.groupby(by, dropna=False).agg(
        mean=("mean", "mean"), units=("mean", "size"), low=("low_n", "any")
    )
    found = {k if isinstance(k, tuple) else (k,): r for k, r in avg.iterrows()}
    columns = ordered(rows[layout.column].dropna().unique(), layout.column)

    def one(key: tuple) -> str:
        r = found.get(key)
        return "NA" if r is None else figure_text(CellFigure(r["mean"], low=bool(r["low"])))

    cells = [
        [
            f"{one((d, c, 'with'))} {one((d, c, 'without'))}*" if layout.pair else one((d, c))
            for c in columns
        ]
        for d in detectors
    ]
    plain, marked, notes = _column_labels(layout, rows, columns)
    units = avg["units"]
    notes.append(
        f"Mean over units ({' and '.join(ROW_HEADERS.get(k, k).lower() for k in layout.rows)}) of each "
        f"unit's figure; {int(units.min())} units per figure"
        + (f" or up to {int(units.max())}" if units.max() != units.min() else "")
        + " (units a detector did not finish are left out)."
    )
    notes += data_notes(rows)
    group = f"{figure_label(metric)} (%) {layout.group}".strip()
    caption = f"{layout.title or 'Protocol'}: every detector side by side."
    return Table(
        caption, ["Detector"], group, plain, [(d,) for d in detectors], cells, label_, marked, notes
    )


def _metrics_side_by_side(
    rows: pd.DataFrame, layout: ShownLayout, detectors: Sequence[str], label_: str
) -> Table:
    """A layout with several metrics (streaming): a row per detector, a column per metric, each
    the mean over units of each unit's figure (mean over seeds)."""
    keys = [k for k in layout.rows if k in rows]
    cells = []
    for d in detectors:
        line = []
        for m in layout.metrics:
            per = summarize(rows[rows["detector"] == d], keys, m)
            per = per[per["status"] == "ok"]
            line.append(
                metric_text(m, CellFigure(per["mean"].mean(), low=bool(per["low_n"].any())))
                if len(per)
                else "NA"
            )
        cells.append(line)
    units = " and ".join(ROW_HEADERS.get(k, k).lower() for k in keys)
    return Table(
        f"{layout.title or 'Protocol'}: every detector side by side.",
        ["Detector"],
        layout.group,
        [metric_header(m) for m in layout.metrics],
        [(d,) for d in detectors],
        cells,
        label_,
        notes=[f"Mean over units ({units}) of each unit's figure."]
        + ([STREAM_LOW_NOTE] if any(LOW_MARK in c for line in cells for c in line) else [])
        + data_notes(rows),
    )


def split_table(
    rows: pd.DataFrame,
    splits: Sequence[str],
    metric: str = "accuracy",
    protocols: Sequence[str] = (),
    detectors: Sequence[str] = (),
) -> Table | None:
    """Per protocol and detector (in these orders), the mean ``metric`` of the cells every split
    finished, per split, and each other split minus the first: the mean change and its range
    over cells. None where no cell has the figure on every split (streaming rows have no accuracy)."""
    first, others = splits[0], list(splits[1:])
    ok = rows[rows["status"] == "ok"] if "status" in rows else rows
    if metric not in ok or ok[metric].isna().all():
        return None
    # a setting that differs (labels, dataset, ...) names the protocol's line: never pooled
    named = setting_labels(ok, exclude=("split",)).map(lambda t: f" ({t})" if t else "")
    ok = ok.assign(protocol=ok["protocol"].astype(str) + named)
    keys = [*ENTRANT_CELL, "seed"]
    wide = ok.pivot_table(index=keys, columns="split", values=metric, aggfunc="mean")
    wide = (
        wide.dropna(subset=[s for s in splits if s in wide])
        if set(splits) <= set(wide.columns)
        else wide.iloc[:0]
    )
    if wide.empty:
        return None
    lines, cells = [], []
    for (protocol, detector), part in wide.groupby(level=["protocol", "detector"]):
        line = [str(len(part)), *(f"{100 * part[s].mean():.1f}" for s in splits)]
        for s in others:
            d = 100 * (part[s] - part[first])
            line.append(f"{d.mean():+.1f} [{d.min():+.1f}, {d.max():+.1f}]")
        lines.append((protocol, detector))
        cells.append(line)
    order = {p: i for i, p in enumerate(protocols)}
    by = sorted(
        range(len(lines)),
        key=lambda i: (
            order.get(lines[i][0].split(" (")[0], len(order)),
            lines[i][0],
            rank([d for _, d in lines], detectors).index(lines[i][1]),
        ),
    )
    what = metric.replace("_", " ")
    return Table(
        f"The {first} split beside the {', '.join(others)} split: mean {what} (%) over the cells both "
        "finished, and the difference.",
        ["Protocol", "Detector"],
        "",
        ["cells", *splits, *(f"{s} − {first} [min, max]" for s in others)],
        [lines[i] for i in by],
        [cells[i] for i in by],
        "tab:splits",
        notes=[
            "grouped: whole trials on one side of the split for every unit, so no test trial has a twin "
            "recording (another finger, the same trial) that trained the model; paper: windows shuffled "
            "and halved, as the paper did. A positive difference is what the paper's split gains from "
            "testing on trials it trained on."
        ],
    )
