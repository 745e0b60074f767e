"""The `slipbench` command: thin click commands, no logic beyond parsing and calling."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click

from . import registry
from .errors import SlipbenchError, UsageError

EXIT_CODES = """Exit codes: 0 success; 1 compare found a regression; 2 bad usage or bad data;
3 a plugin failed to load; 130 interrupted."""


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
@click.option("--scale", default=0.05, show_default=True, help="1.0 gives ~8 million samples per sensor instance.")
@click.option("--seed", default=0, show_default=True)
def dataset_synth(out: Path, scale: float, seed: int) -> None:
    """Write the simulated design of experiments to folder OUT."""
    from .synth import synthesize

    if scale <= 0:
        raise UsageError(f"--scale must be > 0, got {scale}")
    synthesize(out, scale, seed)
    click.echo(f"wrote {out}")


@dataset.command("validate")
@click.argument("path", type=click.Path(path_type=Path))
def dataset_validate(path: Path) -> None:
    """Check that PATH follows the dataset format; name the first problem found."""
    from .data import read_dataset

    ds = read_dataset(path)
    n = sum(len(s) for s in ds.samples.values())
    labelled = sum(int((labels >= 0).sum()) for labels in ds.slip_labels.values())
    click.echo(f"{path}: valid slipbench dataset v1, {len(ds.recordings)} recordings in {ds.recordings['trial'].nunique()} trials, "
               f"{n} samples ({labelled} labelled per sample), fingerprint {ds.fingerprint}")


@dataset.command("info")
@click.argument("path", type=click.Path(path_type=Path))
def dataset_info(path: Path) -> None:
    """Recordings, samples and duration per sensor, instance, scenario, material and speed."""
    from .data import info, read_dataset

    table = info(read_dataset(path))
    click.echo(table.to_markdown(index=False, floatfmt=".1f"))
    click.echo(f"\ntotal: {int(table['recordings'].sum())} recordings, {int(table['samples'].sum())} samples, "
               f"{table['seconds'].sum():.1f} s")


@dataset.command("import")
@click.argument("kind", type=click.Choice(["csv", "biotacsp-dos"]))
@click.argument("src", type=click.Path(path_type=Path))
@click.argument("out", type=click.Path(path_type=Path))
@click.option("--config", type=click.Path(path_type=Path), help="csv: the mapping file (TOML; see datasets.md).")
def dataset_import(kind: str, src: Path, out: Path, config: Path | None) -> None:
    """Convert CSV files (KIND csv, with --config) or a published dataset at SRC into a
    slipbench dataset folder OUT."""
    from .importers import IMPORTERS, import_csv

    if kind == "csv":
        if config is None:
            raise UsageError("dataset import csv needs --config MAPPING.toml (see datasets.md, 'Bring your own recordings')")
        import_csv(src, out, config)
    elif config is not None:
        raise UsageError(f"dataset import {kind} takes no --config; its mapping is built in")
    else:
        IMPORTERS[kind](src, out)
    click.echo(f"wrote {out}")


@cli.command("list")
@click.option("--plugins", multiple=True, type=click.Path(), help="A plugin folder (repeatable).")
def list_plugins(plugins: tuple[str, ...]) -> None:
    """The detectors and protocols that can be selected."""
    _plugins(plugins)
    click.echo("detectors: " + ", ".join(registry.detectors.names()))
    click.echo("protocols: " + ", ".join(registry.protocols.names()))


@cli.command()
@click.option("--detector", "detector_name", required=True, help="A detector id, or 'all' (see `slipbench list`).")
@click.option("--protocol", "protocol_name", required=True, help="A protocol id, or 'all' (see `slipbench list`).")
@click.option("--dataset", "dataset_path", type=click.Path(path_type=Path), help="Dataset folder [default: the simulated one].")
@click.option("--scale", default=0.05, show_default=True, help="Scale of the simulated dataset when --dataset is not given.")
@click.option("--out", default="results", show_default=True, type=click.Path(path_type=Path), help="Results folder.")
@click.option("--split", type=click.Choice(["paper", "grouped"]), default="paper", show_default=True)
@click.option("--seed", default=0, show_default=True, help="Seed of balancing, splitting and training (and of the simulated data).")
@click.option("--repeats", default=1, show_default=True, type=click.IntRange(1), help="Rerun with seeds seed, seed+1, ...")
@click.option("--param", "params", multiple=True, help="Detector hyperparameter NAME=VALUE (JSON value); repeatable.")
@click.option("--protocol-param", "protocol_params", multiple=True, help="Protocol option NAME=VALUE, e.g. decimation=both.")
@click.option("--plugins", multiple=True, type=click.Path(), help="A plugin folder (repeatable).")
@click.option("--jobs", default=1, show_default=True, type=click.IntRange(1), help="Local worker processes.")
@click.option("--scheduler", default=None, help="Address of a dask.distributed scheduler to run on.")
@click.option("--cell-timeout", default=None, type=click.FloatRange(min=0, min_open=True), help="Seconds one model may take; its cells are then reported as timeout.")
@click.option("--force", is_flag=True, help="Recompute cells already in the results folder.")
@click.option("--intervals", is_flag=True, help="Show 95 % intervals in the table.")
@click.option("--quiet", is_flag=True, help="No progress bar.")
def evaluate(detector_name, protocol_name, dataset_path, scale, out, split, seed, repeats, params, protocol_params,
             plugins, jobs, scheduler, cell_timeout, force, intervals, quiet) -> None:
    """Run protocols with detectors; write results to --out and print the tables."""
    from .data import read_dataset
    from .defaults import default_dataset
    from .report import protocol_table
    from .results import ResultsStore
    from .runner import Run, evaluate as run_protocols

    _plugins(plugins)
    detector_names = registry.detectors.names() if detector_name == "all" else [detector_name]
    protocol_names = registry.protocols.names() if protocol_name == "all" else [protocol_name]
    detectors = {n: registry.detectors.get(n)().set_params(**_param(params)) for n in detector_names}
    options = _param(protocol_params)
    protocols = {}
    for name in protocol_names:
        cls = registry.protocols.get(name)
        try:
            protocols[name] = cls(**options) if options else cls()
        except TypeError as exc:
            raise UsageError(f"protocol {name!r} does not take options {sorted(options)}: {exc}") from None
    ds = read_dataset(dataset_path) if dataset_path else default_dataset(scale, seed, echo=click.echo)
    runs = [Run(d, dn, p, pn, split, seed + r) for dn, d in detectors.items() for pn, p in protocols.items() for r in range(repeats)]
    rows = run_protocols(ds, runs, ResultsStore(out), force=force, jobs=jobs, scheduler=scheduler,
                         cell_timeout=cell_timeout, progress=not quiet)
    for (dn, pn), group in rows.groupby(["detector", "protocol"], sort=False):
        click.echo(f"\n## {dn} x {pn}\n")
        click.echo(protocol_table(group, protocols[pn].table, intervals=intervals))
    for reason in rows.loc[rows["status"].isin(["failed", "timeout"]), "reason"].unique():
        click.echo(f"warning: {reason}", err=True)
    click.echo(f"\n{len(rows)} cells ({(rows['status'] == 'ok').sum()} ok); results in {out / 'results.parquet'}")


# -- bench (detector costs)
@cli.command()
@click.option("--detector", "names", multiple=True, help="A detector id (repeatable) [default: all].")
@click.option("--windows", default=3840, show_default=True, help="Training windows (3840 x 50 is a default-dataset cell).")
@click.option("--length", default=50, show_default=True, help="Window length in samples.")
@click.option("--seconds", default=2.0, show_default=True, help="Time spent on each LSTM figure.")
@click.option("--no-lstm-targets", is_flag=True, help="Skip the LSTM-versus-stock-torch figures.")
@click.option("--plugins", multiple=True, type=click.Path(), help="A plugin folder (repeatable).")
def bench(names, windows, length, seconds, no_lstm_targets, plugins) -> None:
    """Train µs/sample, inference µs/window and peak memory per detector; the LSTM's speed
    targets as ratios against stock torch.nn.LSTM timed in the same run."""
    from .bench import detector_costs, lstm_targets

    _plugins(plugins)
    if windows < 2 or length < 5:
        raise UsageError(f"--windows must be >= 2 and --length >= 5, got {windows} and {length}")
    costs = detector_costs(list(names) or registry.detectors.names(), windows, length)
    click.echo(costs.to_markdown(index=False, floatfmt=".3g"))
    if not no_lstm_targets:
        click.echo("\nLSTM (hidden 20) against stock torch.nn.LSTM, same run:\n")
        click.echo(lstm_targets(length, seconds).to_markdown(index=False, floatfmt=".3g"))



# -- spectral analysis
@cli.command("spectral")
@click.option("--sensor", "sensors", required=True, multiple=True, help="Sensor type, e.g. Nano17 (repeatable).")
@click.option("--instance", default=None, help="One instance, e.g. index [default: all, each balanced on its own].")
@click.option("--dataset", "dataset_path", type=click.Path(path_type=Path), help="Dataset folder [default: the simulated one, seed 0].")
@click.option("--scale", default=0.05, show_default=True, help="Scale of the simulated dataset when --dataset is not given.")
@click.option("--out", default="spectral", show_default=True, type=click.Path(path_type=Path), help="Folder for figures and tables.")
@click.option("--seed", default=0, show_default=True, help="Seeds balancing and bootstrap draws.")
@click.option("--boot", default=100, show_default=True, help="Bootstrap sequences per class and round.")
@click.option("--repeats", default=200, show_default=True, help="Rounds, i.e. KS tests per frequency.")
@click.option("--segment", type=int, default=None, help="Samples per balanced window joined into a sequence [default: one second, contiguous].")
@click.option("--alpha", default=0.05, show_default=True, help="Level of each KS test.")
@click.option("--level", default=0.95, show_default=True, help="Significance a bin needs to be in a significant band.")
@click.option("--keep", default=0.8, show_default=True, help="Most significant band: bins whose mean KS statistic is >= keep x the peak's.")
def spectral_cmd(sensors, instance, dataset_path, scale, out, seed, boot, repeats, segment, alpha, level, keep) -> None:
    """Which frequencies separate slip from non-slip (the paper's section IV): figure, table, bands."""
    import time

    from . import spectral
    from .data import read_dataset
    from .defaults import default_dataset

    ds = read_dataset(dataset_path) if dataset_path else default_dataset(scale, 0, echo=click.echo)
    results, seconds = [], []
    for sensor in sensors:  # every analysis before any file, so a bad name leaves no partial output
        start = time.perf_counter()
        results.append(spectral.analyze(ds, sensor, instance, segment=segment, n_boot=boot, repeats=repeats,
                                        alpha=alpha, level=level, keep=keep, seed=seed))
        seconds.append(time.perf_counter() - start)
    for sensor, result, took in zip(sensors, results, seconds):
        name = spectral.stem(sensor, instance)
        spectral.write(result, out, name)
        bands = ", ".join(f"{lo:g}-{hi:g}" for lo, hi in result.bands) or "none"
        click.echo(f"{name}: significant (>= {level:g}) bands, Hz: {bands}")
        if result.best_band:
            click.echo(f"{name}: most significant band {result.best_band[0]:g}-{result.best_band[1]:g} Hz; "
                       f"use it with --param {spectral.band_param(result.best_band)}")
        click.echo(f"{name}: analysed in {took:.1f} s; wrote {out / name}.png, .pdf, .csv, .json")


# -- report and compare
@cli.command()
@click.argument("results", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--format", "fmt", type=click.Choice(["md", "latex"]), default="md", show_default=True)
@click.option("--metric", type=click.Choice(["accuracy", "tp_rate", "tn_rate", "balanced_accuracy", "auroc"]),
              default="accuracy", show_default=True, help="The figure the protocol tables show.")
@click.option("--intervals", is_flag=True, help="Show 95 % intervals: 88.0 [86.9, 89.1].")
@click.option("--paper", is_flag=True, help="Show the paper's published tables and the differences beside ours.")
@click.option("--standalone", is_flag=True, help="LaTeX: a whole document that compiles, not only the tables.")
@click.option("--plots", "plots_dir", type=click.Path(path_type=Path), help="Also write figures (PNG and PDF) here.")
@click.option("--out", type=click.Path(path_type=Path), help="Write the report to this file instead of printing it.")
def report(results, fmt, metric, intervals, paper, standalone, plots_dir, out) -> None:
    """Render RESULTS (results files or --out folders) as the paper's tables."""
    from .report import render_report
    from .results import read_results

    import pandas as pd

    rows = pd.concat([read_results(p) for p in results], ignore_index=True)
    text = render_report(rows, fmt, metric, intervals, paper, standalone)
    if out:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text)
        click.echo(f"wrote {out}")
    else:
        click.echo(text, nl=False)
    if plots_dir:
        from .plots import write_plots

        for path in write_plots(rows, plots_dir, paper=paper):
            click.echo(f"wrote {path}")


@cli.command("compare")
@click.argument("base", type=click.Path(path_type=Path))
@click.argument("candidate", type=click.Path(path_type=Path))
@click.option("--margin", default=0.0, show_default=True,
              help="Accuracy points a cell may lose (significantly) before it counts as a regression.")
@click.option("--out", type=click.Path(path_type=Path), help="Also write the Markdown to this file (a PR comment).")
def compare_command(base, candidate, margin, out) -> None:
    """Compare CANDIDATE results with BASE cell by cell; exit 1 if a cell regressed.

    Exit codes: 0 nothing regressed beyond --margin; 1 a cell regressed; 2 bad usage or data.
    """
    from .compare import compare, to_markdown

    result = compare(base, candidate, margin)
    text = to_markdown(result)
    click.echo(text, nl=False)
    if out:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text)
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
        click.echo("interrupted; finished cells are kept, rerun the same command to resume", err=True)
        sys.exit(130)


if __name__ == "__main__":
    main()
