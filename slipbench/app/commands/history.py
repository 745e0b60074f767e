"""`slipbench history`: runs kept over commits (add), the steps in their series (steps), and a
static site of them (page)."""

from __future__ import annotations

import importlib
import json
import sys
from dataclasses import dataclass
from pathlib import Path

import click

from slipbench.app.options import Destination, SuggestingGroup, jobs_option, out_option

HISTORY_HELP = "The history folder (made by the first `history add`)."
#: what `history page` imports beyond the plain install: the `history` extra (add and steps
#: need nothing more: the steps' segmentation is numpy, slipbench/history/segmentation.py)
EXTRA = ("plotly",)
INSTALL = "pip install 'slipbench[history]'"


def needs_extra() -> None:
    """Refuse `history page`, before any work, where the ``history`` extra is not installed:
    a UsageError (exit 2) in one line naming what is missing and the install command."""
    missing = []
    for name in EXTRA:
        try:
            importlib.import_module(name)
        except ImportError:
            missing.append(name)
    if missing:
        from slipbench.errors import UsageError

        raise UsageError(
            f"slipbench history page needs {' and '.join(missing)}, which the plain install leaves "
            f"out: {INSTALL}"
        )


@click.group("history", cls=SuggestingGroup)
def history() -> None:
    """Runs kept over commits, the steps in their series, and a site of them."""


@dataclass(frozen=True)
class AddArgs:
    """What `slipbench history add` was given, one field per option."""

    results: Path
    history: Path
    commit: str
    date: str | None
    machine: str


@history.command("add")
@click.argument("results", type=click.Path(path_type=Path))
@click.option("--history", type=Destination(file_okay=False), required=True, help=HISTORY_HELP)
@click.option("--commit", required=True, help="The commit the results were computed at.")
@click.option("--date", help="The commit's date, ISO 8601 [default: now, UTC].")
@click.option(
    "--machine", default="", help="The machine that ran them (kept on each row, not a series)."
)
def add_command(**options) -> None:
    """Add RESULTS (a results folder or file) to the history as the run of --commit; a commit
    the history holds already changes nothing."""
    o = AddArgs(**options)
    from slipbench.history.series import series_rows
    from slipbench.stats.factors import latest_runs
    from slipbench.store.history import Run, add_run, check_commit, held, utc_date
    from slipbench.store.results import check_unique_keys, read_results

    check_commit(o.commit)
    date = utc_date(o.date)
    if (found := held(o.history, o.commit)) is not None:
        click.echo(f"{o.history}: commit {o.commit} is held already ({found}); nothing added")
        return
    found = read_results(o.results)
    # rows of files without digests (another tool, an edit): marked so for good in the history
    found["proven"] = ~found["key"].astype(str).isin(set(found.attrs["unproven_keys"]))
    rows, superseded = latest_runs(check_unique_keys(found, str(o.results)))
    lacking = int(rows["code_identity"].isna().sum() if "code_identity" in rows else len(rows))
    if lacking:
        click.echo(
            f"warning: {lacking} row(s) of {o.results} hold no code identity (written by an older "
            "slipbench): they are never taken as seeds of one code",
            err=True,
        )
    try:
        kept = series_rows(rows)
    except ValueError as exc:
        from slipbench.errors import DataError

        raise DataError(f"{o.results}: {exc}") from None
    path = add_run(o.history, kept, Run(o.commit, date, o.machine, _bench_digest(o.results)))
    if path is None:
        click.echo(f"{o.history}: commit {o.commit} was added meanwhile; nothing added")
        return
    left = f" ({superseded} earlier row(s) of cells run again left out)" if superseded else ""
    unproven = int((~kept["proven"].astype(bool)).sum())
    if unproven:
        left += f"; {unproven} of them unproven (no digest vouches for them), marked so"
    click.echo(f"added {len(kept)} rows of commit {o.commit} ({date}) to {path}{left}")


def _bench_digest(results: Path) -> str:
    """The SHA-256 of the bench file the results were run from (``slipbench run`` records
    it beside them), "" where they were not."""
    from slipbench.app.benchfile import RECORD_FILE
    from slipbench.errors import DataError
    from slipbench.store.results import results_folder

    record = results_folder(results) / RECORD_FILE
    if not record.is_file():
        return ""
    try:
        return str(json.loads(record.read_text())["sha256"])
    except (ValueError, KeyError, TypeError, OSError) as exc:
        raise DataError(f"{record}: not a benchmark record ({exc})") from None


@dataclass(frozen=True)
class StepsArgs:
    """What `slipbench history steps` was given, one field per option."""

    history: Path
    figures: tuple[str, ...]
    bench: Path | None
    since: str | None
    as_json: bool
    jobs: int | None


@history.command("steps")
@click.option(
    "--history", type=click.Path(path_type=Path, file_okay=False), required=True, help=HISTORY_HELP
)
@click.option(
    "--figure",
    "figures",
    multiple=True,
    metavar="NAME[=TOLERANCE]",
    help="A figure judged, with its tolerance (points; repeatable) [default: the [gate] table of "
    "--bench, else accuracy, tn_rate and tp_rate at 1 point].",
)
@click.option(
    "--bench",
    type=click.Path(path_type=Path, dir_okay=False),
    help="A benchmark file whose [gate] table gives the figures and tolerances.",
)
@click.option(
    "--since",
    metavar="COMMIT|DATE",
    help="Exit 1 where a confirmed regression is newer than this commit (or ISO date).",
)
@click.option("--json", "as_json", is_flag=True, help="Print every proposal as JSON.")
@jobs_option("Processes that cut the series [default: the machine's cores].")
def steps_command(**options) -> None:
    """Propose steps in every series of the history and confirm each by the gate's test
    between the runs before and after it; print the confirmed ones.

    Exit codes: 0, or 1 where a confirmed regression is newer than --since; 2 bad usage or data.
    """
    o = StepsArgs(**options)
    from slipbench.app.commands.compare import gate_from
    from slipbench.history.steps import STEP_COLUMNS, default_jobs, find_steps
    from slipbench.report.steps import steps_json, steps_text
    from slipbench.store.history import read_history

    gate = gate_from(o.figures, o.bench, None, 40.0)
    frame = read_history(o.history, STEP_COLUMNS, categorical=True)
    found = find_steps(frame, gate, o.jobs or default_jobs())
    click.echo(steps_json(found) if o.as_json else steps_text(found, o.history), nl=False)
    if o.since is not None and _regressed_since(found, o.since):
        sys.exit(1)


def _regressed_since(found, since: str) -> bool:
    """Whether a confirmed regression came after ``since``: a commit of the history (or a
    prefix of one) or an ISO date."""
    from datetime import datetime

    from slipbench.errors import UsageError
    from slipbench.store.history import utc_date

    runs = found.runs
    match = runs[runs["commit"].str.startswith(since)]
    if len(match) > 1:
        raise UsageError(f"--since: {since!r} names {len(match)} commits of the history")
    if len(match):
        after = found.steps["run"] > int(match["run"].iloc[0])
    else:
        try:
            datetime.fromisoformat(since.strip().replace("Z", "+00:00"))
        except ValueError:
            raise UsageError(
                f"--since: {since!r} is neither a commit of the history nor an ISO date"
            ) from None
        after = found.steps["date"] > utc_date(since, "--since")
    return bool(((found.steps["verdict"] == "regressed") & after).any())


@dataclass(frozen=True)
class PageArgs:
    """What `slipbench history page` was given, one field per option."""

    history: Path | None
    results: Path | None
    out: Path
    figures: tuple[str, ...]
    bench: Path | None
    jobs: int | None


@history.command("page")
@click.option("--history", type=click.Path(path_type=Path, file_okay=False), help=HISTORY_HELP)
@click.option(
    "--results",
    type=click.Path(path_type=Path),
    help="A results folder: its report, leaderboard and side by side pages (with --history: "
    "the latest run's) [default: the latest run of --history, from its rows].",
)
@out_option("The site's folder.", default="site")
@click.option("--figure", "figures", multiple=True, metavar="NAME[=TOLERANCE]", help="As in steps.")
@click.option(
    "--bench",
    type=click.Path(path_type=Path, dir_okay=False),
    help="A benchmark file whose [gate] table gives the figures and tolerances.",
)
@jobs_option("Processes that cut the series [default: the machine's cores].")
def page_command(**options) -> None:
    """Write a static site (it opens from file://, nothing from the network): a filterable
    leaderboard, any two detectors side by side, each series over commits with its confirmed
    steps marked, and the run's report."""
    o = PageArgs(**options)
    needs_extra()
    from slipbench.app.commands.compare import gate_from
    from slipbench.errors import UsageError
    from slipbench.history.steps import default_jobs, find_steps
    from slipbench.report.site import write_site
    from slipbench.store.history import read_history

    if o.history is None and o.results is None:
        raise UsageError("history page needs --history, --results or both")
    found, latest, about = None, None, []
    if o.history is not None:
        frame = read_history(o.history)
        gate = gate_from(o.figures, o.bench, None, 40.0)
        found = find_steps(frame, gate, o.jobs or default_jobs())
        last = found.runs.iloc[-1]
        latest = frame[frame["run"] == frame["run"].max()]
        first = found.runs.iloc[0]
        about.append(
            f"The project's history: {len(found.runs)} runs over commits, from "
            f"{first['commit']} ({first['date'][:10]}) to the latest commit, {last['commit']} "
            f"({last['date'][:10]})."
        )
        marked = found.runs.loc[found.runs["unproven"] > 0, "commit"].tolist()
        if marked:
            about.append(
                f"{len(marked)} run{' holds' if len(marked) == 1 else 's hold'} rows that "
                f"entered unproven ({', '.join(marked)}): results without digests, whose edits "
                "cannot be detected."
            )
    report = None
    if o.results is not None:
        latest, report = _run_report(o.results)
    if latest is not None:
        about.append(_latest_words(latest, found))
    for path in write_site(o.out, latest, found, report, " ".join(about)):
        click.echo(f"wrote {path}")


def _latest_words(rows, found) -> str:
    """What the leaderboard shows, in words: the latest commit's run where a history names it,
    else one run's size (never a folder's name)."""
    ok = rows[rows["status"] == "ok"]
    counts = [(ok[c].nunique(), word) for c, word in (("cell", "cell"), ("detector", "detector"))]
    counts.append((ok["protocol"].nunique(), "protocol"))
    cells, detectors, protocols = (f"{n} {w}{'' if n == 1 else 's'}" for n, w in counts)
    size = f"{cells} of {detectors} under {protocols}"
    if found is None:
        return f"Leaderboard and side by side: one run's results, {size}."
    return f"Leaderboard and side by side: the latest commit's run, {size}."


def _run_report(results: Path):
    """A results folder's rows (each cell and seed's latest run) and its HTML report."""
    from slipbench.report.document import build_report, render
    from slipbench.stats.factors import latest_runs
    from slipbench.store.results import check_unique_keys, read_results, results_folder

    rows, superseded = latest_runs(check_unique_keys(read_results(results), str(results)))
    blocks = build_report(
        rows,
        superseded=superseded,
        intervals=True,
        with_figures=True,
        predictions=[results_folder(results)],
    )
    return rows, render(blocks, "html")
