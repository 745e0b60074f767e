"""`slipbench compare`: candidate results against base results on the gate's figures, as a
pull-request comment (Markdown) and JSON in one call; the exit code is the verdict."""

from __future__ import annotations

import sys
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import click

from slipbench.app.options import LAYOUT_PLUGINS_HELP, out_option, plugins_option
from slipbench.app.selection import add_plugin_folders, recorded_plugins
from slipbench.gate.gate import DEFAULT_TOLERANCE

if TYPE_CHECKING:  # read when compare runs (each command's imports are its own)
    from slipbench.app.benchfile import Benchmark


@dataclass(frozen=True)
class CompareArgs:
    """What `slipbench compare` was given, one field per option."""

    base: Path
    candidate: Path
    figures: tuple[str, ...]
    margin: float | None
    bench: Path | None
    max_width: float
    fmt: str
    max_rows: int | None
    out: Path | None
    json_out: Path | None
    plugins: tuple[str, ...]


@click.command("compare")
@click.argument("base", type=click.Path(path_type=Path))
@click.argument("candidate", type=click.Path(path_type=Path))
@click.option(
    "--figure",
    "figures",
    multiple=True,
    metavar="NAME[=TOLERANCE]",
    help="A figure the gate judges, with its tolerance (a drop smaller than it is no regression; "
    "points of a rate, false alarms per minute, ms); repeat for several. Figures: "
    + ", ".join(f"{k} (default {v:g})" for k, v in DEFAULT_TOLERANCE.items())
    + " [default: every figure, or the [gate] table of --bench].",
)
@click.option(
    "--margin",
    type=float,
    help="Points: the tolerance of every rate figure (accuracy, TN and TP rate, detection rate) "
    "that --figure or --bench does not set.",
)
@click.option(
    "--bench",
    type=click.Path(path_type=Path, dir_okay=False),
    help="The base's bench file: it must be the one BASE's run recorded (the same SHA-256), "
    "and its calibration beside it, where it holds for BASE's detectors and agrees with BASE's "
    "own seeds, gives the seed noise. The gate (figures, tolerances, budget, detectors) is "
    "always the bench BASE recorded; where BASE recorded none, this file's.",
)
@click.option(
    "--max-width",
    default=40.0,
    show_default=True,
    help="Points: a cell whose change interval is wider (and decides nothing) is inconclusive.",
)
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["md", "json"]),
    default="md",
    show_default=True,
    help="What is printed: md, a pull-request comment; json, every cell and test, for bots.",
)
@click.option(
    "--max-rows",
    type=click.IntRange(min=0),
    help="Markdown: cells listed besides the regressed ones, improved first, then the largest changes "
    "[default: 60; a whole-paper comparison of five detectors is then about 18,000 characters].",
)
@out_option("Also write the Markdown comment to this file.")
@click.option(
    "--json",
    "json_out",
    type=click.Path(path_type=Path, dir_okay=False),
    help="Also write the JSON to this file (the same comparison: no second run).",
)
@plugins_option(LAYOUT_PLUGINS_HELP)
def compare_command(**options) -> None:
    """Compare CANDIDATE results with BASE on the gate's figures; exit 1 if one regressed.

    Windowed cells are judged on accuracy, TN rate and TP rate; streaming cells on false alarms
    per minute, detection rate and median delay; each protocol and detector also gets a pooled
    test per figure, which states the smallest drop it would flag with 80 % power.

    The gate (figures, tolerances, budget, detectors) is the bench BASE recorded, where it
    recorded one; the comment's first line names where CANDIDATE's differs.

    Exit codes: 0 no regression; 1 a figure regressed (in a cell or pooled), or a cell the base
    finished failed or is missing; 6 undecided (one seed per side, too few trials, or noise larger than the
    tolerance: the comment says how many seeds or trials would decide); 2 bad usage or data.
    """
    o = CompareArgs(**options)
    from slipbench.app.basegate import judge, missing
    from slipbench.atomic import write_text_atomic
    from slipbench.gate.compare import compare
    from slipbench.report.compare import MAX_ROWS, comment_markdown, to_json

    add_plugin_folders(o.plugins)
    judged = judge(o.base, o.candidate, o.bench)
    gate = gate_from(o.figures, judged.bench, o.margin, o.max_width)
    sources, notes = (
        _calibration(judged.calibration_bench, o.base)
        if judged.calibration_bench is not None
        else ([], [])
    )
    sources, refused = _numbers_checked(sources, o.base, gate, judged.calibration_bench)
    result = compare(o.base, o.candidate, gate, sources=sources)
    result.notes.extend(notes)
    result.headline[:0] = [*judged.headline, *refused]
    if judged.recorded and judged.bench is not None:  # the base's bench: its work is owed
        result.missing[:0] = missing(result.only_base, judged.bench)
    if result.rows is not None:  # rows written before they recorded their layouts
        result = replace(result, rows=recorded_plugins(result.rows))
    texts = {
        "json": to_json(result),
        "md": comment_markdown(result, MAX_ROWS if o.max_rows is None else o.max_rows),
    }
    click.echo(texts[o.fmt], nl=False)
    for path, kind in ((o.out, "md"), (o.json_out, "json")):
        if path:
            path.parent.mkdir(parents=True, exist_ok=True)
            write_text_atomic(path, texts[kind])
    sys.exit(result.exit_code)


def gate_from(
    figures: tuple[str, ...], bench: Path | Benchmark | None, margin: float | None, max_width: float
):
    """The gate from --figure options, else the benchmark file's [gate] (the base's, as BASE
    recorded it), else every figure; --margin sets every rate's tolerance that is not given as
    NAME=TOLERANCE. The bench's repeats and budget set the looks."""
    from slipbench.app.benchfile import load_benchmark
    from slipbench.gate.gate import Gate, parse_tolerances, unit

    b = load_benchmark(bench) if isinstance(bench, (str, Path)) else bench
    explicit = parse_tolerances(f for f in figures if "=" in f)
    named = [f.partition("=")[0].strip() for f in figures]
    if not named and b is not None:
        explicit = dict(b.gate)
        named = list(explicit)
    tolerances = {f: DEFAULT_TOLERANCE.get(f, 1.0) for f in named or DEFAULT_TOLERANCE}
    if margin is not None:
        tolerances |= {f: margin for f in tolerances if unit(f) == "points"}
    if b is None:
        return Gate(tolerances | explicit, max_width)
    return Gate(tolerances | explicit, max_width, b.repeats, max(b.repeats, b.seeds_budget))


def _calibration(bench: Path, base: Path) -> tuple[list, list[str]]:
    """The calibration beside ``bench`` (the base's bench file) where it holds for BASE's
    detectors (checked against the ``calibration_key`` BASE's run recorded), and the lines
    saying where it does not."""
    import json

    from slipbench.app.benchfile import RECORD_FILE, load_benchmark
    from slipbench.app.calibrate import recorded_status
    from slipbench.errors import DataError

    record = base / RECORD_FILE if base.is_dir() else base.parent / RECORD_FILE
    try:
        key = json.loads(record.read_text()).get("calibration_key") if record.is_file() else None
    except (ValueError, AttributeError) as exc:
        raise DataError(f"{record}: not a benchmark run's record ({exc})") from None
    if key is None:
        return [], [
            f"BASE holds no record of a benchmark run's code ({RECORD_FILE}): the calibration "
            "is not checked against it, and the seed noise rests on the sides' own seeds"
        ]
    found = recorded_status(load_benchmark(bench, here=False), key)
    return found.sources(), found.lines()


def _numbers_checked(sources: list, base: Path, gate, bench: Path | None) -> tuple[list, list[str]]:
    """The calibration kept to the detectors whose numbers agree with what BASE's own seeds
    show (:mod:`slipbench.gate.calibration_check`), and the first-line words of each detector
    it was refused for (not used: the sides' own seeds carry its noise)."""
    import warnings

    from slipbench.gate.calibration import calibration_path
    from slipbench.gate.calibration_check import refused
    from slipbench.store.results import read_results

    if not sources or bench is None:
        return sources, []
    with warnings.catch_warnings():  # compare reads BASE again and says what it finds
        warnings.simplefilter("ignore")
        rows = read_results(base)
    cal = sources[0]
    bad = refused(cal, rows, list(gate.tolerances))
    said = [
        f"{calibration_path(bench).name} not used for {detector}: {why}; the sides' own seeds "
        "carry its noise."
        for detector, why in bad.items()
    ]
    return [cal.holding(d for d in cal.detectors if d not in bad)], said
