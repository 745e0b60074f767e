"""Figures from result rows (matplotlib, no pyplot state), of the kinds each protocol's layout
declares (``Presentation.figure``), never chosen by a protocol's name:

- "curve": per detector, accuracy against ``Presentation.x`` with one line per finger and its 95 %
  interval as a band (the paper's LSTM values as hollow markers); across detectors, every
  detector on one axis per sensor type (mean over fingers, the range over fingers shaded) with
  the paper's LSTM as a dashed reference line;
- "with-without": per detector, heatmaps with and without explicit training (``Layout.pair``)
  and their difference;
- "matrix": per detector, the last row key by the column key, one panel per sensor type;
- "tradeoff": detection rate against false alarms per minute (log axis) over a threshold sweep
  (a streaming cell's ``tradeoff`` column, drawn as its monotone upper envelope), one panel per
  detector, one curve per unit coloured by sensor type, the detector's own threshold as a dot
  and the operating point as a cross;
- and the leaderboard's critical-difference diagram.

Every figure is drawn for a single column of print (3.5 in wide, 7 pt text), with one legend
per figure and units on every axis. Accuracy colour scales run from 50 % (chance), or lower
where a figure holds lower values, to 100 %: the scale shows the true range, nothing clamps.
"""

from __future__ import annotations

import json
import re
import textwrap
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any, ParamSpec, TypeVar

import matplotlib

matplotlib.use("Agg")  # files only, never a window; must precede any backend use
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.artist import Artist  # noqa: E402
from matplotlib.colors import TwoSlopeNorm  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from slipbench.errors import writing  # noqa: E402
from slipbench.report.order import ordered, rank
from slipbench.report.outline import Outline, Section, Split, split_parts  # noqa: E402
from slipbench.report.paper import paper_frame  # noqa: E402
from slipbench.report.presentation import ShownLayout  # noqa: E402
from slipbench.report.tables import summarize  # noqa: E402
from slipbench.stats.leaderboard import ALL, Leaderboard  # noqa: E402
from slipbench.stats.meta import MetaAnalysis  # noqa: E402
from slipbench.store.columns import DETECTION_RATE, FALSE_ALARMS  # noqa: E402
from slipbench.vocabulary import DETECTOR_ORDER, SENSOR_TYPE, SPLIT_ORDER, label  # noqa: E402

if TYPE_CHECKING:
    from matplotlib.typing import RcKeyType

IMAGE_FORMATS = ("png", "pdf")
WIDTH = 3.5  # inches: one column of a two-column paper
TITLE_CHARS = 60  # a title wraps to the figure's width at its font size
DPI = 200
STYLE: dict[RcKeyType, Any] = {
    "font.size": 7,
    "axes.titlesize": 7,
    "axes.labelsize": 7,
    "xtick.labelsize": 6.5,
    "ytick.labelsize": 6.5,
    "legend.fontsize": 6.5,
    "figure.titlesize": 7.5,
    "lines.linewidth": 1.1,
    "lines.markersize": 3,
}
CHANCE = 50.0
AXIS_LABELS = {  # a key column's axis label with its unit, where the layout gives none
    "window": "window (samples)",
    "window_ms": "window (ms)",
    "rate_hz": "sampling rate (Hz)",
    "speed_mm_s": "slip speed (mm/s)",
    "downsample": "downsampling factor",
}


@dataclass
class FigureSpec:
    """A figure to draw: its file stem, a caption, the protocol section it belongs to (None for
    the leaderboard's) and how to draw it (None: the rows hold nothing to draw)."""

    stem: str
    caption: str
    section: str | None
    draw: Callable[[], Figure | None]
    detector: str | None = None  # the detector it shows alone, None for every detector
    split: str | None = None


def _figure(height: float) -> Figure:
    return Figure(figsize=(WIDTH, height), layout="constrained")


_P = ParamSpec("_P")
_R = TypeVar("_R")


def _styled(draw: Callable[_P, _R]) -> Callable[_P, _R]:
    def inner(*args: _P.args, **kwargs: _P.kwargs) -> _R:
        with matplotlib.rc_context(STYLE):
            return draw(*args, **kwargs)

    inner.__doc__ = draw.__doc__
    return inner


def file_stem(name: str) -> str:
    """``name`` as a file name a Markdown link takes as it is: runs of anything but letters,
    digits and dots become one hyphen (``tcn (channels)-grouped`` -> ``tcn-channels-grouped``)."""
    return re.sub(r"[^A-Za-z0-9.]+", "-", name).strip("-")


def save(fig: Figure, folder: Path, stem: str) -> list[Path]:
    """``fig`` as ``stem.png`` and ``stem.pdf`` in ``folder``."""
    paths = []
    for ext in IMAGE_FORMATS:
        path = folder / f"{stem}.{ext}"
        # a fixed creation date keeps PDFs byte-identical across runs
        with writing(path):  # a full disk mid-write raises an OSError that names no file
            fig.savefig(path, dpi=DPI, metadata={"CreationDate": None} if ext == "pdf" else None)
        paths.append(path)
    return paths


def _legend_once(fig: Figure, axes) -> None:
    """One legend for the figure, under the panels, from every panel's labelled artists."""
    seen: dict[str, Artist] = {}
    for ax in axes:
        for handle, text in zip(*ax.get_legend_handles_labels()):
            seen.setdefault(text, handle)
    if seen:
        fig.legend(
            list(seen.values()),
            list(seen),
            loc="outside lower center",
            ncol=min(3, len(seen)),
            frameon=False,
        )


def _sensors(rows: pd.DataFrame) -> list[str]:
    return ordered(rows[SENSOR_TYPE].unique(), SENSOR_TYPE)


def _x_axis(ax, x: pd.Series, layout: ShownLayout) -> None:
    if layout.log_base:
        ax.set_xscale("log", base=layout.log_base)
        ticks = sorted(x.dropna().unique())
        ax.set_xticks(ticks, [f"{t:g}" for t in ticks])
        ax.minorticks_off()
    ax.grid(alpha=0.3)


@_styled
def _curves(
    rows: pd.DataFrame, layout: ShownLayout, title: str, paper: pd.DataFrame | None
) -> Figure:
    """One detector: one panel per sensor type, stacked; one line per finger (and per
    combination of the layout's ``split`` columns that vary) with its interval band."""
    x, line, splits = layout.x or layout.column, layout.rows[-1], layout.splits
    sensors = _sensors(rows)
    fig = _figure(0.6 + 1.35 * len(sensors))
    axes = fig.subplots(len(sensors), 1, squeeze=False)[
        :, 0
    ]  # each sensor its own x ticks (its rates)
    extra = [c for c in splits if c in rows and rows[c].nunique(dropna=False) > 1]
    variants = (
        sorted(
            rows[extra].drop_duplicates().itertuples(index=False, name=None),
            key=lambda v: [
                rank(rows[c].unique(), SPLIT_ORDER).index(x_) for c, x_ in zip(extra, v)
            ],
        )
        if extra
        else [()]
    )
    styles = dict(
        zip(variants, ("-", "--", ":", "-.") * len(variants))
    )  # the first (the paper's) solid
    for ax, sensor in zip(axes, sensors):
        s = summarize(rows[rows[SENSOR_TYPE] == sensor], [line, *extra, x])
        for i, inst in enumerate(ordered(s[line].unique(), line)):
            color = f"C{i}"
            for dec, points in (
                s[s[line] == inst].groupby(extra) if extra else [((), s[s[line] == inst])]
            ):
                points = points.sort_values(x)
                name = label(line, inst) + (f" ({', '.join(str(v) for v in dec)})" if extra else "")
                ax.plot(
                    points[x],
                    100 * points["mean"],
                    styles.get(tuple(dec), "-"),
                    marker="o",
                    color=color,
                    label=name,
                )
                ax.fill_between(
                    points[x], 100 * points["lo"], 100 * points["hi"], color=color, alpha=0.15, lw=0
                )
            if paper is not None and len(paper) and line in paper and x in paper:
                ref = paper[(paper[SENSOR_TYPE] == sensor) & (paper[line] == inst)].sort_values(x)
                ax.plot(ref[x], 100 * ref["accuracy"], "o", mfc="none", color=color, ms=5)
        if paper is not None and len(paper):
            ax.plot([], [], "o", mfc="none", color="0.3", ms=5, label="paper (LSTM)")
        _finish_panel(ax, sensor, rows.loc[rows[SENSOR_TYPE] == sensor, x], layout)
    return _finish_figure(fig, axes, layout, x, title)


def _finish_panel(ax, sensor: str, xs: pd.Series, layout: ShownLayout) -> None:
    """A sensor's panel of an accuracy curve: its x ticks, title and y label."""
    _x_axis(ax, xs, layout)
    ax.set_title(label(SENSOR_TYPE, sensor), loc="left", pad=2)
    ax.set_ylabel("accuracy (%)")


def _finish_figure(fig: Figure, axes, layout: ShownLayout, x: str, title: str) -> Figure:
    """Stacked panels: the x label under the last, one legend, the title wrapped to the width."""
    axes[-1].set_xlabel(layout.x_label or AXIS_LABELS.get(x, x))
    _legend_once(fig, axes)
    fig.suptitle(textwrap.fill(title, TITLE_CHARS))
    return fig


@_styled
def _compare_curves(
    rows: pd.DataFrame, layout: ShownLayout, title: str, paper: pd.DataFrame | None
) -> Figure:
    """Every detector on one axis per sensor type: the mean over fingers of each finger's
    figure (mean over seeds), the range over fingers shaded, the paper's LSTM dashed."""
    x, unit = layout.x or layout.column, layout.rows[-1]
    sensors = _sensors(rows)
    detectors = rank(rows["detector"].unique(), DETECTOR_ORDER)
    fig = _figure(0.75 + 1.35 * len(sensors))
    axes = fig.subplots(len(sensors), 1, squeeze=False)[
        :, 0
    ]  # each sensor its own x ticks (its rates)
    for ax, sensor in zip(axes, sensors):
        part = rows[rows[SENSOR_TYPE] == sensor]
        for i, det in enumerate(detectors):
            s = summarize(part[part["detector"] == det], [unit, x])
            s = s[s["status"] == "ok"]
            if s.empty:
                continue
            g = s.groupby(x)["mean"].agg(["mean", "min", "max"]).sort_index()
            ax.plot(g.index, 100 * g["mean"], marker="o", color=f"C{i}", label=det)
            ax.fill_between(
                g.index, 100 * g["min"], 100 * g["max"], color=f"C{i}", alpha=0.12, lw=0
            )
        if paper is not None and len(paper) and x in paper:
            ref = paper[paper[SENSOR_TYPE] == sensor].groupby(x)["accuracy"].mean().sort_index()
            ax.plot(
                ref.index,
                100 * ref,
                "--",
                color="black",
                marker="o",
                mfc="none",
                ms=4,
                lw=0.9,
                label="paper (LSTM)",
            )
        _finish_panel(ax, sensor, part[x], layout)
    return _finish_figure(fig, axes, layout, x, title)


def accuracy_range(*grids: np.ndarray) -> tuple[float, float]:
    """Colour limits of accuracy heatmaps: chance (50 %), or lower where the data go lower, to
    100 %, in steps of 5 points."""
    values = np.concatenate([g[np.isfinite(g)] for g in grids]) if grids else np.array([])
    low = min(CHANCE, 5 * np.floor(values.min() / 5)) if values.size else CHANCE
    return float(low), 100.0


def _matrix(
    ax,
    grid: np.ndarray,
    ylabels: list[str] | None,
    xlabels: list[str],
    limits: tuple[float, float] | None = None,
):
    """An annotated heatmap; text black or white by the colour under it. Without ``limits``, a
    difference: a diverging map around 0, figures signed."""
    fmt = "{:.1f}" if limits else "{:+.1f}"
    if limits is None:
        top = max(1.0, float(np.nanmax(np.abs(grid)))) if np.isfinite(grid).any() else 1.0
        norm = TwoSlopeNorm(0.0, -top, top)
        im = ax.imshow(grid, cmap="RdBu", norm=norm, aspect="auto")
    else:
        im = ax.imshow(grid, cmap="viridis", vmin=limits[0], vmax=limits[1], aspect="auto")
    ax.set_xticks(
        range(len(xlabels)),
        xlabels,
        rotation=30 if max(map(len, xlabels), default=0) > 4 else 0,
        ha="right" if max(map(len, xlabels), default=0) > 4 else "center",
    )
    ax.set_yticks(range(grid.shape[0]), ylabels if ylabels is not None else [])
    for (i, j), v in np.ndenumerate(grid):
        if np.isnan(v):
            ax.text(j, i, "NA", ha="center", va="center", fontsize=5.5, color="0.4")
            continue
        r, g, b, _ = im.cmap(im.norm(v))
        ax.text(
            j,
            i,
            fmt.format(v),
            ha="center",
            va="center",
            fontsize=5.5,
            color="white" if 0.299 * r + 0.587 * g + 0.114 * b < 0.5 else "black",
        )
    return im


@_styled
def _heatmaps(rows: pd.DataFrame, layout: ShownLayout, title: str) -> Figure:
    """With and without explicit training (``layout.pair``) and with minus without, stacked;
    rows sensor and finger, columns ``layout.column``."""
    column, pair = layout.column, layout.pair
    assert pair is not None  # drawn for with-without layouts only
    s = summarize(rows, [SENSOR_TYPE, "sensor_instance", column, pair])
    index = sorted(
        s[[SENSOR_TYPE, "sensor_instance"]].drop_duplicates().itertuples(index=False, name=None),
        key=lambda t: (
            ordered(s[SENSOR_TYPE].unique(), SENSOR_TYPE).index(t[0]),
            ordered(s["sensor_instance"].unique(), "sensor_instance").index(t[1]),
        ),
    )
    cols = ordered(s[column].unique(), column)
    grids = {}
    for training in ("with", "without"):
        grid = np.full((len(index), len(cols)), np.nan)
        for r in s[(s[pair] == training) & (s["status"] == "ok")].to_dict("records"):
            grid[index.index((r[SENSOR_TYPE], r["sensor_instance"])), cols.index(r[column])] = (
                100 * r["mean"]
            )
        grids[training] = grid
    limits = accuracy_range(*grids.values())
    names = [f"{label('sensor_type', a)} {label('sensor_instance', b)}" for a, b in index]
    xlabels = [label(column, c) for c in cols]
    fig = _figure(0.5 + 3 * (0.16 * len(index) + 0.5))
    axes = fig.subplots(3, 1, sharex=True)
    for ax, training in zip(axes, ("with", "without")):
        im = _matrix(ax, grids[training], names, xlabels, limits)
        ax.set_title(
            f"{training} explicit training" + ("" if training == "with" else " (*)"),
            loc="left",
            pad=2,
        )
        fig.colorbar(im, ax=ax, label="accuracy (%)", fraction=0.05, pad=0.02)
    im = _matrix(axes[2], grids["with"] - grids["without"], names, xlabels)
    axes[2].set_title("with minus without", loc="left", pad=2)
    fig.colorbar(im, ax=axes[2], label="difference (points)", fraction=0.05, pad=0.02)
    axes[2].set_xlabel(layout.x_label or AXIS_LABELS.get(column, (layout.title or column).lower()))
    fig.suptitle(textwrap.fill(title, TITLE_CHARS))
    return fig


@_styled
def _transfer(rows: pd.DataFrame, layout: ShownLayout, title: str) -> Figure:
    """The last row key by the column key (training by test unit), one panel per sensor type."""
    row, column = layout.rows[-1], layout.column
    sensors = _sensors(rows)
    summaries = {}
    for sensor in sensors:
        s = summarize(rows[rows[SENSOR_TYPE] == sensor], [row, column])
        tr, te = ordered(s[row].unique(), row), ordered(s[column].unique(), column)
        grid = np.full((len(tr), len(te)), np.nan)
        for r in s[s["status"] == "ok"].to_dict("records"):
            grid[tr.index(r[row]), te.index(r[column])] = 100 * r["mean"]
        summaries[sensor] = (tr, te, grid)
    limits = accuracy_range(*(g for _, _, g in summaries.values()))
    fig = _figure(0.5 + sum(0.2 * len(tr) + 0.55 for tr, _, _ in summaries.values()))
    axes = fig.subplots(
        len(sensors),
        1,
        squeeze=False,
        height_ratios=[len(tr) + 2 for tr, _, _ in summaries.values()],
    )[:, 0]
    for ax, sensor in zip(axes, sensors):
        tr, te, grid = summaries[sensor]
        im = _matrix(ax, grid, [label(row, t) for t in tr], [label(column, t) for t in te], limits)
        ax.set_ylabel("trained on")
        ax.set_title(label(SENSOR_TYPE, sensor), loc="left", pad=2)
        fig.colorbar(im, ax=ax, label="accuracy (%)", fraction=0.05, pad=0.02)
    axes[-1].set_xlabel("tested on")
    fig.suptitle(textwrap.fill(title, TITLE_CHARS))
    return fig


def envelope(curve: pd.DataFrame) -> pd.DataFrame:
    """The upper envelope of a threshold sweep: per false-alarm rate, the highest detection rate
    any threshold reaches at that rate or fewer, so the curve rises monotonically (a sweep's
    raw points saw-tooth where a lower threshold trades detections between scenarios).
    Columns ``false_alarms_per_min`` (ascending, distinct) and ``detection_rate``."""
    x, y = FALSE_ALARMS.name, DETECTION_RATE.name
    points = curve.dropna(subset=[x, y]).sort_values([x, y])
    best = points.groupby(x, sort=True)[y].max().cummax()
    return best.reset_index()


def _floor(rates: list[float]) -> tuple[float, float]:
    """(floor, decade): where a log axis draws 0 false alarms per minute (a third of the
    decade below the smallest rate above 0) and that decade (its first tick after 0)."""
    positive = [r for r in rates if r > 0]
    decade = 10 ** np.floor(np.log10(min(positive))) if positive else 0.1
    return float(decade / 3), float(decade)


@_styled
def tradeoff(rows: pd.DataFrame, title: str) -> Figure | None:
    """Detection rate (%) against false alarms per minute (log axis), from the streaming rows'
    sweeps: one panel per detector, one curve per unit (the sweep's upper envelope, monotone),
    a colour per sensor type; each row's own threshold a dot, its operating point a cross.
    Zero false alarms are drawn at the axis's left edge (its tick reads 0). None when no row
    holds a sweep."""
    rows = rows[rows["status"] == "ok"] if "status" in rows else rows
    if "tradeoff" not in rows or rows["tradeoff"].dropna().empty:
        return None
    rows = rows[rows["tradeoff"].notna()]
    sensors = ordered(rows[SENSOR_TYPE].unique(), SENSOR_TYPE)
    detectors = rank(rows["detector"].unique(), DETECTOR_ORDER)
    curves = {i: envelope(pd.DataFrame(json.loads(r["tradeoff"]))) for i, r in rows.iterrows()}
    alarms, detected = FALSE_ALARMS.name, DETECTION_RATE.name
    rates = [float(x) for c in curves.values() for x in c[alarms]]
    rates += [float(x) for x in rows[alarms].dropna()]
    if f"op_{alarms}" in rows:
        rates += [float(x) for x in rows[f"op_{alarms}"].dropna()]
    floor, decade = _floor(rates)
    ncols = 1 if len(detectors) < 3 else 2
    nrows = -(-len(detectors) // ncols)
    fig = _figure(0.95 + 1.25 * nrows)
    axes = fig.subplots(nrows, ncols, squeeze=False, sharex=True, sharey=True)
    for ax in axes.flat[len(detectors) :]:
        ax.set_visible(False)
    for ax, detector in zip(axes.flat, detectors):
        part = rows[rows["detector"] == detector]
        for i, row in part.iterrows():
            color = f"C{sensors.index(row['sensor_type'])}"
            curve = curves[i]
            ax.plot(
                np.maximum(curve[alarms], floor),
                100 * curve[detected],
                "-",
                color=color,
                lw=0.8,
                alpha=0.8,
                drawstyle="steps-post",  # the envelope holds its rate until the next point
            )
            for prefix, marker in (("", "o"), ("op_", "x")):
                x, y = row.get(prefix + alarms), row.get(prefix + detected)
                if pd.notna(x) and pd.notna(y):
                    ax.plot(
                        max(float(x), floor),
                        100 * float(y),
                        marker,
                        color=color,
                        ms=3.5,
                        mfc="none",
                    )
        ax.set_xscale("log")
        ax.set_title(detector, loc="left", pad=2)
        ax.set_ylim(-3, 103)
        ax.grid(alpha=0.3)
    for ax in axes[:, 0]:
        ax.set_ylabel("detection rate (%)")
    for ax in axes[-1, :]:
        ax.set_xlabel("false alarms per minute")
    for ax in axes.flat[len(detectors) - ncols : len(detectors)]:
        ax.xaxis.set_tick_params(labelbottom=True)  # the last row's panel above an empty slot
        ax.set_xlabel("false alarms per minute")
    _zero_tick(axes.flat[0], floor, decade)
    from matplotlib.lines import Line2D

    keys = [Line2D([], [], color=f"C{i}", lw=1) for i in range(len(sensors))]
    keys += [Line2D([], [], ls="", marker=m, color="0.3", mfc="none", ms=3.5) for m in "ox"]
    names = [label(SENSOR_TYPE, s) for s in sensors] + ["threshold 0.5", "operating point"]
    fig.legend(keys, names, loc="outside lower center", ncols=min(len(names), 3), frameon=False)
    fig.suptitle(textwrap.fill(title, TITLE_CHARS))
    return fig


def _zero_tick(ax, floor: float, decade: float) -> None:
    """The shared log axis: 0 at ``floor``, then every decade from ``decade`` up."""
    from matplotlib.ticker import FixedLocator, FuncFormatter

    top = max(ax.get_xlim()[1], decade * 10)
    ax.set_xlim(floor / 1.5, top)
    ax.xaxis.set_minor_locator(FixedLocator([]))
    ticks = [floor] + [decade * 10**k for k in range(int(np.ceil(np.log10(top / decade))) + 1)]
    ax.xaxis.set_major_locator(FixedLocator(ticks))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: "0" if v <= floor else f"{v:g}"))


@_styled
def critical_difference(board: Leaderboard) -> Figure:
    """The leaderboard's critical-difference diagram: per scope (every cell, then each
    protocol), the detectors at their mean rank on a rank axis (1 = best, on the left), and a
    bar joining each group shown not to differ (the leaderboard's pairwise tests; an undecided
    pair joins none).

    Drawn here rather than with aeon's ``plot_critical_difference``: that recomputes its own
    tests (its "holm" is a fixed alpha / (k - 1), not Holm's step-down) and cannot take the
    leaderboard's, so its bars could disagree with the table beside it; and aeon is optional.
    """
    scopes = [s for s in board.scopes if s.n_cells]
    k = len(board.order)
    rows_per = (k + 1) // 2
    heights = [0.55 + 0.13 * rows_per + 0.06 * len(s.groups) for s in scopes]
    fig = _figure(0.3 + sum(heights))
    axes = fig.subplots(len(scopes), 1, squeeze=False, height_ratios=heights)[:, 0]
    for ax, scope in zip(axes, scopes):
        order = list(scope.ranks.index)
        ax.set_xlim(0.5, k + 0.5)
        ax.set_ylim(-(rows_per + 1.2 + 0.5 * len(scope.groups)), 1.5)
        ax.axhline(0, color="black", lw=1)
        for r in range(1, k + 1):
            ax.plot([r, r], [0, 0.25], color="black", lw=0.8)
            ax.text(r, 0.35, str(r), ha="center", va="bottom", fontsize=6.5)
        for g, members in enumerate(scope.groups):
            y = -0.35 - 0.5 * g
            ax.plot(
                [scope.ranks[members[0]] - 0.03, scope.ranks[members[-1]] + 0.03],
                [y, y],
                color="black",
                lw=2.2,
                solid_capstyle="round",
            )
        base = -0.6 - 0.5 * len(scope.groups)
        for i, name in enumerate(order):
            r = scope.ranks[name]
            left = i < (len(order) + 1) // 2
            level = base - (i if left else len(order) - 1 - i) * 0.8
            end = 0.55 if left else k + 0.45
            ax.plot([r, r, end], [0, level, level], color="0.25", lw=0.7)
            ax.text(
                end + (-0.05 if left else 0.05),
                level,
                f"{name} ({r:.2f})",
                ha="right" if left else "left",
                va="center",
                fontsize=6.5,
                clip_on=False,
            )
        ax.set_axis_off()
        ax.text(
            (k + 1) / 2,
            0.95,
            f"{'every protocol' if scope.name == ALL else scope.name}: {scope.n_cells} blocks"
            + (f" ({scope.n_duplicates} duplicate cells merged)" if scope.n_duplicates else ""),
            ha="center",
            va="bottom",
            fontsize=7,
        )
    fig.suptitle(
        textwrap.fill(
            f"Mean rank of {board.metric.replace('_', ' ')} over blocks (1 = best)", TITLE_CHARS
        )
        + "\n"
        + textwrap.fill(
            "a bar joins detectors shown not to differ (every pair's interval inside the margin)",
            TITLE_CHARS,
        )
    )
    return fig


def figure(part: pd.DataFrame, layout: ShownLayout, title: str, paper: bool) -> Figure | None:
    """One detector's figure of the kind ``layout.figure`` asks for, or None (no figure kind,
    or rows it cannot draw)."""
    if layout.figure is None or SENSOR_TYPE not in part:
        return None
    if layout.figure == "curve":
        ref = paper_frame(layout.paper_table) if paper and layout.paper_table else None
        return _curves(
            part,
            layout,
            f"Accuracy against {layout.title.lower() or layout.x or layout.column}: {title}",
            ref,
        )
    if layout.figure == "tradeoff":
        return tradeoff(part, f"Detection rate against false alarms: {title}")
    if layout.figure == "with-without":
        return _heatmaps(
            part, layout, f"Accuracy per {layout.title.lower() or layout.column}: {title}"
        )
    return _transfer(part, layout, f"{layout.title or 'Accuracy'}: {title}")


def compare_figure(
    part: pd.DataFrame, layout: ShownLayout, title: str, paper: bool
) -> Figure | None:
    """Every detector of ``part`` on one figure, where ``layout.figure`` is a curve; else None."""
    if layout.figure != "curve" or SENSOR_TYPE not in part or part["detector"].nunique() < 2:
        return None
    ref = paper_frame(layout.paper_table) if paper and layout.paper_table else None
    return _compare_curves(
        part,
        layout,
        f"Accuracy against {layout.title.lower() or layout.x or layout.column}: {title}",
        ref,
    )


def leaderboard_specs(board: Leaderboard, named: str = "", tail: str = "") -> list[FigureSpec]:
    """The critical-difference diagram of ``board`` (two detectors or more, a ranked block);
    ``named`` adds to its caption what the board is of, ``tail`` to its stem."""
    if len(board.order) < 2 or not board.scopes[0].n_cells:
        return []
    return [
        FigureSpec(
            file_stem(f"leaderboard{tail}"),
            "Critical-difference diagram of the leaderboard: mean ranks per scope over blocks "
            "(duplicate cells merged); a bar joins detectors every pair of which is shown not to "
            "differ (the pairwise table's intervals over blocks and seeds, Bonferroni, each inside "
            f"the margin); an undecided pair joins no bar.{named}",
            None,
            lambda: critical_difference(board),
        )
    ]


def figure_specs(made: Outline, paper: bool = True) -> list[FigureSpec]:
    """Every figure of a report's cells (``made``, its :class:`~slipbench.report.outline.Outline`):
    per protocol the figure of every detector together and each detector's own, one per table
    where a layout splits its tables.

    Stems: ``<protocol>-detectors[-<split>][-<values>]``, ``<protocol>-<detector>[-<split>][-<values>]``
    (split omitted for the paper's)."""
    specs = []
    for section in made.sections:
        for split in section.splits:
            specs += _detectors_specs(section, split, paper)
            for detector in section.detectors:
                drows = split.rows[split.rows["detector"] == detector]
                if len(drows):
                    specs += _detector_specs(section, (detector, split.name), drows, paper)
    return specs


def _tail(split: str, which: dict, named: str) -> str:
    """A stem's end: the split (but the paper's) and, where a layout splits its tables, the
    table's values."""
    return ("" if split == "paper" else f"-{split}") + (
        "".join(f"-{v}" for v in which.values()) if named else ""
    )


def _detectors_specs(section: Section, split: Split, paper: bool) -> list:
    """The figures of every detector together, of one split of a protocol's cells."""
    protocol, layout, parts = section.protocol, section.layout, split.parts
    if layout.figure not in ("curve", "tradeoff") or SENSOR_TYPE not in split.rows:
        return []
    specs = []
    for which, part in parts:
        if part["detector"].nunique() < 2:
            continue
        named = "".join(f", {c} {v}" for c, v in which.items()) if len(parts) > 1 else ""
        title = f"every detector ({split.name} split{named})"
        if layout.figure == "tradeoff":
            caption = (
                f"{protocol}, {title}: detection rate against false alarms per minute over the "
                "threshold sweep (its upper envelope), one panel per detector, one curve per "
                "unit; dot: threshold 0.5, cross: the operating point chosen on the training "
                "trials."
            )
            draw = partial(tradeoff, part, f"{protocol}, {title}")
        else:
            caption = (
                f"{protocol}, {title}: mean over fingers (line), range over fingers (band)"
                + ("; the paper's LSTM dashed." if paper and layout.paper_table else ".")
            )
            draw = partial(compare_figure, part, layout, title, paper)
        stem = f"{protocol}-detectors{_tail(split.name, which, named)}"
        specs.append(FigureSpec(stem, caption, protocol, draw, None, split.name))
    return specs


def _detector_specs(
    section: Section, entry: tuple[str, str], rows: pd.DataFrame, paper: bool
) -> list:
    """The figures of one detector (``entry``: it and the split) of a protocol's cells."""
    (detector, split), protocol, layout = entry, section.protocol, section.layout
    specs = []
    parts = split_parts(rows, layout)
    for which, part in parts:
        if layout.figure is None or SENSOR_TYPE not in part:
            continue
        named = "".join(f", {c} {v}" for c, v in which.items()) if len(parts) > 1 else ""
        title = f"{detector} ({split} split{named})"
        specs.append(
            FigureSpec(
                file_stem(f"{protocol}-{detector}{_tail(split, which, named)}"),
                f"{protocol}, {title}.",
                protocol,
                partial(figure, part, layout, title, paper),
                detector,
                split,
            )
        )
    return specs


def _literal(name: str) -> str:
    """A name as matplotlib prints it literally: a ``$`` would start mathtext."""
    return name.replace("$", r"\$")


def forest(metas: Sequence[MetaAnalysis]) -> Figure | None:
    """A forest plot of :func:`slipbench.stats.meta.meta_analysis`' results: one panel per
    detector pair, a line per dataset (dot and 95 % interval) and the pooled change (diamond
    and interval), changes in accuracy points, a zero line. None when no pair has a change."""
    metas = [m for m in metas if m.datasets["d"].notna().any()]
    if not metas:
        return None
    with matplotlib.rc_context(STYLE):
        sizes = [len(m.datasets) + 1 for m in metas]
        fig = _figure(0.8 + sum(0.35 + 0.2 * n for n in sizes))
        axes = fig.subplots(len(metas), 1, squeeze=False, sharex=True, height_ratios=sizes)[:, 0]
        for ax, m in zip(axes, metas):
            lines = m.datasets.to_dict("records")
            for y, r in enumerate(lines):
                if np.isfinite(r["lo"]) and np.isfinite(r["hi"]):
                    ax.plot([100 * r["lo"], 100 * r["hi"]], [y, y], "-", color="0.3")
                ax.plot(100 * r["d"], y, "o", color="0.3" if not r["reason"] else "0.7")
            pooled = len(lines)
            if np.isfinite(m.d):
                ax.plot([100 * m.lo, 100 * m.hi], [pooled, pooled], "-", color="#2166ac", lw=1.6)
                ax.plot(100 * m.d, pooled, "D", color="#2166ac", ms=5)
            names = [_literal(str(r["dataset"])) for r in lines] + ["pooled"]
            ax.set_yticks(range(len(names)), names)
            ax.set_ylim(len(names) - 0.5, -0.5)
            ax.axvline(0, color="black", lw=0.8)
            ax.set_title(_literal(f"{m.cand} − {m.base}"), loc="left", pad=2)
            ax.grid(axis="x", alpha=0.3)
        axes[-1].set_xlabel("change in accuracy (points)")
        fig.suptitle("One verdict across datasets")
        return fig
