"""`slipbench evaluate`: run protocols with detectors on a dataset (or train on one and test
on another), store the cells in a results folder and print each protocol's table."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import click

from slipbench.app.options import (
    balance_option,
    dataset_option,
    force_option,
    intervals_option,
    jobs_option,
    labels_option,
    out_option,
    parse_params,
    plugins_option,
    protocol_params_option,
    quiet_option,
    repeats_problem,
    scale_option,
    scheduler_option,
    seed_option,
    slurm_option,
    slurm_resources,
    split_option,
)
from slipbench.app.selection import (
    add_plugin_folders,
    check_ids,
    readable,
    recorded_plugins,
    select_plugins,
    with_options,
)
from slipbench.engine import registry
from slipbench.errors import PluginError, UsageError

if TYPE_CHECKING:
    import pandas as pd


@dataclass(frozen=True)
class EvaluateArgs:
    """What `slipbench evaluate` was given, one field per option."""

    detector_name: tuple[str, ...]
    protocol_name: tuple[str, ...]
    dataset_path: Path | None
    train_path: Path | None
    sensor_map: tuple[str, ...]
    scale: float
    out: Path
    split: str
    labels: str
    normalize: str
    balance: str
    input_kind: str
    seed: int
    repeats: int
    params: tuple[str, ...]
    protocol_params: tuple[str, ...]
    plugins: tuple[str, ...]
    jobs: int
    scheduler: str | None
    slurm: tuple[str, ...]
    cell_timeout: float | None
    force: bool
    intervals: bool
    quiet: bool


@click.command("evaluate")
@click.option(
    "--detector",
    "detector_name",
    required=True,
    multiple=True,
    help="A detector id, a comma list of ids, or 'all' (repeatable; see `slipbench list`).",
)
@click.option(
    "--protocol",
    "protocol_name",
    required=True,
    multiple=True,
    help="A protocol id, a comma list of ids, or 'all' (repeatable; see `slipbench list`).",
)
@dataset_option("Dataset folder [default: the simulated one].")
@click.option(
    "--train-dataset",
    "train_path",
    type=click.Path(path_type=Path),
    help="Train on this dataset and test on --dataset (all of its windows): the 'datasets' split.",
)
@click.option(
    "--sensor-map",
    multiple=True,
    help="With --train-dataset: TEST_TYPE[:INSTANCE]=TRAIN_TYPE[:INSTANCE] (repeatable).",
)
@scale_option("Scale of the simulated dataset when --dataset is not given.")
@out_option("Results folder.", default="results", results=True)
@split_option(
    "paper: windows shuffled and halved; grouped: whole trials on one side, the same for every unit."
)
@labels_option(
    "A window's class: its recording's scenario (the paper), or its samples' slip labels."
)
@balance_option()
@click.option(
    "--normalize",
    type=click.Choice(["none", "recording", "unit"]),
    default="none",
    show_default=True,
    help="Scale the signal before windows are cut: not at all (the paper), per recording, or per "
    "sensor unit (median and 1.4826 x MAD of the unit's training-side signal; across datasets, each "
    "dataset's unit by its own).",
)
@click.option(
    "--input",
    "input_kind",
    type=click.Choice(["univariate", "channels", "both"]),
    default="univariate",
    show_default=True,
    help="What detectors read: the paper's univariate signal, the raw channels (standardized by "
    "the training windows), or both (one run each; detectors that read one of them run it alone).",
)
@seed_option("Seed of balancing, splitting and training (and of the simulated data).")
@click.option(
    "--repeats",
    default=1,
    show_default=True,
    type=click.IntRange(1),
    help="Rerun with seeds seed, seed+1, ...",
)
@click.option(
    "--param",
    "params",
    multiple=True,
    help="Detector hyperparameter NAME=VALUE (JSON value); repeatable.",
)
@protocol_params_option("Protocol option NAME=VALUE, e.g. decimation=both.")
@plugins_option()
@jobs_option("Local worker processes (0: in this process, for debugging).", default=1)
@scheduler_option()
@slurm_option()
@click.option(
    "--cell-timeout",
    default=None,
    type=click.FloatRange(min=0),
    help="Seconds one model may take; its cells are then reported as timeout "
    "(default: 7200 with local workers; 0: none).",
)
@force_option()
@intervals_option("Show 95 % intervals in the table.")
@quiet_option()
def evaluate_command(**options) -> None:
    """Run protocols with detectors; write results to --out and print the tables."""
    o = EvaluateArgs(**options)
    if problem := repeats_problem(o.seed, o.repeats):
        raise UsageError(f"--repeats {o.repeats}: {problem}")
    add_plugin_folders(o.plugins)
    if o.train_path and not o.dataset_path:
        raise UsageError("--train-dataset needs --dataset: the dataset to test on")
    if o.sensor_map and not o.train_path:
        raise UsageError(
            "--sensor-map matches a test dataset's sensors to a training dataset's: it needs --train-dataset"
        )
    split = "datasets" if o.train_path else o.split
    check_ids(registry.detectors, o.detector_name)  # both kinds before a plugin is imported
    check_ids(registry.protocols, o.protocol_name)
    simulating = _first_use(o)  # said before the plugins and the data's libraries are imported
    broken: list[str] = []
    note = lambda line: click.echo(line, err=True)  # noqa: E731
    detectors = with_options(
        select_plugins(registry.detectors, o.detector_name, broken, note),
        parse_params(o.params),
        "detector",
    )
    protocols = with_options(
        select_plugins(registry.protocols, o.protocol_name, broken, note),
        parse_params(o.protocol_params, "--protocol-param"),
        "protocol",
    )
    # the engine once the plugins are known: a mistyped id is refused at once
    from slipbench.engine.plan import Run

    runs = [
        Run(d, p, split, o.seed + r, o.labels, o.normalize, kind, o.balance)
        for name, d in detectors.items()
        for kind in readable(name, d, o.input_kind, note)
        for p in protocols.values()
        for r in range(o.repeats)
    ]
    if not runs:
        raise UsageError(
            f"no detector chosen reads the {o.input_kind} input (see `slipbench list`)"
        )
    for run in runs:
        run.validate()  # every option before the dataset is read or simulated
    slurm = slurm_resources(o.scheduler, o.slurm, None, detectors)
    from slipbench.report.document import protocol_table
    from slipbench.report.provenance import balance_kept, fitting_warnings, grouped_warnings
    from slipbench.store.columns import DETECTOR, ENTRANT, INPUT, PROTOCOL, READING, identity
    from slipbench.store.results import ResultsStore, cells_failed

    store = ResultsStore(o.out)
    rows = None if o.force or o.train_path else _cached(o, runs, store)
    if rows is None:
        rows = _evaluated(o, runs, store, slurm, simulating)
    shown = recorded_plugins(rows)  # cells kept from a run before rows recorded their layouts
    by = [c for c in (*identity(ENTRANT, READING), PROTOCOL) if c in shown]  # an entrant's table
    for _, group in shown.groupby(by, sort=False, dropna=False):
        dn, kind, pn = (group[c].iloc[0] for c in (DETECTOR, INPUT, PROTOCOL))
        click.echo(f"\n## {dn}{'' if kind == 'univariate' else f' ({kind})'} x {pn}\n")
        click.echo(protocol_table(group, intervals=o.intervals))
    counts = rows["status"].value_counts()
    click.echo(
        f"\n{len(rows)} cells: "
        + ", ".join(f"{int(counts.get(s, 0))} {s}" for s in ("ok", "skipped", "failed", "timeout"))
        + f"; results in {o.out / 'results.parquet'}"
    )
    if kept := balance_kept(rows):
        click.echo(f"windows used of those available before balancing: {kept}")
    for line in grouped_warnings(rows) + fitting_warnings(rows):
        click.echo(f"warning: {line}", err=True)
    for reason in rows.loc[rows["status"] == "skipped", "reason"].unique():
        click.echo(f"skipped: {reason}", err=True)
    failed = cells_failed(rows, str(o.out))
    if broken:  # exit 3 outranks 4, so the cells that did not finish are listed with it
        raise PluginError(
            "; ".join(broken) + " (the other plugins ran)" + (f"\n{failed}" if failed else "")
        )
    if failed:
        raise failed


def _first_use(o: EvaluateArgs) -> bool:
    """Say, first of all, that the default dataset is simulated where this run needs it and it
    is not cached yet (a newcomer's first command: it takes a while); whether it was said."""
    if o.dataset_path or o.train_path:
        return False
    from slipbench.data.defaults import first_use

    line = first_use(o.scale, o.seed)
    if line:
        click.echo(line)
    return line is not None


def _cached(o: EvaluateArgs, runs: list, store) -> pd.DataFrame | None:
    """The rows of a fully cached run, read from the store without reading the dataset's samples
    (:func:`slipbench.engine.cached.cached_rows`); None where a cell must be computed."""
    from slipbench.data.defaults import default_dataset_path
    from slipbench.data.read import read_recordings
    from slipbench.engine.cached import cached_rows

    known = read_recordings(o.dataset_path or default_dataset_path(o.scale, o.seed))
    return None if known is None else cached_rows(*known, runs, store)


def _evaluated(o: EvaluateArgs, runs: list, store, slurm, simulating: bool) -> pd.DataFrame:
    """The rows of a run that computes cells: the dataset read whole (or simulated, or two
    combined), workers started where cells must run. What the detectors prepare once per
    machine (the LSTM's kernels) starts first, beside the reading or simulating."""
    from slipbench.data.defaults import default_dataset
    from slipbench.data.read import read_dataset
    from slipbench.engine.limits import cell_limit, limit_words
    from slipbench.engine.runner import evaluate as run_protocols
    from slipbench.engine.runner import prepare_ahead

    if o.scheduler is None:  # this machine's workers will load what it prepares
        prepare_ahead(runs, not o.quiet)

    if o.train_path and o.dataset_path:  # checked above: --train-dataset needs --dataset
        from slipbench.data.transfer import combine, parse_sensor_map

        ds = combine(
            read_dataset(o.train_path), read_dataset(o.dataset_path), parse_sensor_map(o.sensor_map)
        )
    else:
        ds = (
            read_dataset(o.dataset_path)
            if o.dataset_path
            else default_dataset(o.scale, o.seed, echo=None if simulating else click.echo)
        )
    if not o.quiet:
        click.echo(limit_words(o.cell_timeout, o.jobs, o.scheduler), err=True)
    return run_protocols(
        ds,
        runs,
        store,
        force=o.force,
        jobs=o.jobs,
        scheduler=o.scheduler,
        cell_timeout=cell_limit(o.cell_timeout, o.jobs, o.scheduler),
        progress=not o.quiet,
        slurm=slurm,
    )
