"""Rows to a whole report text, or to figure files, in one call: how the tests render (the
commands build, draw and render in steps of their own: slipbench/app/commands/report.py)."""

from __future__ import annotations

import os
from pathlib import Path

import pandas as pd

from slipbench.report.document import build_report, render, write_figures
from slipbench.report.outline import outline
from slipbench.report.plots import figure_specs, save
from slipbench.report.render import renderer


def render_report(rows: pd.DataFrame, fmt: str = "md", found=None, **options) -> str:
    """Every table the rows allow as one Markdown, LaTeX or HTML text. ``options``: those of
    :class:`~slipbench.report.document.ReportOptions`, and how the text is laid out:
    ``standalone`` (a LaTeX document that compiles), ``plots_dir`` (the figures are drawn there
    and linked; HTML embeds them either way), ``link_from`` (the folder links are relative to)."""
    standalone = options.pop("standalone", False)
    plots_dir = options.pop("plots_dir", None)
    link_from = options.pop("link_from", None)
    with_figures = renderer(fmt).embeds_figures or plots_dir is not None
    blocks = build_report(rows, found, **options, with_figures=with_figures)
    files = write_figures(blocks, plots_dir) if plots_dir is not None else {}
    return render(blocks, fmt, standalone, files, link_from)


def write_plots(rows: pd.DataFrame, folder: str | os.PathLike, paper: bool = True) -> list[Path]:
    """Every figure the rows allow (:func:`~slipbench.report.plots.figure_specs`) as PNG and
    PDF in ``folder``; ``paper`` overlays the published LSTM accuracies where a layout names a
    paper table."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths: list[Path] = []
    for spec in figure_specs(outline(rows), paper):
        fig = spec.draw()
        if fig is not None:
            paths += save(fig, folder, spec.stem)
    return paths
