"""`slipbench calibrate`: a bench file's seed noise, measured once on many seeds and written
beside it, then the gate's plan it gives."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import click

from slipbench.app.options import jobs_option, quiet_option


@dataclass(frozen=True)
class CalibrateArgs:
    """What `slipbench calibrate` was given, one field per option."""

    bench_file: Path
    seeds: int
    jobs: int | None
    work: Path | None
    if_stale: bool
    quiet: bool


@click.command("calibrate")
@click.argument("bench_file", type=click.Path(path_type=Path))
@click.option(
    "--seeds",
    type=click.IntRange(min=2),
    default=20,
    show_default=True,
    help="Seeds to run, from the file's run.seed, each twice (the second time retrained from "
    "another draw on the same split); at least the [gate] budget serves every look.",
)
@jobs_option("Local worker processes [default: the file's run.jobs].")
@click.option(
    "--work",
    type=click.Path(path_type=Path, file_okay=False),
    help="Folder for the calibration's results (an interrupted calibration resumes from them) "
    "[default: calibration/ in the file's benchmark.out].",
)
@click.option(
    "--if-stale",
    is_flag=True,
    help="Measure only where the bench's calibration does not hold for every detector "
    "(none yet, the bench's settings, a detector's parameters or code changed): what a "
    "workflow runs on each push to main.",
)
@quiet_option()
def calibrate_command(**options) -> None:
    """Measure BENCH_FILE's seed noise per detector, protocol, cell and figure, write it to its
    calibration file (<name>.calibration.json beside it, or the one its [benchmark] calibration
    names), and print what the gate can then see."""
    o = CalibrateArgs(**options)
    from slipbench.app.benchfile import plan_runs
    from slipbench.app.benchspec import load_benchmark, with_overrides
    from slipbench.app.calibrate import calibrate, measured_read, status
    from slipbench.app.gateplan import plan_gate
    from slipbench.atomic import check_writable
    from slipbench.errors import UsageError

    bench = with_overrides(load_benchmark(o.bench_file), jobs=o.jobs)
    if bench.input == "both":
        raise UsageError(
            f'{bench.path}: [run] input = "both" runs each detector twice; a calibration '
            'measures one input per detector: calibrate a copy with input = "univariate" or '
            '"channels"'
        )
    runs = plan_runs(bench, click.echo, check_gate=False)  # this is how a refused gate is mended
    now = status(bench, runs)
    if o.if_stale and now.calibration is not None and not now.stale:
        click.echo(f"{now.path} holds for every detector of {bench.path.name}: nothing to measure")
        return
    work = o.work or bench.out / "calibration"
    target = bench.calibration_file
    for path in (work, target.parent):
        check_writable(path)
    data, side = measured_read(bench, click.echo)
    calibrate(bench, runs, data, o.seeds, work, progress=not o.quiet, echo=click.echo, side=side)
    click.echo(f"wrote {target}")
    for line in plan_gate(bench, runs, status(bench, runs)).lines():
        click.echo(line)
