"""`slipbench report`: render results files or folders as a Markdown, LaTeX or HTML report
(what they stand on, the leaderboard, each protocol's tables), printed or written to a file."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import click

from slipbench.app.options import (
    LAYOUT_PLUGINS_HELP,
    Destination,
    intervals_option,
    out_option,
    plugins_option,
)
from slipbench.app.selection import add_plugin_folders, recorded_plugins
from slipbench.report.render import FORMATS
from slipbench.store.columns import WINDOWED, names


@dataclass(frozen=True)
class ReportArgs:
    """What `slipbench report` was given, one field per option."""

    results: tuple[Path, ...]
    fmt: str
    metric: str
    leaderboard_only: bool
    intervals: bool
    paper: bool
    standalone: bool
    plots_dir: Path | None
    out: Path | None
    appendix: Path | None
    plugins: tuple[str, ...]


@click.command("report")
@click.argument("results", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option(
    "--format",
    "fmt",
    type=click.Choice(list(FORMATS)),
    default="md",
    show_default=True,
    help="html: one self-contained page, figures embedded.",
)
@click.option(
    "--metric",
    type=click.Choice(names(WINDOWED)),
    default="accuracy",
    show_default=True,
    help="The figure the protocol tables show and the leaderboard ranks.",
)
@click.option(
    "--leaderboard",
    "leaderboard_only",
    is_flag=True,
    help="Only the header and the leaderboard: ranks, tests, mean figures.",
)
@intervals_option("Show 95 % intervals: 88.0 [86.9, 89.1].")
@click.option(
    "--paper",
    is_flag=True,
    help="Show the paper's published tables and the differences beside ours.",
)
@click.option(
    "--standalone", is_flag=True, help="LaTeX: a whole document that compiles, not only the tables."
)
@click.option(
    "--plots",
    "plots_dir",
    type=Destination(),
    help="Also write figures (PNG and PDF) here, linked from the report.",
)
@out_option("Write the report to this file instead of printing it.")
@click.option(
    "--appendix",
    type=Destination(dir_okay=False),
    help="Markdown or LaTeX: write each detector's own tables and figures, every detector on "
    "the other splits and the published tables to this file; the report keeps the summary (what "
    "it stands on, leaderboard, findings, every detector side by side on the lead split) and "
    "links it.",
)
@plugins_option(LAYOUT_PLUGINS_HELP)
def report(**options) -> None:
    """Render RESULTS (results files or --out folders): what they stand on, the leaderboard,
    then each protocol in its own layout (the paper's tables)."""
    o = ReportArgs(**options)
    import os

    import pandas as pd

    from slipbench.report.document import build_report, render, split_appendix, write_figures
    from slipbench.report.render import renderer
    from slipbench.stats.factors import latest_runs
    from slipbench.store.results import check_unique_keys, read_results, results_folder

    if o.appendix is not None and not renderer(o.fmt).appendix:
        paged = ", ".join(f for f in FORMATS if renderer(f).appendix)
        raise click.BadParameter(
            f"a report in {o.fmt} keeps every table in one file; use --appendix with --format {paged}",
            param_hint="--appendix",
        )
    if o.appendix is not None and o.out is not None and o.appendix.resolve() == o.out.resolve():
        raise click.BadParameter(
            "the appendix needs a file of its own, not --out's", param_hint="--appendix"
        )
    add_plugin_folders(o.plugins)
    read = [read_results(p) for p in o.results]
    rows, superseded = latest_runs(
        check_unique_keys(pd.concat(read, ignore_index=True), " + ".join(map(str, o.results)))
    )
    rows = recorded_plugins(rows)  # rows written before they recorded their layouts
    blocks = build_report(
        rows,
        superseded=superseded,
        metric=o.metric,
        intervals=o.intervals,
        paper=o.paper,
        leaderboard_only=o.leaderboard_only,
        with_figures=renderer(o.fmt).embeds_figures or o.plots_dir is not None,
        predictions=[results_folder(p) for p in o.results],
        unproven=[path for part in read for path in part.attrs["unproven"]],
    )
    files = write_figures(blocks, o.plots_dir) if o.plots_dir else {}
    home = o.out.parent if o.out else Path.cwd()
    rest = None
    if o.appendix is not None:
        link = Path(os.path.relpath(o.appendix.absolute(), home.absolute())).as_posix()
        back = (
            Path(os.path.relpath(o.out.absolute(), o.appendix.parent.absolute())).as_posix()
            if o.out
            else ""
        )
        blocks, rest = split_appendix(blocks, link, o.fmt, back)
    text = render(blocks, o.fmt, o.standalone, files, link_from=o.out.parent if o.out else None)
    from slipbench.atomic import write_text_atomic

    if (
        rest is not None and o.appendix is not None
    ):  # the appendix first: a report never links a file not yet written
        o.appendix.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(
            o.appendix, render(rest, o.fmt, o.standalone, files, link_from=o.appendix.parent)
        )
        click.echo(f"wrote {o.appendix}", err=not o.out)
    if o.out:
        o.out.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(o.out, text)
        click.echo(f"wrote {o.out}")
    else:
        click.echo(text, nl=False)
    for path in (p for paths in files.values() for p in paths):
        click.echo(f"wrote {path}", err=not o.out)
