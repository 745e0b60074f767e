"""`slipbench spectral`: which frequencies separate slip from non-slip (the paper's section IV)
for each sensor named, written as figure, table and bands, with the band in the form
`evaluate --param` reads."""

from __future__ import annotations

import click

from slipbench.app.options import (
    dataset_option,
    out_option,
    scale_option,
    seed_option,
    split_option,
)
from slipbench.errors import UsageError


@click.command("spectral")
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
@dataset_option("Dataset folder [default: the simulated one at --seed, as evaluate].")
@scale_option("Scale of the simulated dataset when --dataset is not given.")
@out_option("Folder for figures and tables.", default="spectral")
@seed_option("Seeds balancing, splitting and bootstrap draws (and the simulated data).")
@click.option(
    "--train-only",
    is_flag=True,
    help="Analyse only the training side of a run with --split and --seed, at --segment samples (default 50): a band chosen there never saw test data.",
)
@split_option("With --train-only: the run's split [default: paper].", default=None)
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
