"""The `slipbench` command: thin click commands, no logic beyond parsing and calling."""

from __future__ import annotations

import json
import math
import sys
import traceback
from pathlib import Path

import click

from slipbench.engine import registry
from slipbench.errors import (
    ENVIRONMENT_ERRNOS,
    PluginError,
    SlipbenchError,
    UsageError,
    environment_fault,
)

EXIT_BUG = 70  # sysexits' EX_SOFTWARE: an internal error, reported with its traceback
EXIT_CODES = """Exit codes: 0 every cell ok or skipped; 1 compare found a regression; 2 bad usage or
bad data; 3 a plugin failed to load; 4 the run finished but cells failed or timed out (listed);
5 an environment fault (disk full, read-only folder, permission); 70 a bug in slipbench (with
its traceback); 130 interrupted."""


def _param(values: tuple[str, ...]) -> dict:
    params = {}
    for item in values:
        if "=" not in item:
            raise UsageError(f"--param {item!r}: expected NAME=VALUE, e.g. --param band=[0,100]")
        name, text = item.split("=", 1)
        try:
            params[name] = json.loads(text)
        except json.JSONDecodeError:
            params[name] = text
    return params


MAX_SCALE = 10.0  # 80 M samples per unit: beyond this machine's memory for any protocol


class Scale(click.ParamType):
    """A finite scale of the simulated dataset in (0, MAX_SCALE]."""

    name = "scale"

    def convert(self, value, param, ctx):
        try:
            scale = float(value)
        except (TypeError, ValueError):
            self.fail(f"{value!r} is not a number", param, ctx)
        if not (math.isfinite(scale) and 0 < scale <= MAX_SCALE):
            self.fail(
                f"{value!r} is not in (0, {MAX_SCALE:g}] (1.0 is the paper's size, about 8 M samples per unit)",
                param,
                ctx,
            )
        return scale


SEED = click.IntRange(0, 2**32 - 1)  # what numpy's SeedSequence and every seeded library accept


def _loaded(reg: registry.Registry, name: str, broken: list[str]) -> dict:
    """The plugin called ``name`` (or every plugin, for 'all'), made with its defaults. With 'all',
    a plugin that fails to load is noted in ``broken`` and the others run."""
    if name != "all":
        return {name: reg.get(name)()}
    out = {}
    for n in reg.names():
        try:
            out[n] = reg.get(n)()
        except PluginError as exc:
            broken.append(str(exc))
    if not out:
        raise PluginError("; ".join(broken))
    return out


def _with_options(plugins: dict, options: dict, kind: str) -> dict:
    """Each option set on the plugins that take it; one that none takes is a usage error."""
    for name, value in options.items():
        takers = [p for p in plugins.values() if name in p.get_params()]
        if not takers:
            raise UsageError(
                f"no selected {kind} takes the parameter {name!r}; parameters: "
                + "; ".join(
                    f"{n}: {', '.join(p.get_params()) or 'none'}" for n, p in plugins.items()
                )
            )
        for plugin in takers:
            plugin.set_params(**{name: value})
    return plugins


def _plugins(folders: tuple[str, ...]) -> None:
    for folder in folders:
        registry.add_plugin_folder(folder)


@click.group(epilog=EXIT_CODES)
@click.version_option(package_name="slipbench")
def cli() -> None:
    """Benchmark slip detectors on univariate tactile signals."""


@cli.group()
def dataset() -> None:
    """Create, check and describe Parquet datasets."""


@dataset.command("synth")
@click.argument("out", type=click.Path(path_type=Path))
@click.option(
    "--scale",
    default=0.05,
    show_default=True,
    type=Scale(),
    help="1.0 gives ~8 million samples per sensor instance.",
)
@click.option("--seed", default=0, show_default=True, type=SEED)
def dataset_synth(out: Path, scale: float, seed: int) -> None:
    """Write the simulated design of experiments to folder OUT."""
    from slipbench.data.synth import synthesize

    synthesize(out, scale, seed)
    click.echo(f"wrote {out}")


@dataset.command("validate")
@click.argument("path", type=click.Path(path_type=Path))
def dataset_validate(path: Path) -> None:
    """Check that PATH follows the dataset format; name the first problem found."""
    from slipbench.data.read import read_dataset

    ds = read_dataset(path)
    n = sum(len(s) for s in ds.samples.values())
    labelled = sum(int((labels >= 0).sum()) for labels in ds.slip_labels.values())
    click.echo(
        f"{path}: valid slipbench dataset v1, {len(ds.recordings)} recordings in {ds.recordings['trial'].nunique()} trials, "
        f"{n} samples ({labelled} labelled per sample), fingerprint {ds.fingerprint}"
    )


@dataset.command("info")
@click.argument("path", type=click.Path(path_type=Path))
def dataset_info(path: Path) -> None:
    """Recordings, trials, samples and duration per sensor, instance, scenario, material and
    speed; with per-sample labels, the slip fraction and how far they disagree with the scenario."""
    from slipbench.app.info import info
    from slipbench.data.read import read_dataset

    table = info(read_dataset(path))
    click.echo(table.to_markdown(index=False, floatfmt=".3g"))
    click.echo(
        f"\ntotal: {int(table['recordings'].sum())} recordings, {int(table['samples'].sum())} samples, "
        f"{table['seconds'].sum():.1f} s"
    )


@dataset.command("check")
@click.argument("path", type=click.Path(path_type=Path))
@click.option(
    "--protocol",
    "protocol_names",
    multiple=True,
    default=("all",),
    show_default=True,
    help="A protocol id (repeatable), or 'all'.",
)
@click.option(
    "--protocol-param",
    "protocol_params",
    multiple=True,
    help="Protocol option NAME=VALUE, e.g. windows='[\"50ms\"]'.",
)
@click.option(
    "--split", type=click.Choice(["paper", "grouped"]), default="paper", show_default=True
)
@click.option(
    "--labels",
    type=click.Choice(["scenario", "majority", "any", "last"]),
    default="scenario",
    show_default=True,
)
@click.option("--seed", default=0, show_default=True, type=SEED)
@click.option("--plugins", multiple=True, type=click.Path(), help="A plugin folder (repeatable).")
def dataset_check(path, protocol_names, protocol_params, split, labels, seed, plugins) -> None:
    """What PATH can support: classes, recordings and trials per unit, windows per size, and
    which protocol cells would run, be skipped, or rest on too few test trials."""
    from slipbench.data.read import read_dataset
    from slipbench.engine.check import LOW_N, check_dataset
    from slipbench.engine.runner import Run

    _plugins(plugins)
    broken: list[str] = []
    protocols = {}
    for name in protocol_names:
        protocols |= _loaded(registry.protocols, name, broken)
    protocols = _with_options(protocols, _param(protocol_params), "protocol")
    runs = [Run("holweg", p, split, seed, labels) for p in protocols.values()]
    for run in runs:
        run.validate()
    result = check_dataset(read_dataset(path), runs)
    click.echo(f"## {path}: classes per unit (labels: {labels}; windows of 50 samples)\n")
    click.echo(result.units.to_markdown(index=False))
    click.echo("\n## Windows per size: slip / non-slip, before balancing\n")
    click.echo(result.windows.to_markdown(index=False, floatfmt="g"))
    for name, cells in result.cells.groupby("protocol", sort=False):
        counts = cells["verdict"].value_counts()
        click.echo(
            f"\n## {name} ({split} split, seed {seed}): "
            + ", ".join(f"{int(counts.get(v, 0))} {v}" for v in ("runs", "low n", "skipped"))
            + f" of {len(cells)} cells\n"
        )
        flagged = cells[cells["verdict"] != "runs"]
        if len(flagged):
            click.echo(flagged.drop(columns="protocol").to_markdown(index=False))
    click.echo(
        f"\nlow n: fewer than {LOW_N} test trials of a class; such cells are flagged in results and tables."
    )
    if broken:
        raise PluginError("; ".join(broken))


@dataset.command("import")
@click.argument("kind", type=click.Choice(["csv", "biotacsp-dos"]))
@click.argument("src", type=click.Path(path_type=Path))
@click.argument("out", type=click.Path(path_type=Path))
@click.option(
    "--config",
    type=click.Path(path_type=Path),
    help="csv: the mapping file (TOML; see datasets.md).",
)
def dataset_import(kind: str, src: Path, out: Path, config: Path | None) -> None:
    """Convert CSV files (KIND csv, with --config) or a published dataset at SRC into a
    slipbench dataset folder OUT."""
    from slipbench.data.importers import IMPORTERS, import_csv

    if kind == "csv":
        if config is None:
            raise UsageError(
                "dataset import csv needs --config MAPPING.toml (see datasets.md, 'Bring your own recordings')"
            )
        import_csv(src, out, config)
    elif config is not None:
        raise UsageError(f"dataset import {kind} takes no --config; its mapping is built in")
    else:
        IMPORTERS[kind](src, out)
    click.echo(f"wrote {out}")


@cli.command("list")
@click.option("--plugins", multiple=True, type=click.Path(), help="A plugin folder (repeatable).")
@click.option("--json", "as_json", is_flag=True, help="Machine-readable: one object per plugin.")
def list_plugins(plugins: tuple[str, ...], as_json: bool) -> None:
    """The detectors and protocols that can be selected: status, description, parameters."""
    _plugins(plugins)
    found = {
        kind: [reg.describe(n) for n in reg.names()]
        for kind, reg in (("detectors", registry.detectors), ("protocols", registry.protocols))
    }
    if as_json:
        click.echo(json.dumps(found, indent=2, default=repr))
        return
    for kind, entries in found.items():
        click.echo(f"{kind}:")
        for e in entries:
            state = e["status"] + (f" ({e['detail']})" if e["detail"] else "")
            click.echo(f"  {e['name']:<18} {state if e['status'] != 'ok' else e['description']}")
            for name, p in e["parameters"].items():
                click.echo(
                    f"      {name}={p['default']!r}"
                    + (f"  ({p['constraint']})" if p["constraint"] else "")
                )


@cli.command()
@click.option(
    "--detector",
    "detector_name",
    required=True,
    help="A detector id, or 'all' (see `slipbench list`).",
)
@click.option(
    "--protocol",
    "protocol_name",
    required=True,
    help="A protocol id, or 'all' (see `slipbench list`).",
)
@click.option(
    "--dataset",
    "dataset_path",
    type=click.Path(path_type=Path),
    help="Dataset folder [default: the simulated one].",
)
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
@click.option(
    "--scale",
    default=0.05,
    show_default=True,
    type=Scale(),
    help="Scale of the simulated dataset when --dataset is not given.",
)
@click.option(
    "--out",
    default="results",
    show_default=True,
    type=click.Path(path_type=Path),
    help="Results folder.",
)
@click.option(
    "--split",
    type=click.Choice(["paper", "grouped"]),
    default="paper",
    show_default=True,
    help="paper: windows shuffled and halved; grouped: whole trials on one side, the same for every unit.",
)
@click.option(
    "--labels",
    type=click.Choice(["scenario", "majority", "any", "last"]),
    default="scenario",
    show_default=True,
    help="A window's class: its recording's scenario (the paper), or its samples' slip labels.",
)
@click.option(
    "--seed",
    default=0,
    show_default=True,
    type=SEED,
    help="Seed of balancing, splitting and training (and of the simulated data).",
)
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
@click.option(
    "--protocol-param",
    "protocol_params",
    multiple=True,
    help="Protocol option NAME=VALUE, e.g. decimation=both.",
)
@click.option("--plugins", multiple=True, type=click.Path(), help="A plugin folder (repeatable).")
@click.option(
    "--jobs",
    default=1,
    show_default=True,
    type=click.IntRange(0),
    help="Local worker processes (0: in this process, for debugging).",
)
@click.option(
    "--scheduler", default=None, help="Address of a dask.distributed scheduler to run on."
)
@click.option(
    "--cell-timeout",
    default=None,
    type=click.FloatRange(min=0, min_open=True),
    help="Seconds one model may take; its cells are then reported as timeout.",
)
@click.option("--force", is_flag=True, help="Recompute cells already in the results folder.")
@click.option("--intervals", is_flag=True, help="Show 95 % intervals in the table.")
@click.option("--quiet", is_flag=True, help="No progress bar.")
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

    _plugins(plugins)
    if train_path and not dataset_path:
        raise UsageError("--train-dataset needs --dataset: the dataset to test on")
    if sensor_map and not train_path:
        raise UsageError(
            "--sensor-map matches a test dataset's sensors to a training dataset's: it needs --train-dataset"
        )
    split = "datasets" if train_path else split
    broken: list[str] = []
    detectors = _with_options(
        _loaded(registry.detectors, detector_name, broken), _param(params), "detector"
    )
    protocols = _with_options(
        _loaded(registry.protocols, protocol_name, broken), _param(protocol_params), "protocol"
    )
    runs = [
        Run(d, p, split, seed + r, labels)
        for d in detectors.values()
        for p in protocols.values()
        for r in range(repeats)
    ]
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
    for (dn, pn), group in rows.groupby(["detector", "protocol"], sort=False):
        click.echo(f"\n## {dn} x {pn}\n")
        click.echo(protocol_table(group, protocols[pn].layout, intervals=intervals))
    counts = rows["status"].value_counts()
    click.echo(
        f"\n{len(rows)} cells: "
        + ", ".join(f"{int(counts.get(s, 0))} {s}" for s in ("ok", "skipped", "failed", "timeout"))
        + f"; results in {out / 'results.parquet'}"
    )
    for reason in rows.loc[rows["status"] == "skipped", "reason"].unique():
        click.echo(f"skipped: {reason}", err=True)
    if broken:
        raise PluginError("; ".join(broken) + " (the other plugins ran)")
    failed = cells_failed(rows, str(out))
    if failed:
        raise failed


# -- bench (detector costs)
@cli.command()
@click.option(
    "--detector", "names", multiple=True, help="A detector id (repeatable) [default: all]."
)
@click.option(
    "--windows",
    default=3840,
    show_default=True,
    help="Training windows (3840 x 50 is a default-dataset cell).",
)
@click.option("--length", default=50, show_default=True, help="Window length in samples.")
@click.option("--seconds", default=2.0, show_default=True, help="Time spent on each LSTM figure.")
@click.option(
    "--no-own-figures",
    is_flag=True,
    help="Skip the figures detectors declare themselves (the LSTM against stock torch).",
)
@click.option("--plugins", multiple=True, type=click.Path(), help="A plugin folder (repeatable).")
def bench(names, windows, length, seconds, no_own_figures, plugins) -> None:
    """Train µs/sample, inference µs/window and peak memory per detector; each detector's own
    figures (the LSTM's against stock torch.nn.LSTM) as ratios timed in the same run."""
    from slipbench.app.bench import detector_benchmarks, detector_costs

    _plugins(plugins)
    if windows < 2 or length < 5:
        raise UsageError(f"--windows must be >= 2 and --length >= 5, got {windows} and {length}")
    names = list(names) or registry.detectors.names()
    costs = detector_costs(names, windows, length)
    click.echo(costs.to_markdown(index=False, floatfmt=".3g"))
    if not no_own_figures:
        for name, table in detector_benchmarks(names, length, seconds).items():
            click.echo(f"\n{name}: its own figures against a reference timed in the same run\n")
            click.echo(table.to_markdown(index=False, floatfmt=".3g"))


# -- spectral analysis
@cli.command("spectral")
@click.option(
    "--sensor",
    "sensors",
    required=True,
    multiple=True,
    help="Sensor type, e.g. Nano17 (repeatable).",
)
@click.option(
    "--instance",
    default=None,
    help="One instance, e.g. index [default: all, each balanced on its own].",
)
@click.option(
    "--dataset",
    "dataset_path",
    type=click.Path(path_type=Path),
    help="Dataset folder [default: the simulated one at --seed, as evaluate].",
)
@click.option(
    "--scale",
    default=0.05,
    show_default=True,
    type=Scale(),
    help="Scale of the simulated dataset when --dataset is not given.",
)
@click.option(
    "--out",
    default="spectral",
    show_default=True,
    type=click.Path(path_type=Path),
    help="Folder for figures and tables.",
)
@click.option(
    "--seed",
    default=0,
    show_default=True,
    type=SEED,
    help="Seeds balancing, splitting and bootstrap draws (and the simulated data).",
)
@click.option(
    "--train-only",
    is_flag=True,
    help="Analyse only the training side of a run with --split and --seed, at --segment samples (default 50): a band chosen there never saw test data.",
)
@click.option(
    "--split",
    type=click.Choice(["paper", "grouped"]),
    default=None,
    help="With --train-only: the run's split [default: paper].",
)
@click.option(
    "--boot", default=100, show_default=True, help="Bootstrap sequences per class and round."
)
@click.option(
    "--repeats", default=200, show_default=True, help="Rounds, i.e. KS tests per frequency."
)
@click.option(
    "--segment",
    type=int,
    default=None,
    help="Samples per balanced window joined into a sequence [default: one second, contiguous; with --train-only: 50, the run's window].",
)
@click.option("--alpha", default=0.05, show_default=True, help="Level of each KS test.")
@click.option(
    "--level",
    default=0.95,
    show_default=True,
    help="Significance a bin needs to be in a significant band.",
)
@click.option(
    "--keep",
    default=0.8,
    show_default=True,
    help="Most significant band: bins whose mean KS statistic is >= keep x the peak's.",
)
def spectral_cmd(
    sensors,
    instance,
    dataset_path,
    scale,
    out,
    seed,
    train_only,
    split,
    boot,
    repeats,
    segment,
    alpha,
    level,
    keep,
) -> None:
    """Which frequencies separate slip from non-slip (the paper's section IV): figure, table, bands."""
    import time

    from slipbench.analysis import spectral
    from slipbench.data.defaults import default_dataset
    from slipbench.data.read import read_dataset

    if split is not None and not train_only:
        raise UsageError(
            "--split names the run whose training side --train-only analyses; add --train-only"
        )
    split = (split or "paper") if train_only else None
    ds = (
        read_dataset(dataset_path)
        if dataset_path
        else default_dataset(scale, seed, echo=click.echo)
    )
    results, seconds = [], []
    for sensor in sensors:  # every analysis before any file, so a bad name leaves no partial output
        start = time.perf_counter()
        results.append(
            spectral.analyze(
                ds,
                sensor,
                instance,
                segment=segment,
                n_boot=boot,
                repeats=repeats,
                alpha=alpha,
                level=level,
                keep=keep,
                seed=seed,
                split=split,
            )
        )
        seconds.append(time.perf_counter() - start)
    for sensor, result, took in zip(sensors, results, seconds):
        name = spectral.stem(sensor, instance)
        spectral.write(result, out, name)
        bands = ", ".join(f"{lo:g}-{hi:g}" for lo, hi in result.bands) or "none"
        click.echo(f"{name}: significant (>= {level:g}) bands, Hz: {bands}")
        if result.best_band:
            click.echo(
                f"{name}: most significant band {result.best_band[0]:g}-{result.best_band[1]:g} Hz; "
                f"use it with --param {spectral.band_param(result.best_band)}"
            )
        click.echo(f"{name}: {spectral.provenance(result)}")
        click.echo(f"{name}: analysed in {took:.1f} s; wrote {out / name}.png, .pdf, .csv, .json")


# -- report, run and compare
@cli.command()
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
@click.option("--intervals", is_flag=True, help="Show 95 % intervals: 88.0 [86.9, 89.1].")
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
    type=click.Path(path_type=Path),
    help="Also write figures (PNG and PDF) here, linked from the report.",
)
@click.option(
    "--out",
    type=click.Path(path_type=Path),
    help="Write the report to this file instead of printing it.",
)
@click.option(
    "--plugins",
    multiple=True,
    type=click.Path(),
    help="A plugin folder whose protocols' layouts to use (repeatable).",
)
def report(
    results, fmt, metric, leaderboard_only, intervals, paper, standalone, plots_dir, out, plugins
) -> None:
    """Render RESULTS (results files or --out folders): what they stand on, the leaderboard,
    then each protocol in its own layout (the paper's tables)."""
    import pandas as pd

    from slipbench.report.document import build_report, render, write_figures
    from slipbench.store.results import check_unique_keys, read_results, results_folder

    _plugins(plugins)
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
    text = render(blocks, fmt, standalone, files, link_from=out.parent if out else None)
    if out:
        from slipbench.atomic import write_text_atomic

        out.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(out, text)
        click.echo(f"wrote {out}")
    else:
        click.echo(text, nl=False)
    for path in (p for paths in files.values() for p in paths):
        click.echo(f"wrote {path}", err=not out)


@cli.command("run")
@click.argument("bench_file", type=click.Path(path_type=Path))
@click.option(
    "--out",
    type=click.Path(path_type=Path),
    help="Results folder [default: the file's benchmark.out].",
)
@click.option(
    "--jobs",
    type=click.IntRange(0),
    default=None,
    help="Local worker processes [default: the file's run.jobs].",
)
@click.option("--force", is_flag=True, help="Recompute cells already in the results folder.")
@click.option("--quiet", is_flag=True, help="No progress bar.")
def run_command(bench_file, out, jobs, force, quiet) -> None:
    """Run what BENCH_FILE (TOML) declares: dataset, detectors with parameters, protocols with
    options, split, seeds; write its results, its reports and a copy of the file."""
    from slipbench.app.benchfile import load_benchmark, run_benchmark
    from slipbench.store.results import cells_failed

    bench = load_benchmark(bench_file)
    rows, paths = run_benchmark(bench, out, jobs, force, progress=not quiet, echo=click.echo)
    folder = out or bench.out
    counts = rows["status"].value_counts()
    click.echo(
        f"{len(rows)} cells: "
        + ", ".join(f"{int(counts.get(s, 0))} {s}" for s in ("ok", "skipped", "failed", "timeout"))
        + f"; results in {folder / 'results.parquet'}"
    )
    for path in paths:
        click.echo(f"wrote {path}")
    failed = cells_failed(rows, str(folder))
    if failed:
        raise failed


@cli.command("compare")
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
@click.option(
    "--out",
    type=click.Path(path_type=Path),
    help="Also write the text to this file (a PR comment).",
)
@click.option(
    "--plugins",
    multiple=True,
    type=click.Path(),
    help="A plugin folder whose protocols' layouts to use (repeatable).",
)
def compare_command(
    base, candidate, margin, delay_margin, alarm_margin, fmt, max_rows, out, plugins
) -> None:
    """Compare CANDIDATE results with BASE cell by cell; exit 1 if a cell regressed.

    Exit codes: 0 nothing regressed beyond --margin; 1 a cell regressed; 2 bad usage or data.
    """
    from slipbench.atomic import write_text_atomic
    from slipbench.stats.compare import MAX_ROWS, compare, to_json, to_markdown

    _plugins(plugins)
    result = compare(
        base, candidate, margin, delay_margin_ms=delay_margin, alarm_margin=alarm_margin
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


def main(argv: list[str] | None = None) -> None:
    try:
        cli.main(args=argv, prog_name="slipbench", standalone_mode=False)
    except click.exceptions.ClickException as exc:
        exc.show()
        sys.exit(exc.exit_code)
    except click.exceptions.Abort:
        sys.exit(130)
    except SlipbenchError as exc:
        click.echo(f"error: {exc}", err=True)
        sys.exit(exc.exit_code)
    except KeyboardInterrupt:
        click.echo(
            "interrupted; finished cells are kept, rerun the same command to resume", err=True
        )
        sys.exit(130)
    except OSError as exc:
        if exc.errno not in ENVIRONMENT_ERRNOS:
            _bug()
        fault = environment_fault(exc, exc.filename or "?")
        click.echo(f"error: {fault}", err=True)
        sys.exit(fault.exit_code)
    except Exception:  # noqa: BLE001 - anything else is a bug, and said to be one
        _bug()


def _bug() -> None:
    traceback.print_exc()
    click.echo(
        "error: this is a bug in slipbench or in a plugin, not a problem with your data or options; "
        "please report it with the traceback above",
        err=True,
    )
    sys.exit(EXIT_BUG)


if __name__ == "__main__":
    main()
