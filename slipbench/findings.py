"""How the paper's findings fare: one contrast per published table, computed alike on the
published numbers and on each detector's rows, from the protocol's layout (never its name):

- a "curve" (accuracy against window size, sampling rate): the change from the smallest to the
  largest ``x``, per sensor type, mean over units;
- a "with-without" pair (material, speed): the mean change without explicit training, and the
  level that loses most;
- a "matrix" (training unit by test unit): the transfer penalty, the mean accuracy on the unit
  trained on minus on the other units (combined training and testing left out).

A layout split into several tables (decimation, anti-aliasing) is read at its first table, the
paper's reading.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .paper import paper_frame
from .protocol import Layout
from .tables import Table, label, ordered, rank, summarize

COMBINED = "combined"


def _means(rows: pd.DataFrame, keys: list[str], values: str) -> pd.DataFrame:
    """Per combination of ``keys``: the mean over seeds of each cell's figure; for published
    numbers (``values == "paper"``) the numbers themselves."""
    if values == "paper":
        return rows[[*keys, "accuracy"]].rename(columns={"accuracy": "mean"})
    s = summarize(rows, keys)
    return s[s["status"] == "ok"][[*keys, "mean"]]


def _curve(rows: pd.DataFrame, layout: Layout, values: str, ends: dict | None = None) -> dict[str, float]:
    """Per sensor type: the mean over units at the largest ``x`` minus at the smallest; with
    ``ends`` (sensor type -> (smallest, largest), the paper's), only where the rows hold both."""
    x, unit = layout.x or layout.column, layout.rows[-1]
    m = _means(rows, ["sensor_type", unit, x], values)
    out = {}
    for sensor, part in m.groupby("sensor_type"):
        by_x = part.groupby(x)["mean"].mean().sort_index()
        lo, hi = (by_x.index[0], by_x.index[-1]) if ends is None else ends.get(sensor, (None, None))
        if len(by_x) > 1 and lo in by_x.index and hi in by_x.index:
            out[sensor] = 100 * (by_x[hi] - by_x[lo])
    return out


def _ends(rows: pd.DataFrame, layout: Layout) -> dict:
    x = layout.x or layout.column
    return {s: (part[x].min(), part[x].max()) for s, part in rows.groupby("sensor_type")}


def _pair(rows: pd.DataFrame, layout: Layout, values: str) -> tuple[float, str]:
    """The mean change without explicit training (points) and the level losing most."""
    keys = [*layout.rows, layout.column]
    m = _means(rows, [*keys, layout.pair], values).pivot_table(index=keys, columns=layout.pair, values="mean")
    if not {"with", "without"} <= set(m.columns):
        return np.nan, ""
    change = 100 * (m["without"] - m["with"]).dropna()
    if change.empty:
        return np.nan, ""
    per_level = change.groupby(level=layout.column).mean()
    worst = per_level.idxmin()
    return float(change.mean()), f"{label(layout.column, worst)} ({per_level[worst]:+.1f})"


def _matrix(rows: pd.DataFrame, layout: Layout, values: str) -> float:
    """Mean accuracy on the unit trained on minus on the other units (points)."""
    row, column = layout.rows[-1], layout.column
    m = _means(rows, ["sensor_type", row, column], values)
    m = m[(m[row] != COMBINED) & (m[column] != COMBINED)]
    same, other = m[m[row] == m[column]]["mean"], m[m[row] != m[column]]["mean"]
    return 100 * (same.mean() - other.mean()) if len(same) and len(other) else np.nan


def _first_table(rows: pd.DataFrame, layout: Layout) -> pd.DataFrame:
    from .sections import split_parts

    parts = split_parts(rows, layout)
    return parts[0][1] if parts else rows  # no rows (a detector that did not run the protocol): none


def findings_table(rows: pd.DataFrame, found: dict[str, tuple[Layout, str]], order: list[str]) -> Table | None:
    """One line per finding: the paper's value (its LSTM) and each detector's, in points."""
    from .sections import DETECTOR_ORDER

    detectors = rank(rows["detector"].unique(), DETECTOR_ORDER)
    lines: list[tuple[str, str, list[str]]] = []
    for protocol in order:
        layout = found[protocol][0]
        ref = paper_frame(layout.paper_table) if layout.paper_table else pd.DataFrame()
        if ref.empty or layout.figure is None:
            continue
        prows = rows[rows["protocol"] == protocol]
        ours = {d: _first_table(prows[prows["detector"] == d], layout) for d in detectors}
        if layout.figure == "curve":
            paper = _curve(ref, layout, "paper")
            mine = {d: _curve(r, layout, "ours", _ends(ref, layout)) for d, r in ours.items()}
            what = (layout.title or layout.x or layout.column).lower()
            for sensor in ordered(list(paper), "sensor_type"):
                lines.append((protocol, f"{label('sensor_type', sensor)}: accuracy from the smallest to the largest "
                              f"{what} (points)", [f"{paper[sensor]:+.1f}"]
                              + [f"{mine[d][sensor]:+.1f}" if sensor in mine[d] else "—" for d in detectors]))
        elif layout.figure == "with-without":
            paper = _pair(ref, layout, "paper")
            mine = {d: _pair(r, layout, "ours") for d, r in ours.items()}
            lines.append((protocol, "mean change without explicit training (points)",
                          [f"{v[0]:+.1f}" if np.isfinite(v[0]) else "—" for v in (paper, *mine.values())]))
            lines.append((protocol, f"the {(layout.title or layout.column).lower()} losing most without it",
                          [v[1] or "—" for v in (paper, *mine.values())]))
        else:
            paper = _matrix(ref, layout, "paper")
            mine = {d: _matrix(r, layout, "ours") for d, r in ours.items()}
            lines.append((protocol, "transfer penalty: the unit trained on minus other units (points)",
                          [f"{v:+.1f}" if np.isfinite(v) else "—" for v in (paper, *mine.values())]))
    if not lines:
        return None
    return Table("The paper's findings and ours: each contrast on the published table (the paper's LSTM) and on each "
                 "detector's results.", ["Protocol", "Finding"], "", ["paper (LSTM)", *detectors],
                 [(p, f) for p, f, _ in lines], [c for _, _, c in lines], "tab:findings", wrap={0: 0.12, 1: 0.24}, notes=[
                     "Means over units (sensor and finger) of each unit's figure; a curve from the paper's smallest "
                     "to its largest x (windows of 5 and 200 samples; the lowest and the full sampling rate), — where "
                     "the results lack either; a layout split into several tables is read at its first (plain "
                     "decimation, no anti-aliasing)."])
