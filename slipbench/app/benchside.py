"""What a side of a benchmark file does around its models: reads the dataset it declares and
writes its reports. :mod:`slipbench.app.benchfile` runs a side with them, and
:mod:`slipbench.app.calibrate` times them as a side spends them (the plan's cost of a side)."""

from __future__ import annotations

from pathlib import Path

from slipbench.app.benchspec import Benchmark


def read_data(bench: Benchmark, echo=print):
    """The file's dataset folder (with ``train``: the two combined); None for the simulated."""
    from slipbench.data.read import read_dataset

    if bench.dataset is None:
        return None
    if bench.train is not None:
        from slipbench.data.transfer import combine, parse_sensor_map

        return combine(
            read_dataset(bench.train),
            read_dataset(bench.dataset),
            parse_sensor_map(tuple(bench.sensor_map)),
        )
    return read_dataset(bench.dataset)


def bench_dataset(bench: Benchmark, echo=print):
    """The dataset the file declares: its folder (:func:`read_data`), or the simulated one at
    its scale and seed (the run's seed where ``[dataset]`` gives none)."""
    from slipbench.data.defaults import default_dataset

    if bench.dataset is not None:
        return read_data(bench, echo)
    data_seed = bench.seed if bench.data_seed is None else bench.data_seed
    return default_dataset(bench.scale, data_seed, echo=echo)


def write_reports(bench: Benchmark, rows, out: Path) -> list[Path]:
    """Write the file's reports (and figures, with ``plots``) of ``rows`` into ``out``: what a
    run does after its last cell (and what a calibration times, :mod:`slipbench.app.calibrate`).
    Returns the files written."""
    from slipbench.app.selection import recorded_plugins
    from slipbench.atomic import write_text_atomic
    from slipbench.report.document import build_report, render, write_figures
    from slipbench.report.render import renderer

    blocks = build_report(
        recorded_plugins(rows),  # cells kept from a run before rows recorded their layouts
        metric=bench.metric,
        intervals=bench.intervals,
        paper=bench.paper,
        with_figures=bench.plots,
        benchmark=bench.describe,
        predictions=[out],
    )
    files = write_figures(blocks, out / "figures") if bench.plots else {}
    paths = [p for ps in files.values() for p in ps]
    for fmt in bench.report:
        path = out / f"report.{renderer(fmt).suffix}"
        write_text_atomic(path, render(blocks, fmt, standalone=True, files=files, link_from=out))
        paths.append(path)
    return paths
