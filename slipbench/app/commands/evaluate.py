"""`slipbench evaluate`: run protocols with detectors on a dataset (or train on one and test
on another), store the cells in a results folder and print each protocol's table."""

from __future__ import annotations

from pathlib import Path

import click

from slipbench.app.options import (
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
    scale_option,
    seed_option,
    split_option,
)
from slipbench.app.selection import add_plugin_folders, readable, select_plugins, with_options
from slipbench.engine import registry
from slipbench.errors import PluginError, UsageError


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
@click.option(
    "--scheduler", default=None, help="Address of a dask.distributed scheduler to run on."
)
@click.option(
    "--cell-timeout",
    default=None,
    type=click.FloatRange(min=0, min_open=True),
    help="Seconds one model may take; its cells are then reported as timeout.",
)
@force_option()
@intervals_option("Show 95 % intervals in the table.")
@quiet_option()
def evaluate(
    detector_name,
    protocol_name,
    dataset_path,
    train_path,
    sensor_map,
    scale,
    out,
    split,
    labels,
    normalize,
    input_kind,
    seed,
    repeats,
    params,
    protocol_params,
    plugins,
    jobs,
    scheduler,
    cell_timeout,
    force,
    intervals,
    quiet,
) -> None:
    """Run protocols with detectors; write results to --out and print the tables."""
    from slipbench.data.defaults import default_dataset
    from slipbench.data.read import read_dataset
    from slipbench.engine.runner import Run
    from slipbench.engine.runner import evaluate as run_protocols
    from slipbench.report.document import protocol_table
    from slipbench.store.results import ResultsStore, cells_failed

    add_plugin_folders(plugins)
    if train_path and not dataset_path:
        raise UsageError("--train-dataset needs --dataset: the dataset to test on")
    if sensor_map and not train_path:
        raise UsageError(
            "--sensor-map matches a test dataset's sensors to a training dataset's: it needs --train-dataset"
        )
    split = "datasets" if train_path else split
    broken: list[str] = []
    note = lambda line: click.echo(line, err=True)  # noqa: E731
    detectors = with_options(
        select_plugins(registry.detectors, detector_name, broken, note),
        parse_params(params),
        "detector",
    )
    protocols = with_options(
        select_plugins(registry.protocols, protocol_name, broken, note),
        parse_params(protocol_params),
        "protocol",
    )
    runs = [
        Run(d, p, split, seed + r, labels, normalize, kind)
        for name, d in detectors.items()
        for kind in readable(name, d, input_kind, note)
        for p in protocols.values()
        for r in range(repeats)
    ]
    if not runs:
        raise UsageError(f"no detector chosen reads the {input_kind} input (see `slipbench list`)")
    for run in runs:
        run.validate()  # every option before the dataset is read or simulated
    if train_path:
        from slipbench.data.transfer import combine, parse_sensor_map

        ds = combine(
            read_dataset(train_path), read_dataset(dataset_path), parse_sensor_map(sensor_map)
        )
    else:
        ds = (
            read_dataset(dataset_path)
            if dataset_path
            else default_dataset(scale, seed, echo=click.echo)
        )
    rows = run_protocols(
        ds,
        runs,
        ResultsStore(out),
        force=force,
        jobs=jobs,
        scheduler=scheduler,
        cell_timeout=cell_timeout,
        progress=not quiet,
    )
    for (dn, kind, pn), group in rows.groupby(["detector", "input", "protocol"], sort=False):
        click.echo(f"\n## {dn}{'' if kind == 'univariate' else f' ({kind})'} x {pn}\n")
        click.echo(protocol_table(group, protocols[pn].layout, intervals=intervals))
    counts = rows["status"].value_counts()
    click.echo(
        f"\n{len(rows)} cells: "
        + ", ".join(f"{int(counts.get(s, 0))} {s}" for s in ("ok", "skipped", "failed", "timeout"))
        + f"; results in {out / 'results.parquet'}"
    )
    for reason in rows.loc[rows["status"] == "skipped", "reason"].unique():
        click.echo(f"skipped: {reason}", err=True)
    failed = cells_failed(rows, str(out))
    if broken:  # exit 3 outranks 4, so the cells that did not finish are listed with it
        raise PluginError(
            "; ".join(broken) + " (the other plugins ran)" + (f"\n{failed}" if failed else "")
        )
    if failed:
        raise failed
