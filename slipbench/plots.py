"""Figures from result rows (matplotlib, Agg backend): PNG and PDF per protocol and detector,
of the kind each protocol's layout declares (``Layout.figure``):

- "curve": accuracy against ``Layout.x`` per sensor type, one line per finger with its 95 %
  interval as a band (optionally the paper's LSTM values as hollow markers);
- "with-without": heatmaps with and without explicit training (``Layout.pair``);
- "matrix": the last row key by the column key, one panel per sensor type (the transfer matrix);
- "tradeoff": median delay against false alarms per minute over a threshold sweep (a streaming
  cell's ``tradeoff`` column), one curve per detector and unit, one panel per sensor type, the
  detector's own threshold as a dot and the operating point as a cross.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only, never a window; must precede pyplot
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from .paper import paper_frame  # noqa: E402
from .protocol import Layout  # noqa: E402
from .report import SPLIT_ORDER, _sections, layouts, split_parts  # noqa: E402
from .tables import label, ordered, rank, summarize  # noqa: E402

FORMATS = ("png", "pdf")


def _save(fig, folder: Path, stem: str) -> list[Path]:
    paths = []
    for ext in FORMATS:
        path = folder / f"{stem}.{ext}"
        # a fixed creation date keeps PDFs byte-identical across runs
        fig.savefig(path, dpi=150, bbox_inches="tight", metadata={"CreationDate": None} if ext == "pdf" else None)
        paths.append(path)
    plt.close(fig)
    return paths


def _curves(rows: pd.DataFrame, x: str, title: str, xlabel: str, paper: pd.DataFrame | None, log_base: int,
            line: str = "sensor_instance", splits: list[str] = ()):
    """One panel per sensor type; one line per finger (and each combination of the ``splits``
    columns that vary, e.g. decimation) with its interval band."""
    sensors = ordered(rows["sensor_type"].unique(), "sensor_type")
    fig, axes = plt.subplots(1, len(sensors), figsize=(4.2 * len(sensors), 3.4), sharey=True, squeeze=False)
    extra = [c for c in splits if c in rows and rows[c].nunique(dropna=False) > 1]
    variants = sorted(rows[extra].drop_duplicates().itertuples(index=False, name=None),
                      key=lambda v: [rank(rows[c].unique(), SPLIT_ORDER).index(x) for c, x in zip(extra, v)]) if extra else [()]
    styles = dict(zip(variants, ("-", "--", ":", "-.") * len(variants)))  # the first (the paper's) solid
    for ax, sensor in zip(axes[0], sensors):
        part = rows[rows["sensor_type"] == sensor]
        s = summarize(part, [line, *extra, x])
        for i, inst in enumerate(ordered(s[line].unique(), line)):
            color = f"C{i}"
            for dec, points in s[s[line] == inst].groupby(extra) if extra else [((), s[s[line] == inst])]:
                points = points.sort_values(x)
                name = label(line, inst) + (f" ({', '.join(str(v) for v in dec)})" if extra else "")
                ax.plot(points[x], 100 * points["mean"], styles.get(tuple(dec), "-"), marker="o", ms=3, color=color, label=name)
                ax.fill_between(points[x], 100 * points["lo"], 100 * points["hi"], color=color, alpha=0.15, lw=0)
            if paper is not None and len(paper) and line in paper and x in paper:
                ref = paper[(paper["sensor_type"] == sensor) & (paper[line] == inst)].sort_values(x)
                ax.plot(ref[x], 100 * ref["accuracy"], "o", mfc="none", color=color, ms=6,
                        label=f"{label(line, inst)}, paper (LSTM)")
        if log_base:
            ax.set_xscale("log", base=log_base)
        ax.set_title(label("sensor_type", sensor))
        ax.set_xlabel(xlabel)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    axes[0][0].set_ylabel("accuracy (%)")
    fig.suptitle(title)
    return fig


def _heatmaps(rows: pd.DataFrame, column: str, pair: str, title: str):
    """With and without explicit training (``pair``) side by side; rows sensor/finger, columns ``column``."""
    s = summarize(rows, ["sensor_type", "sensor_instance", column, pair])
    index = s[["sensor_type", "sensor_instance"]].drop_duplicates()
    index = sorted(index.itertuples(index=False, name=None), key=lambda t: (
        ordered(s["sensor_type"].unique(), "sensor_type").index(t[0]),
        ordered(s["sensor_instance"].unique(), "sensor_instance").index(t[1])))
    cols = ordered(s[column].unique(), column)
    fig, axes = plt.subplots(1, 2, figsize=(2 + 1.6 * len(cols) * 2, 0.45 * len(index) + 1.8), squeeze=False)
    for ax, training in zip(axes[0], ("with", "without")):
        grid = np.full((len(index), len(cols)), np.nan)
        for r in s[(s[pair] == training) & (s["status"] == "ok")].to_dict("records"):
            grid[index.index((r["sensor_type"], r["sensor_instance"])), cols.index(r[column])] = 100 * r["mean"]
        names = [f"{label('sensor_type', a)} {label('sensor_instance', b)}" for a, b in index]
        _matrix(ax, grid, names if training == "with" else None, [label(column, c) for c in cols],
                colorbar=training == "without")
        ax.set_title(f"{training} explicit training" + ("" if training == "with" else " (*)"))
    fig.suptitle(title)
    return fig


def _matrix(ax, grid: np.ndarray, ylabels: list[str] | None, xlabels: list[str], colorbar: bool = True) -> None:
    """An annotated accuracy heatmap on a fixed 50-100 % scale, so panels compare by colour."""
    im = ax.imshow(grid, cmap="viridis", vmin=50, vmax=100, aspect="auto")
    ax.set_xticks(range(len(xlabels)), xlabels, rotation=30, ha="right")
    ax.set_yticks(range(grid.shape[0]), ylabels if ylabels is not None else [])
    for (i, j), v in np.ndenumerate(grid):
        ax.text(j, i, "NA" if np.isnan(v) else f"{v:.1f}", ha="center", va="center", fontsize=7,
                color="white" if not np.isnan(v) and v < 80 else "black")
    if colorbar:
        ax.figure.colorbar(im, ax=ax, fraction=0.046, label="accuracy (%)")


def _transfer(rows: pd.DataFrame, row: str, column: str, title: str):
    """``row`` by ``column`` (training by test instance), one panel per sensor type."""
    sensors = ordered(rows["sensor_type"].unique(), "sensor_type")
    fig, axes = plt.subplots(1, len(sensors), figsize=(4.4 * len(sensors), 3.8), squeeze=False, layout="constrained")
    for n, (ax, sensor) in enumerate(zip(axes[0], sensors)):
        s = summarize(rows[rows["sensor_type"] == sensor], [row, column])
        tr = ordered(s[row].unique(), row)
        te = ordered(s[column].unique(), column)
        grid = np.full((len(tr), len(te)), np.nan)
        for r in s[s["status"] == "ok"].to_dict("records"):
            grid[tr.index(r[row]), te.index(r[column])] = 100 * r["mean"]
        _matrix(ax, grid, [label(row, t) for t in tr], [label(column, t) for t in te],
                colorbar=n == len(sensors) - 1)
        if n == 0:
            ax.set_ylabel("trained on")
        ax.set_xlabel("tested on")
        ax.set_title(label("sensor_type", sensor))
    fig.suptitle(title)
    return fig


def tradeoff(rows: pd.DataFrame, title: str):
    """Median delay (ms) against false alarms per minute, from the streaming rows' sweeps: one
    panel per sensor type, a colour per detector, a line style per unit; each row's own
    threshold a dot, its operating point a cross. None when no row holds a sweep."""
    rows = rows[rows["status"] == "ok"] if "status" in rows else rows
    if "tradeoff" not in rows or rows["tradeoff"].dropna().empty:
        return None
    rows = rows[rows["tradeoff"].notna()]
    sensors = ordered(rows["sensor_type"].unique(), "sensor_type")
    detectors = rank(rows["detector"].unique(), ("holweg", "lstm"))
    fig, axes = plt.subplots(1, len(sensors), figsize=(4.2 * len(sensors), 3.6), sharey=True, squeeze=False)
    for ax, sensor in zip(axes[0], sensors):
        part = rows[rows["sensor_type"] == sensor]
        units = ordered(part["sensor_instance"].unique(), "sensor_instance")
        for d, detector in enumerate(detectors):
            for u, unit in enumerate(units):
                for _, row in part[(part["detector"] == detector) & (part["sensor_instance"] == unit)].iterrows():
                    curve = pd.DataFrame(json.loads(row["tradeoff"])).dropna(subset=["median_delay_ms", "false_alarms_per_min"])
                    curve = curve.sort_values(["false_alarms_per_min", "median_delay_ms"])
                    ax.plot(curve["false_alarms_per_min"], curve["median_delay_ms"], ("-", "--", ":", "-.")[u % 4], color=f"C{d}",
                            lw=1, label=f"{detector}, {label('sensor_instance', unit)}")
                    ax.plot(row["false_alarms_per_min"], row["median_delay_ms"], "o", color=f"C{d}", ms=4)
                    if pd.notna(row.get("op_median_delay_ms", np.nan)):
                        ax.plot(row["op_false_alarms_per_min"], row["op_median_delay_ms"], "x", color=f"C{d}", ms=5)
        ax.set_xscale("symlog", linthresh=1.0)  # 0 false alarms is a result worth seeing
        ax.set_xlabel("false alarms per minute")
        ax.set_title(label("sensor_type", sensor))
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6)
    axes[0][0].set_ylabel("median delay (ms)")
    fig.suptitle(title)
    return fig


def figure(part: pd.DataFrame, layout: Layout, title: str, paper: bool):
    """The figure ``layout.figure`` asks for, or None (no figure kind, or rows it cannot draw)."""
    if layout.figure is None or "sensor_type" not in part:
        return None
    if layout.figure == "curve":
        x = layout.x or layout.column
        ref = paper_frame(layout.paper_table) if paper and layout.paper_table else None
        return _curves(part, x, f"Accuracy against {layout.title.lower() or x}: {title}", layout.x_label or x, ref,
                       log_base=layout.log_base, line=layout.rows[-1], splits=layout.splits)
    if layout.figure == "tradeoff":
        return tradeoff(part, f"Delay against false alarms: {title}")
    if layout.figure == "with-without":
        return _heatmaps(part, layout.column, layout.pair, f"Accuracy per {layout.title.lower() or layout.column}: {title}")
    return _transfer(part, layout.rows[-1], layout.column, f"{layout.title or 'Accuracy'}: {title}")


def write_plots(rows: pd.DataFrame, folder: str | os.PathLike, paper: bool = True) -> list[Path]:
    """Every figure the rows allow, as ``<protocol>-<detector>[-<split>].png/.pdf`` in ``folder``.

    ``paper`` overlays the published LSTM accuracies on curves whose layout names a paper table.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    found = layouts(rows)
    paths: list[Path] = []
    for protocol, detector, split, part in _sections(rows, found):
        variants = split_parts(part, found[protocol][0])  # one figure per table
        for which, rows_ in variants:
            named = "".join(f", {c} {v}" for c, v in which.items()) if len(variants) > 1 else ""
            fig = figure(rows_, found[protocol][0], f"{detector} ({split} split{named})", paper)
            if fig is not None:
                stem = f"{protocol}-{detector}" + ("" if split == "paper" else f"-{split}")
                paths += _save(fig, folder, stem + ("".join(f"-{v}" for v in which.values()) if named else ""))
    for protocol, (layout, _) in found.items():  # trade-offs: every detector on one figure
        prows = rows[rows["protocol"] == protocol]
        if layout.figure == "tradeoff" and prows["detector"].nunique() > 1:
            fig = tradeoff(prows, f"Delay against false alarms: {protocol}, every detector")
            if fig is not None:
                paths += _save(fig, folder, f"{protocol}-detectors")
    return paths
