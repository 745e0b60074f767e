"""Figures from result rows (matplotlib, Agg backend): PNG and PDF per protocol and detector.

- window size and sampling rate: accuracy per sensor type, one line per finger with its 95 %
  interval as a band (optionally the paper's LSTM values as hollow markers);
- material and speed: heatmaps with and without explicit training;
- cross-instance: the transfer matrix, training instance by test instance.
"""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only, never a window; must precede pyplot
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from .report import _ordered, _sections, label, paper_frame, summarize  # noqa: E402

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


def _curves(rows: pd.DataFrame, x: str, title: str, xlabel: str, paper: pd.DataFrame | None, log2: bool):
    """One panel per sensor type; one line per finger (and decimation) with its interval band."""
    sensors = _ordered(rows["sensor_type"].unique(), "sensor_type")
    fig, axes = plt.subplots(1, len(sensors), figsize=(4.2 * len(sensors), 3.4), sharey=True, squeeze=False)
    styles = {"plain": "-", "antialias": "--"}
    extra = ["decimation"] if "decimation" in rows and rows["decimation"].nunique() > 1 else []
    for ax, sensor in zip(axes[0], sensors):
        part = rows[rows["sensor_type"] == sensor]
        s = summarize(part, ["sensor_instance", *extra, x])
        for i, inst in enumerate(_ordered(s["sensor_instance"].unique(), "sensor_instance")):
            color = f"C{i}"
            for dec, line in s[s["sensor_instance"] == inst].groupby(extra) if extra else [((None,), s[s["sensor_instance"] == inst])]:
                line = line.sort_values(x)
                name = label("sensor_instance", inst) + (f" ({dec[0]})" if extra else "")
                ax.plot(line[x], 100 * line["mean"], styles.get(dec[0], "-"), marker="o", ms=3, color=color, label=name)
                ax.fill_between(line[x], 100 * line["lo"], 100 * line["hi"], color=color, alpha=0.15, lw=0)
            if paper is not None and len(paper):
                ref = paper[(paper["sensor_type"] == sensor) & (paper["sensor_instance"] == inst)].sort_values(x)
                ax.plot(ref[x], 100 * ref["accuracy"], "o", mfc="none", color=color, ms=6,
                        label=f"{label('sensor_instance', inst)}, paper (LSTM)")
        ax.set_xscale("log", base=2 if log2 else 10)
        ax.set_title(label("sensor_type", sensor))
        ax.set_xlabel(xlabel)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    axes[0][0].set_ylabel("accuracy (%)")
    fig.suptitle(title)
    return fig


def _heatmaps(rows: pd.DataFrame, column: str, title: str):
    """With and without explicit training side by side; rows sensor/finger, columns ``column``."""
    s = summarize(rows, ["sensor_type", "sensor_instance", column, "training"])
    index = s[["sensor_type", "sensor_instance"]].drop_duplicates()
    index = sorted(index.itertuples(index=False, name=None), key=lambda t: (
        _ordered(s["sensor_type"].unique(), "sensor_type").index(t[0]),
        _ordered(s["sensor_instance"].unique(), "sensor_instance").index(t[1])))
    cols = _ordered(s[column].unique(), column)
    fig, axes = plt.subplots(1, 2, figsize=(2 + 1.6 * len(cols) * 2, 0.45 * len(index) + 1.8), squeeze=False)
    for ax, training in zip(axes[0], ("with", "without")):
        grid = np.full((len(index), len(cols)), np.nan)
        for r in s[(s["training"] == training) & (s["status"] == "ok")].to_dict("records"):
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


def _transfer(rows: pd.DataFrame, title: str):
    sensors = _ordered(rows["sensor_type"].unique(), "sensor_type")
    fig, axes = plt.subplots(1, len(sensors), figsize=(4.4 * len(sensors), 3.8), squeeze=False, layout="constrained")
    for n, (ax, sensor) in enumerate(zip(axes[0], sensors)):
        s = summarize(rows[rows["sensor_type"] == sensor], ["train_instance", "test_instance"])
        tr = _ordered(s["train_instance"].unique(), "train_instance")
        te = _ordered(s["test_instance"].unique(), "test_instance")
        grid = np.full((len(tr), len(te)), np.nan)
        for r in s[s["status"] == "ok"].to_dict("records"):
            grid[tr.index(r["train_instance"]), te.index(r["test_instance"])] = 100 * r["mean"]
        _matrix(ax, grid, [label("train_instance", t) for t in tr], [label("test_instance", t) for t in te],
                colorbar=n == len(sensors) - 1)
        if n == 0:
            ax.set_ylabel("trained on")
        ax.set_xlabel("tested on")
        ax.set_title(label("sensor_type", sensor))
    fig.suptitle(title)
    return fig


def write_plots(rows: pd.DataFrame, folder: str | os.PathLike, paper: bool = True) -> list[Path]:
    """Every figure the rows allow, as ``<protocol>-<detector>[-<split>].png/.pdf`` in ``folder``.

    ``paper`` overlays the published LSTM accuracies on the window-size and sampling-rate curves.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths: list[Path] = []
    for protocol, detector, split, part in _sections(rows):
        stem = f"{protocol}-{detector}" + ("" if split == "paper" else f"-{split}")
        title = f"{detector} ({split} split)"
        if protocol == "window-size":
            fig = _curves(part, "window", f"Accuracy against window size: {title}", "window (samples)",
                          paper_frame(protocol) if paper else None, log2=False)
        elif protocol == "sampling-rate":
            fig = _curves(part, "rate_hz", f"Accuracy against sampling rate (window 200): {title}", "sampling rate (Hz)",
                          paper_frame(protocol) if paper else None, log2=True)
        elif protocol == "material-holdout":
            fig = _heatmaps(part, "material", f"Accuracy per material: {title}")
        elif protocol == "speed-holdout":
            fig = _heatmaps(part, "speed_mm_s", f"Accuracy per slip speed: {title}")
        elif protocol == "cross-instance":
            fig = _transfer(part, f"Cross-instance transfer: {title}")
        else:
            continue  # plugin protocols have tables, not figures
        paths += _save(fig, folder, stem)
    return paths
