"""`slipbench bench`: what each detector costs (train and inference time, peak memory) on toy
windows, and the speed figures detectors declare themselves."""

from __future__ import annotations

from dataclasses import dataclass

import click

from slipbench.app.options import plugins_option
from slipbench.app.selection import add_plugin_folders, available, require_available
from slipbench.engine import registry
from slipbench.errors import UsageError
from slipbench.vocabulary import MIN_WINDOW


@dataclass(frozen=True)
class BenchArgs:
    """What `slipbench bench` was given, one field per option."""

    names: tuple[str, ...]
    windows: int
    length: int
    seconds: float
    no_own_figures: bool
    plugins: tuple[str, ...]


@click.command("bench")
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
@plugins_option()
def bench(**options) -> None:
    """Train µs/sample, inference µs/window and peak memory per detector; each detector's own
    figures (the LSTM's against stock torch.nn.LSTM) as ratios timed in the same run."""
    o = BenchArgs(**options)
    from slipbench.app.bench import detector_benchmarks, detector_costs

    add_plugin_folders(o.plugins)
    if o.windows < 2 or o.length < MIN_WINDOW:
        raise UsageError(
            f"--windows must be >= 2 and --length >= {MIN_WINDOW}, got {o.windows} and {o.length}"
        )
    note = lambda line: click.echo(line, err=True)  # noqa: E731
    if o.names:
        for name in o.names:  # each named one must run: refused before any detector is timed
            require_available(registry.detectors, name)
        names = list(o.names)
    else:
        names = available(registry.detectors, registry.detectors.names(), note)
    costs = detector_costs(names, o.windows, o.length, echo=note)
    click.echo(costs.to_markdown(index=False, floatfmt=".3g"))
    if not o.no_own_figures:
        for name, table in detector_benchmarks(names, o.length, o.seconds).items():
            click.echo(f"\n{name}: its own figures against a reference timed in the same run\n")
            click.echo(table.to_markdown(index=False, floatfmt=".3g"))
