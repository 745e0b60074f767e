"""`slipbench spectral`: which frequencies separate slip from non-slip (the paper's section IV)
for each sensor named, written as figure, table and bands, with the band in the form
`evaluate --param` reads."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import click

from slipbench.app.options import (
    dataset_option,
    out_option,
    scale_option,
    seed_option,
    split_option,
)
from slipbench.errors import UsageError


@dataclass(frozen=True)
class SpectralArgs:
    """What `slipbench spectral` was given, one field per option."""

    sensors: tuple[str, ...]
    instance: str | None
    dataset_path: Path | None
    scale: float
    out: Path
    seed: int
    train_only: bool
    split: str | None
    boot: int
    repeats: int
    segment: int | None
    alpha: float
    level: float
    keep: float


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
def spectral_cmd(**options) -> None:
    """Which frequencies separate slip from non-slip (the paper's section IV): figure, table, bands."""
    o = SpectralArgs(**options)
    import time

    from slipbench.analysis import spectral
    from slipbench.data.defaults import default_dataset
    from slipbench.data.read import read_dataset

    if o.split is not None and not o.train_only:
        raise UsageError(
            "--split names the run whose training side --train-only analyses; add --train-only"
        )
    split = (o.split or "paper") if o.train_only else None
    ds = (
        read_dataset(o.dataset_path)
        if o.dataset_path
        else default_dataset(o.scale, o.seed, echo=click.echo)
    )
    results, seconds = [], []
    for (
        sensor
    ) in o.sensors:  # every analysis before any file, so a bad name leaves no partial output
        start = time.perf_counter()
        results.append(
            spectral.analyze(
                ds,
                sensor,
                o.instance,
                segment=o.segment,
                n_boot=o.boot,
                repeats=o.repeats,
                alpha=o.alpha,
                level=o.level,
                keep=o.keep,
                seed=o.seed,
                split=split,
            )
        )
        seconds.append(time.perf_counter() - start)
    for sensor, result, took in zip(o.sensors, results, seconds):
        name = spectral.stem(sensor, o.instance)
        spectral.write(result, o.out, name)
        bands = ", ".join(f"{lo:g}-{hi:g}" for lo, hi in result.bands) or "none"
        click.echo(f"{name}: significant (>= {o.level:g}) bands, Hz: {bands}")
        if result.best_band:
            click.echo(
                f"{name}: most significant band {result.best_band[0]:g}-{result.best_band[1]:g} Hz; "
                f"use it with --param {spectral.band_param(result.best_band)}"
            )
        click.echo(f"{name}: {spectral.provenance(result)}")
        click.echo(f"{name}: analysed in {took:.1f} s; wrote {o.out / name}.png, .pdf, .csv, .json")
