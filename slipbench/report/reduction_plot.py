"""The figure of "What the reduction keeps": per sensor type, the change channels - univariate
in accuracy of each detector and protocol (a forest plot), in the style of
:mod:`slipbench.report.plots`."""

from __future__ import annotations

import textwrap

import matplotlib
import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from slipbench.report.order import ordered
from slipbench.report.plots import STYLE, TITLE_CHARS, WIDTH
from slipbench.vocabulary import SENSOR_TYPE, label

# a reading's colour: better blue, worse red (as the difference heatmaps), the rest grey
COLOURS = {
    "channels better": "#2166ac",
    "channels worse": "#b2182b",
    "within the margin": "0.1",
    "undecided": "0.35",
    "inconclusive": "0.6",
}


def input_changes(pooled: pd.DataFrame, cells: pd.DataFrame) -> Figure | None:
    """One panel per sensor type, one line per detector and protocol (and split, where there
    are several): the mean change over its cells (marker, coloured by its reading) with its
    interval (bar), each cell's own change (grey dots), and a zero line. ``pooled`` and
    ``cells`` are :class:`~slipbench.gate.reduction.InputComparison`'s, lines in the order
    ``pooled`` gives them. None when nothing was compared."""
    if pooled.empty:
        return None
    with matplotlib.rc_context(STYLE):
        return _draw(pooled, cells)


def _draw(pooled: pd.DataFrame, cells: pd.DataFrame) -> Figure:
    sensors = ordered(pooled[SENSOR_TYPE].unique(), SENSOR_TYPE)
    splits = pooled["split"].nunique() > 1
    counts = [int((pooled[SENSOR_TYPE] == s).sum()) for s in sensors]
    fig = Figure(figsize=(WIDTH, 1.0 + sum(0.4 + 0.25 * n for n in counts)), layout="constrained")
    axes = fig.subplots(len(sensors), 1, squeeze=False, sharex=True, height_ratios=counts)[:, 0]
    for ax, sensor in zip(axes, sensors):
        part = pooled[pooled[SENSOR_TYPE] == sensor].reset_index(drop=True)
        names = []
        for y, r in enumerate(part.to_dict("records")):
            names.append(
                f"{r['detector']}\n{r['protocol']}" + (f", {r['split']}" if splits else "")
            )
            mine = cells[
                (cells[SENSOR_TYPE] == sensor)
                & (cells["detector"] == r["detector"])
                & (cells["protocol"] == r["protocol"])
                & (cells["split"] == r["split"])
            ]
            # each cell's change a dot, spread a little in y so that equal changes stay visible
            jitter = np.linspace(-0.22, 0.22, len(mine)) if len(mine) > 1 else np.zeros(len(mine))
            ax.plot(100 * mine["d_accuracy"], y + jitter, "o", color="0.6", ms=1.8, alpha=0.7)
            d, lo, hi = (100 * r[f"d_accuracy{b}"] for b in ("", "_lo", "_hi"))
            if np.isfinite(lo) and np.isfinite(hi):
                ax.plot([lo, hi], [y, y], "-", color=COLOURS[r["reading"]], lw=1.6)
            ax.plot(d, y, "D", color=COLOURS[r["reading"]], ms=4)
        ax.axvline(0, color="black", lw=0.8)
        ax.set_yticks(range(len(names)), names)
        ax.set_ylim(len(names) - 0.5, -0.5)  # the first line on top
        ax.set_title(label(SENSOR_TYPE, sensor), loc="left", pad=2)
        ax.grid(axis="x", alpha=0.3)
    axes[-1].set_xlabel("channels − univariate, accuracy (points)")
    shown = [k for k in COLOURS if k in set(pooled["reading"])]
    keys = [Line2D([], [], marker="D", color=COLOURS[k], ms=4, lw=1.6) for k in shown]
    keys.append(Line2D([], [], ls="", marker="o", color="0.6", ms=2.5))
    fig.legend(
        keys,
        [*shown, "a cell"],
        loc="outside lower center",
        ncols=min(3, len(keys)),
        frameon=False,
    )
    fig.suptitle(textwrap.fill("Channels against the univariate signal", TITLE_CHARS))
    return fig
