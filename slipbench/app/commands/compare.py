"""`slipbench compare`: candidate results against base results cell by cell, as a pull-request
comment or JSON; the exit code says whether a cell regressed."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from slipbench.app.options import LAYOUT_PLUGINS_HELP, out_option, plugins_option
from slipbench.app.selection import add_plugin_folders


@click.command("compare")
@click.argument("base", type=click.Path(path_type=Path))
@click.argument("candidate", type=click.Path(path_type=Path))
@click.option(
    "--margin",
    default=0.0,
    show_default=True,
    help="Accuracy points a cell may lose: it regressed when its simultaneous interval lies entirely below -margin.",
)
@click.option(
    "--delay-margin",
    default=0.0,
    show_default=True,
    help="Streaming cells: ms of median delay a cell may add before it counts as a regression.",
)
@click.option(
    "--alarm-margin",
    default=0.0,
    show_default=True,
    help="Streaming cells: false alarms per minute a cell may add before it counts as a regression.",
)
@click.option(
    "--max-width",
    default=40.0,
    show_default=True,
    help="Accuracy points: a cell whose change interval is wider (and decides nothing) is inconclusive.",
)
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["md", "json"]),
    default="md",
    show_default=True,
    help="md: a pull-request comment (summary, regressed cells, at most --max-rows others); json: every cell, for bots.",
)
@click.option(
    "--max-rows",
    type=click.IntRange(min=0),
    help="Markdown: cells listed besides the regressed ones, improved first, then the largest changes "
    "[default: 60; a whole-paper comparison of five detectors is then about 18,000 characters].",
)
@out_option("Also write the text to this file (a PR comment).")
@plugins_option(LAYOUT_PLUGINS_HELP)
def compare_command(
    base, candidate, margin, delay_margin, alarm_margin, max_width, fmt, max_rows, out, plugins
) -> None:
    """Compare CANDIDATE results with BASE cell by cell; exit 1 if a cell regressed.

    Cells pair across seeds (a side may hold several per cell, `evaluate --repeats`); each
    protocol and detector also gets a pooled test of its mean change.

    Exit codes: 0 nothing regressed beyond --margin; 1 a cell or a protocol's pooled change
    regressed; 2 bad usage or data.
    """
    from slipbench.atomic import write_text_atomic
    from slipbench.report.compare import MAX_ROWS, to_json, to_markdown
    from slipbench.stats.compare import compare

    add_plugin_folders(plugins)
    result = compare(
        base,
        candidate,
        margin,
        delay_margin_ms=delay_margin,
        alarm_margin=alarm_margin,
        max_width=max_width,
    )
    text = (
        to_json(result)
        if fmt == "json"
        else to_markdown(result, MAX_ROWS if max_rows is None else max_rows)
    )
    click.echo(text, nl=False)
    if out:
        out.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(out, text)
    sys.exit(result.exit_code)
