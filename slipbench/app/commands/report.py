"""`slipbench report`: render results files or folders as a Markdown, LaTeX or HTML report
(what they stand on, the leaderboard, each protocol's tables), printed or written to a file."""

from __future__ import annotations

from pathlib import Path

import click

from slipbench.app.options import (
    LAYOUT_PLUGINS_HELP,
    Destination,
    intervals_option,
    out_option,
    plugins_option,
)
from slipbench.app.selection import add_plugin_folders


@click.command("report")
@click.argument("results", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["md", "latex", "html"]),
    default="md",
    show_default=True,
    help="html: one self-contained page, figures embedded.",
)
@click.option(
    "--metric",
    type=click.Choice(["accuracy", "tp_rate", "tn_rate", "balanced_accuracy", "auroc"]),
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
    help="Markdown or LaTeX: write each detector's own tables and figures to this file; the "
    "report keeps the summary (what it stands on, leaderboard, findings, every detector side by "
    "side) and links it.",
)
@plugins_option(LAYOUT_PLUGINS_HELP)
def report(
    results,
    fmt,
    metric,
    leaderboard_only,
    intervals,
    paper,
    standalone,
    plots_dir,
    out,
    appendix,
    plugins,
) -> None:
    """Render RESULTS (results files or --out folders): what they stand on, the leaderboard,
    then each protocol in its own layout (the paper's tables)."""
    import os

    import pandas as pd

    from slipbench.report.document import build_report, render, split_appendix, write_figures
    from slipbench.store.results import check_unique_keys, read_results, results_folder

    if appendix is not None and fmt == "html":
        raise click.BadParameter(
            "the HTML page keeps every table on one page; use --appendix with --format md or latex",
            param_hint="--appendix",
        )
    if appendix is not None and out is not None and appendix.resolve() == out.resolve():
        raise click.BadParameter(
            "the appendix needs a file of its own, not --out's", param_hint="--appendix"
        )
    add_plugin_folders(plugins)
    rows = check_unique_keys(
        pd.concat([read_results(p) for p in results], ignore_index=True),
        " + ".join(map(str, results)),
    )
    blocks = build_report(
        rows,
        metric,
        intervals,
        paper,
        leaderboard_only,
        with_figures=fmt == "html" or plots_dir is not None,
        predictions=[results_folder(p) for p in results],
    )
    files = write_figures(blocks, plots_dir) if plots_dir else {}
    home = out.parent if out else Path.cwd()
    rest = None
    if appendix is not None:
        link = Path(os.path.relpath(appendix.absolute(), home.absolute())).as_posix()
        back = (
            Path(os.path.relpath(out.absolute(), appendix.parent.absolute())).as_posix()
            if out
            else ""
        )
        blocks, rest = split_appendix(blocks, link, fmt, back)
    text = render(blocks, fmt, standalone, files, link_from=out.parent if out else None)
    from slipbench.atomic import write_text_atomic

    if rest is not None:  # the appendix first: a report never links a file not yet written
        appendix.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(appendix, render(rest, fmt, standalone, files, link_from=appendix.parent))
        click.echo(f"wrote {appendix}", err=not out)
    if out:
        out.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(out, text)
        click.echo(f"wrote {out}")
    else:
        click.echo(text, nl=False)
    for path in (p for paths in files.values() for p in paths):
        click.echo(f"wrote {path}", err=not out)
