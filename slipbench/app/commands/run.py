"""`slipbench run`: run what a benchmark file (TOML) declares and write its results, its
reports and a copy of the file."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import click

from slipbench.app.options import (
    SCHEDULER_HELP,
    force_option,
    jobs_option,
    out_option,
    quiet_option,
    scheduler_option,
    seed_option,
    slurm_option,
    split_option,
)
from slipbench.errors import UsageError


@dataclass(frozen=True)
class RunArgs:
    """What `slipbench run` was given, one field per option."""

    bench_file: Path
    out: Path | None
    jobs: int | None
    seed: int | None
    split: str | None
    scheduler: str | None
    slurm: tuple[str, ...]
    plan: bool
    measured: tuple[Path, ...]
    force: bool
    quiet: bool


@click.command("run")
@click.argument("bench_file", type=click.Path(path_type=Path))
@out_option("Results folder [default: the file's benchmark.out].")
@jobs_option("Local worker processes [default: the file's run.jobs].")
@seed_option(
    "Seed of balancing, splitting and training (and of the simulated data unless [dataset] "
    "gives its own) [default: the file's run.seed].",
    default=None,
)
@split_option("Split of the run [default: the file's run.split].", default=None)
@scheduler_option("Where models run [default: the file's run.scheduler]: " + SCHEDULER_HELP)
@slurm_option()
@click.option(
    "--plan",
    is_flag=True,
    help="Run no cell and generate no data: print the cells, models and estimated cost per "
    "detector, here and on the [slurm] resources.",
)
@click.option(
    "--measured",
    multiple=True,
    type=click.Path(path_type=Path, exists=True, file_okay=False),
    help="With --plan: a results folder whose measured cells set the costs, besides the run's "
    "own (repeatable; any scale).",
)
@force_option()
@quiet_option()
def run_command(**options) -> None:
    """Run what BENCH_FILE (TOML) declares: dataset, detectors with parameters, protocols with
    options, split, seeds; write its results, its reports and a copy of the file."""
    o = RunArgs(**options)
    from slipbench.app.benchfile import run_benchmark
    from slipbench.app.benchspec import load_benchmark, with_overrides
    from slipbench.app.options import slurm_resources
    from slipbench.atomic import check_writable
    from slipbench.engine.slurm import from_options
    from slipbench.store.results import cells_failed

    bench = load_benchmark(o.bench_file)
    table = from_options(o.slurm, bench.slurm) if o.slurm else None
    bench = with_overrides(bench, scheduler=o.scheduler, slurm=table)
    if o.slurm and not o.plan:  # checked before any work: names --slurm
        slurm_resources(bench.scheduler, o.slurm, bench.slurm, bench.detectors)
    if o.split and bench.train is not None:
        raise UsageError(
            f"--split {o.split}: {bench.path} trains on [dataset] train and tests on its path "
            "(the datasets split)"
        )
    if o.measured and not o.plan:
        raise UsageError("--measured sets the costs of --plan")
    if o.plan:
        from slipbench.app.planning import planning, render

        bench = with_overrides(bench, out=o.out, jobs=o.jobs, seed=o.seed, split=o.split)
        note = lambda line: click.echo(line, err=True)  # noqa: E731
        click.echo(render(planning(bench, list(o.measured), note)))
        return
    if o.out is None:  # --out was checked as it was read; a run always writes its record there
        check_writable(bench.out)
    bench = with_overrides(bench, out=o.out, jobs=o.jobs, seed=o.seed, split=o.split)
    rows, paths = run_benchmark(bench, o.force, progress=not o.quiet, echo=click.echo)
    folder = bench.out
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
