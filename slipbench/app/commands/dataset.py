"""`slipbench dataset`: create (simulate or import), validate, describe and check Parquet
datasets; each command parses its options and calls the data and engine wings."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import click

from slipbench.app.options import (
    Destination,
    balance_option,
    labels_option,
    parse_params,
    plugins_option,
    protocol_params_option,
    scale_option,
    seed_option,
    split_option,
)
from slipbench.app.selection import add_plugin_folders, load_plugins, with_options
from slipbench.data.download import MIN_RATE, WAIT_S
from slipbench.engine import registry
from slipbench.errors import PluginError, UsageError
from slipbench.protocol import BaseProtocol


# what `dataset import` takes: csv (with a mapping) and each published dataset's importer, as
# slipbench.data.importers.IMPORTERS names them (kept here so that --help imports no pandas;
# tests/app/test_cli.py holds the two lists together)
IMPORT_KINDS = ["csv", "biotacsp-dos", "xela-proactive"]


@click.group("dataset")
def dataset() -> None:
    """Create, check and describe Parquet datasets."""


@dataset.command("synth")
@click.argument("out", type=Destination())
@scale_option("1.0 gives ~8 million samples per sensor instance.")
@seed_option()
def dataset_synth(out: Path, scale: float, seed: int) -> None:
    """Write the simulated design of experiments to folder OUT."""
    from slipbench.data.synth import synthesize

    synthesize(out, scale, seed)
    click.echo(f"wrote {out}")


@dataset.command("validate")
@click.argument("path", type=click.Path(path_type=Path))
def dataset_validate(path: Path) -> None:
    """Check that PATH follows the dataset format; name the first problem found, and say where
    bit rot could not be detected (no page checksums, no stored fingerprint)."""
    from slipbench.data.integrity import unguarded
    from slipbench.data.read import read_dataset

    ds = read_dataset(path)
    n = sum(len(s) for s in ds.samples.values())
    labelled = sum(int((labels >= 0).sum()) for labels in ds.slip_labels.values())
    click.echo(
        f"{path}: valid slipbench dataset v1, {len(ds.recordings)} recordings in {ds.recordings['trial'].nunique()} trials, "
        f"{n} samples ({labelled} labelled per sample), fingerprint {ds.fingerprint}"
    )
    _say_health(ds, path)
    lines = unguarded(path)
    click.echo(
        "\n".join(f"warning: {line}" for line in lines[:-1]) + f"\n{lines[-1]}"
        if lines
        else f"{path}: every page carries a checksum and the content its stored fingerprint: "
        "a damaged file is refused"
    )


@dataset.command("rewrite")
@click.argument("src", type=click.Path(path_type=Path))
@click.argument("out", type=Destination())
def dataset_rewrite(src: Path, out: Path) -> None:
    """Write dataset SRC again to the new folder OUT as slipbench writes datasets: with page
    checksums and its content fingerprint stored, so that bit rot is detected. The content, and
    so the fingerprint, stays the same."""
    from slipbench.data.write import rewrite_dataset

    rewrite_dataset(src, out)
    click.echo(f"wrote {out}")


@dataset.command("info")
@click.argument("path", type=click.Path(path_type=Path))
def dataset_info(path: Path) -> None:
    """Recordings, trials, samples and duration per sensor, instance, scenario, material and
    speed; with per-sample labels, the slip fraction and how far they disagree with the scenario."""
    from slipbench.app.info import describe, info
    from slipbench.data.read import read_dataset, read_description

    ds = read_dataset(path)
    table = info(ds)
    click.echo(table.to_markdown(index=False, floatfmt=".3g"))
    click.echo(
        f"\ntotal: {int(table['recordings'].sum())} recordings, {int(table['samples'].sum())} samples, "
        f"{table['seconds'].sum():.1f} s"
    )
    for line in describe(read_description(path)):
        click.echo(line)
    _say_health(ds, path)


def _say_health(ds, path: Path) -> None:
    """The dataset's health (repeated rows, time gaps, rate jitter) as ``warning:`` lines."""
    from slipbench.data.health import health_lines
    from slipbench.data.read import read_description

    for line in health_lines(ds, read_description(path)):
        click.echo(f"warning: {line}")


@dataclass(frozen=True)
class CheckArgs:
    """What `slipbench dataset check` was given, one field per option."""

    path: Path
    protocol_names: tuple[str, ...]
    protocol_params: tuple[str, ...]
    split: str
    labels: str
    balance: str
    seed: int
    plugins: tuple[str, ...]


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
@protocol_params_option("Protocol option NAME=VALUE, e.g. windows='[\"50ms\"]'.")
@split_option()
@labels_option()
@balance_option()
@seed_option()
@plugins_option()
def dataset_check(**options) -> None:
    """What PATH can support: classes, recordings and trials per unit, windows per size, and
    which protocol cells would run, be skipped, or rest on too few test trials."""
    o = CheckArgs(**options)
    from slipbench.data.read import read_dataset
    from slipbench.engine.check import CELL_COLUMNS, KEPT_COLUMNS, check_dataset
    from slipbench.engine.runner import Run
    from slipbench.protocol import NO_CELL
    from slipbench.report.provenance import grouped_warnings
    from slipbench.vocabulary import LOW_N

    add_plugin_folders(o.plugins)
    broken: list[str] = []
    protocols: dict[str, BaseProtocol] = {}
    for name in o.protocol_names:
        protocols |= load_plugins(registry.protocols, name, broken)
    protocols = with_options(
        protocols, parse_params(o.protocol_params, "--protocol-param"), "protocol"
    )
    runs = [
        Run("holweg", p, o.split, o.seed, o.labels, balance=o.balance) for p in protocols.values()
    ]
    for run in runs:
        run.validate()
    ds = read_dataset(o.path)
    _say_health(ds, o.path)
    result = check_dataset(ds, runs)
    click.echo(f"## {o.path}: classes per unit and window the protocols use (labels: {o.labels})\n")
    click.echo(result.units.to_markdown(index=False))
    click.echo(
        "\n## Windows the protocols use, per unit: slip and non-slip windows before balancing\n"
    )
    click.echo(result.windows.to_markdown(index=False, floatfmt="g"))
    for name, cells in result.cells.groupby("protocol", sort=False):
        if (cells["cell"] == NO_CELL).all():  # the protocol's stand-in: it makes no cell here
            click.echo(f"\n## {name}: no cell\n\n{cells['reason'].iloc[0]}")
            continue
        counts = cells["verdict"].value_counts()
        click.echo(
            f"\n## {name} ({o.split} split, seed {o.seed}): "
            + ", ".join(f"{int(counts.get(v, 0))} {v}" for v in ("runs", "low n", "skipped"))
            + f" of {len(cells)} cells\n"
        )
        flagged = cells[cells["verdict"] != "runs"]
        if len(flagged):
            click.echo(flagged[["cell", *CELL_COLUMNS[2:6]]].to_markdown(index=False))
        kept = cells[cells["train_slip"] != ""]
        if len(kept):
            click.echo(
                f"\nWindows each cell uses of those its sides could hold before balancing "
                f"(--balance {o.balance}):\n"
            )
            click.echo(kept[["cell", *KEPT_COLUMNS]].to_markdown(index=False))
        for line in grouped_warnings(cells.assign(protocol=name)):
            click.echo(f"warning: {line}", err=True)
    click.echo(
        f"\nlow n: fewer than {LOW_N} test trials of a class; such cells are flagged in results and tables."
    )
    if broken:
        raise PluginError("; ".join(broken))


@dataset.command("import")
@click.argument("kind", type=click.Choice(IMPORT_KINDS))
@click.argument("src", type=click.Path(path_type=Path))
@click.argument("out", type=Destination())
@click.option(
    "--config",
    type=click.Path(path_type=Path),
    help="csv: the mapping file (TOML; see datasets.md).",
)
@click.option(
    "--read-outside",
    "outside",
    multiple=True,
    type=click.Path(path_type=Path, exists=True, file_okay=False),
    help="csv: a folder outside SRC and the mapping's folder that the mapping's paths may lead "
    "into (metadata tables, a segments table, files linked from SRC); repeatable. Without it, "
    "a path with '..', an absolute path or a link leading out is refused.",
)
def dataset_import(
    kind: str, src: Path, out: Path, config: Path | None, outside: tuple[Path, ...]
) -> None:
    """Convert CSV files (KIND csv, with --config) or a published dataset at SRC into a
    slipbench dataset folder OUT."""
    from slipbench.data.importers import IMPORTERS, import_csv, load_mapping

    if kind == "csv":
        if config is None:
            raise UsageError(
                "dataset import csv needs --config MAPPING.toml (see datasets.md, 'Bring your own recordings')"
            )
        import_csv(src, out, load_mapping(config, None, outside))
    elif config is not None or outside:
        raise UsageError(
            f"dataset import {kind} takes no --config or --read-outside; its mapping is built in"
        )
    else:
        IMPORTERS[kind](src, out)
    click.echo(f"wrote {out}")
    from slipbench.data.read import read_dataset

    _say_health(read_dataset(out), out)


@dataset.command("cards")
def dataset_cards() -> None:
    """List the dataset cards: published datasets that `dataset fetch NAME` downloads."""
    import pandas as pd

    from slipbench.data.card import builtin_cards

    rows = [
        {
            "name": c.name,
            "title": c.title,
            "files": len(c.files),
            "size": f"{c.size / 1e6:.1f} MB",
            "license": c.license,
        }
        for c in builtin_cards().values()
    ]
    click.echo(pd.DataFrame(rows).to_markdown(index=False))
    click.echo(
        "\nslipbench dataset fetch NAME [--url MIRROR] [--out FOLDER]; cards: see datasets.md"
    )


@dataset.command("fetch")
@click.argument("name")
@click.option(
    "--url",
    help="Download from this base URL (a mirror) instead of the card's; file paths are appended.",
)
@click.option(
    "--out",
    type=Destination(),
    help="The new dataset folder [default: NAME in the working folder].",
)
@click.option(
    "--min-rate",
    type=click.FloatRange(min=0, min_open=True),
    default=MIN_RATE / 1e3,
    show_default=True,
    help=f"kB/s: each file must arrive within {WAIT_S:g} s plus its size at this rate, else the "
    "fetch stops, saying the server stalled; lower it to wait longer on a slow link.",
)
def dataset_fetch(name: str, url: str | None, out: Path | None, min_rate: float) -> None:
    """Download the published dataset of card NAME (or of a card file NAME.toml), check every
    file's SHA-256, keep them in slipbench's cache, and convert them into a dataset folder."""
    from slipbench.data.card import find_card
    from slipbench.data.fetch import fetch

    card = find_card(name)
    out = Path(card.name) if out is None else out
    fetch(card, out, url, lambda line: click.echo(line, err=True), min_rate * 1e3)
    click.echo(f"wrote {out}")
    click.echo(f"cite: {card.citation}")
    click.echo(f"license: {card.license}")


@dataset.command("card-files")
@click.argument("folder", type=click.Path(path_type=Path, exists=True, file_okay=False))
@click.option(
    "--glob",
    "patterns",
    multiple=True,
    default=("**/*",),
    show_default=True,
    help="Which files (relative to FOLDER, repeatable).",
)
def dataset_card_files(folder: Path, patterns: tuple[str, ...]) -> None:
    """Print the `files = [...]` entries of a card (path, SHA-256, size) for the files under
    FOLDER, a copy of what the lab publishes."""
    from slipbench.data.card import files_block

    click.echo(files_block(folder, patterns), nl=False)
