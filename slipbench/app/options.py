"""Options that several `slipbench` commands share, as click decorators (``@plugins_option()``,
``@out_option(...)``, ``@seed_option()``, ...), with their parameter types (a dataset scale, a
seed) and the parser of repeated NAME=VALUE options, so an option reads, validates and defaults
the same in every command that takes it. The help text stays each command's: the same option
means a different folder or file to ``evaluate`` and to ``report``.

A command takes ``**options`` and builds one frozen dataclass of them, declared beside it
(``o = EvaluateArgs(**options)``; the pattern: docs/contributing.md)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import click

from slipbench.errors import TOO_DEEP, UsageError, did_you_mean

MAX_SCALE = 10.0  # 80 M samples per unit: beyond this machine's memory for any protocol
MAX_SEED = 2**32 - 1  # what numpy's SeedSequence and every seeded library accept
SEED = click.IntRange(0, MAX_SEED)
# seeds of one command: more than any interval needs (a seed retrains every model; the gate
# decides with tens), and a plan of a billion runs would sit in planning without a word
MAX_REPEATS = 1000
SPLIT_CHOICES = ["paper", "grouped"]
LABELLING_CHOICES = ["scenario", "majority", "any", "last"]


class SuggestingGroup(click.Group):
    """A command group that answers a mistyped command with the closest ones
    (:func:`~slipbench.errors.did_you_mean`, as for plugin ids), from the names it lists: a lazy
    group's ``commands`` is empty until one is imported, and click before 8.2 suggests none.
    Options suggest already (click's own, as ``No such option '--protocl'. (Did you mean ...?)``)."""

    def resolve_command(
        self, ctx: click.Context, args: list[str]
    ) -> tuple[str | None, click.Command | None, list[str]]:
        name = args[0]
        if (
            not ctx.resilient_parsing
            and not name.startswith("-")
            and self.get_command(ctx, name) is None
        ):
            names = self.list_commands(ctx)
            ctx.fail(
                f"No such command {name!r}{did_you_mean(name, names)}; commands: {', '.join(names)}."
            )
        return super().resolve_command(ctx, args)


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


class Destination(click.Path):
    """A file or folder the command writes, refused while the options are read, before any work,
    where this process cannot write there (exit 5 naming it; nothing is created). A results
    folder that holds cells passes: a rerun that finds them all writes nothing, and the run
    checks again once it knows what it must write."""

    def __init__(self, results: bool = False, **kwargs) -> None:
        super().__init__(path_type=Path, **kwargs)
        self.results = results

    def convert(self, value, param, ctx):
        from slipbench.atomic import RESULTS_CELLS, check_writable

        path = super().convert(value, param, ctx)
        check_writable(path, RESULTS_CELLS if self.results else "")
        return path


def repeats_problem(seed: int, repeats: int) -> str | None:
    """Why seeds ``seed`` .. ``seed + repeats - 1`` cannot be run, or None."""
    if repeats > MAX_REPEATS:
        return f"at most {MAX_REPEATS} seeds (each retrains every model)"
    if seed + repeats - 1 > MAX_SEED:
        return f"seeds {seed} to {seed + repeats - 1} pass {MAX_SEED}, the largest seed"
    return None


#: an example item of each NAME=VALUE option, for its error message
PARAM_EXAMPLES = {"--param": "band=[0,100]", "--protocol-param": "decimation=both"}


def parse_params(values: tuple[str, ...], option: str = "--param") -> dict:
    """The NAME=VALUE items of a repeated option (``option``, named in errors) as a dict; a
    VALUE that is not JSON stays text."""
    params = {}
    for item in values:
        if "=" not in item:
            raise UsageError(
                f"{option} {item!r}: expected NAME=VALUE, e.g. {option} {PARAM_EXAMPLES[option]}"
            )
        name, text = item.split("=", 1)
        try:
            params[name] = json.loads(text)
        except json.JSONDecodeError:
            params[name] = text
        except RecursionError:
            raise UsageError(f"{option} {name}: {TOO_DEEP}") from None
    return params


def _shown(default) -> dict:
    """A default worth showing in the help; None (decided later, e.g. by a file) is not."""
    return {} if default is None else {"show_default": True}


PLUGINS_HELP = "A plugin folder (repeatable)."
# report and compare read layouts from the rows; a plugin only fills in those of older rows
LAYOUT_PLUGINS_HELP = (
    "A plugin folder whose protocols' layouts to use for rows written before results recorded "
    "them (repeatable)."
)


def plugins_option(help: str = PLUGINS_HELP):
    return click.option("--plugins", multiple=True, type=click.Path(), help=help)


def out_option(help: str, default: str | None = None, results: bool = False):
    """``--out``: a folder or file the command writes, checked before any work (see
    :class:`Destination`; ``results``: a results folder); without a default it is optional and
    the command decides."""
    given: dict[str, Any] = {} if default is None else {"default": default, "show_default": True}
    return click.option("--out", type=Destination(results), help=help, **given)


def seed_option(help: str | None = None, default: int | None = 0):
    """``--seed``; ``default=None`` leaves it unset (a benchmark file's own seed then holds)."""
    return click.option(
        "--seed", default=default, show_default=default is not None, type=SEED, help=help
    )


def scale_option(help: str):
    return click.option("--scale", default=0.05, show_default=True, type=Scale(), help=help)


def dataset_option(help: str):
    return click.option("--dataset", "dataset_path", type=click.Path(path_type=Path), help=help)


def split_option(help: str | None = None, default: str | None = "paper"):
    return click.option(
        "--split", type=click.Choice(SPLIT_CHOICES), default=default, help=help, **_shown(default)
    )


def labels_option(help: str | None = None):
    return click.option(
        "--labels",
        type=click.Choice(LABELLING_CHOICES),
        default="scenario",
        show_default=True,
        help=help,
    )


def balance_option():
    return click.option(
        "--balance",
        type=click.Choice(["within", "across"]),
        default="within",
        show_default=True,
        help="Balancing keeps slip equal per material and speed, and non-slip per material "
        "(within: the paper), or pools the materials (across: slip equal per speed), which keeps "
        "more where each material is one object or trial.",
    )


def protocol_params_option(help: str):
    return click.option("--protocol-param", "protocol_params", multiple=True, help=help)


def _jobs(ctx, param, jobs: int | None) -> int | None:
    from slipbench.engine.limits import jobs_problem

    if jobs is not None and (problem := jobs_problem(jobs)):
        raise UsageError(f"--jobs {jobs}: {problem}")
    return jobs


def jobs_option(help: str, default: int | None = None):
    return click.option(
        "--jobs",
        type=click.IntRange(0),
        default=default,
        callback=_jobs,
        help=help,
        **_shown(default),
    )


def _scheduler(ctx, param, scheduler: str | None) -> str | None:
    from slipbench.engine.limits import scheduler_problem

    if scheduler is not None and (problem := scheduler_problem(scheduler)):
        raise UsageError(f"--scheduler {scheduler!r}: {problem}")
    return scheduler


def scheduler_option(help: str | None = None):
    """``--scheduler``: an executor by name, or a dask scheduler's address or file, checked
    as it is read (:func:`slipbench.engine.limits.scheduler_problem`)."""
    return click.option(
        "--scheduler", default=None, callback=_scheduler, help=help or SCHEDULER_HELP
    )


def force_option():
    return click.option(
        "--force", is_flag=True, help="Recompute cells already in the results folder."
    )


def quiet_option():
    return click.option("--quiet", is_flag=True, help="No progress bar.")


def intervals_option(help: str):
    return click.option("--intervals", is_flag=True, help=help)


SCHEDULER_HELP = (
    "Where models run: slurm (a SLURM job array through submitit; the results folder must be "
    "on a file system the nodes share), submitit-local (the same path in local processes), or "
    "the address of a dask.distributed scheduler (tcp://HOST:8786)."
)


def slurm_option():
    return click.option(
        "--slurm",
        "slurm",
        multiple=True,
        metavar="KEY=VALUE",
        help="A SLURM resource for --scheduler slurm or submitit-local (repeatable; over a run "
        "file's [slurm] table): partition, time (minutes), cpus_per_task, mem_gb, "
        "gpus_per_node, array_parallelism, tasks, account, qos, constraint, setup, folder; "
        "DETECTOR.KEY=VALUE for one detector's tasks.",
    )


def slurm_resources(scheduler: str | None, items: tuple[str, ...], table: dict | None, detectors):
    """The checked resources of a SLURM run (None for any other scheduler); ``--slurm`` given
    without one is a usage error."""
    from slipbench.engine.limits import SCHEDULERS
    from slipbench.engine.slurm import from_options, resources

    if scheduler not in SCHEDULERS:
        if items:
            raise UsageError(f"--slurm sets the resources of --scheduler {' or '.join(SCHEDULERS)}")
        return None
    return resources(from_options(items, table), tuple(detectors))
