"""Benchmark files: what to run, declared in TOML and versioned beside the code
(``slipbench run bench.toml``).

::

    [benchmark]
    out = "results"                # results folder, relative to this file
    report = ["md", "html"]        # report formats written to out/report.<ext>
    plots = true                   # figures (PNG, PDF) to out/figures
    paper = true                   # the published tables beside ours
    intervals = true
    metric = "accuracy"

    [dataset]                      # a dataset folder, or the simulated one (the default)
    path = "data/my-lab"           # or: scale = 0.05, seed = 0 (simulated)
    # train = "data/other-lab"     # train here, test on path (the 'datasets' split)
    # sensor_map = ["Vib=BioTacSP"]

    [run]
    split = "grouped"              # paper | grouped
    labels = "scenario"            # scenario | majority | any | last
    input = "univariate"           # univariate | channels | both (what detectors read)
    seed = 0
    repeats = 3                    # seeds seed, seed+1, seed+2
    jobs = 2
    cell_timeout = 600             # seconds per model (default 7200; 0: none)
    plugins = ["plugins"]          # plugin folders, relative to this file

    [slurm]                        # with scheduler = "slurm": each array task's resources
    partition = "cpu"              # (see docs/guides/scale-out.md for every key)
    time = 240                     # minutes; default: from cell_timeout
    cpus_per_task = 4
    [slurm.lstm]                   # one detector's tasks: their own resources
    gpus_per_node = 1

    [gate]                         # what `compare --bench` judges (default: every figure)
    accuracy = 1.0                 # tolerance: a drop smaller than it is no regression
    tn_rate = 1.0                  # points; false_alarms_per_min per minute, median_delay_ms ms
    budget = 12                    # seeds per side an undecided figure may grow to, in steps
                                   # of run.repeats (default: run.repeats, one look)

    [detectors.holweg]             # one table per detector: its parameters
    [detectors.lstm]
    max_epochs = 100

    [protocols.window-size]        # one table per protocol: its options
    windows = [25, 50, 100]
    [protocols.sampling-rate]
    decimation = "both"

Every key is checked before anything runs: an unknown key, a wrong type or a value outside its
constraint is a usage error (exit 2) naming the file, the line and the key. The file's text is
copied into the results folder (``benchmark.toml``) and its SHA-256 written beside it
(``benchmark.json``), so results say which declaration made them.

Where the file has a calibration beside it (``bench.calibration.json``, ``slipbench
calibrate``) that holds for its settings and detectors, a ``[gate]`` tolerance the bench cannot
decide even at its budget is refused when its runs are planned (:func:`plan_runs`), with the
budget, tolerance or scale that would decide it (:mod:`slipbench.app.gateplan`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import re
from dataclasses import dataclass, field
from datetime import datetime, timezone
from itertools import product
from pathlib import Path
from typing import Any

import tomllib

from slipbench.app.options import repeats_problem
from slipbench.errors import TOO_DEEP, PluginError, SlipbenchError, UsageError
from slipbench.gate.gate import DEFAULT_TOLERANCE, unit
from slipbench.report.render import FORMATS
from slipbench.store.columns import WINDOWED, names

BENCHMARK_FILE = "benchmark.toml"
RECORD_FILE = "benchmark.json"
BUDGET = "budget"  # the [gate] key that is not a figure
#: what a benchmark's report may rank by: a windowed cell's figures
METRICS = names(WINDOWED)
SCHEMA: dict[str, dict[str, tuple[type | tuple[type, ...], str]]] = {
    "benchmark": {
        "out": (str, "a folder"),
        "report": ((str, list), "a format or a list of them (md, latex, html)"),
        "plots": (bool, "true or false"),
        "paper": (bool, "true or false"),
        "intervals": (bool, "true or false"),
        "metric": (str, f"one of {', '.join(METRICS)}"),
        "name": (str, "a string"),
    },
    "dataset": {
        "path": (str, "a dataset folder"),
        "scale": ((int, float), "a number in (0, 10]"),
        "seed": (int, "an int >= 0"),
        "train": (str, "a dataset folder"),
        "sensor_map": (list, 'a list of "TEST=TRAIN" strings'),
    },
    "run": {
        "split": (str, "paper or grouped"),
        "labels": (str, "scenario, majority, any or last"),
        "input": (str, "univariate, channels or both"),
        "seed": (int, "an int in [0, 2**32 - 1]"),
        "repeats": (int, "an int >= 1"),
        "jobs": (int, "an int >= 0"),
        "cell_timeout": ((int, float), "seconds >= 0 (0: none)"),
        "scheduler": (str, "slurm, submitit-local, or a dask scheduler's address or file"),
        "plugins": (list, "a list of folders"),
    },
    # the figures `compare --bench` judges, each with its tolerance, and its seeds' budget
    "gate": {name: ((int, float), f"a tolerance > 0 in {unit(name)}") for name in DEFAULT_TOLERANCE}
    | {BUDGET: (int, "seeds per side, an int >= run.repeats")},
}
TABLES = ("benchmark", "dataset", "run", "slurm", "gate", "detectors", "protocols")


@dataclass
class Benchmark:
    """A parsed, checked benchmark file. Paths are absolute (resolved against the file's folder)."""

    path: Path
    text: str
    sha256: str
    out: Path
    report: list[str]
    plots: bool = True
    paper: bool = False
    intervals: bool = False
    metric: str = "accuracy"
    name: str = ""
    dataset: Path | None = None
    scale: float = 0.05
    data_seed: int | None = None
    train: Path | None = None
    sensor_map: list[str] = field(default_factory=list)
    split: str = "paper"
    labels: str = "scenario"
    input: str = "univariate"
    seed: int = 0
    repeats: int = 1
    jobs: int = 1
    cell_timeout: float | None = None
    scheduler: str | None = None
    plugins: list[Path] = field(default_factory=list)
    detectors: dict[str, dict[str, Any]] = field(default_factory=dict)
    protocols: dict[str, dict[str, Any]] = field(default_factory=dict)
    gate: dict[str, float] = field(default_factory=dict)  # figure -> tolerance; empty: defaults
    slurm: dict[str, Any] = field(default_factory=dict)  # the [slurm] table, checked
    budget: int | None = None  # seeds per side with sequential looks; None: repeats, one look

    @property
    def seeds_budget(self) -> int:
        """The most seeds per side a comparison may grow to (the first look's, ``repeats``,
        where the file sets no budget)."""
        return self.repeats if self.budget is None else self.budget

    @property
    def describe(self) -> str:
        """One line for a report's header."""
        return f"{self.path.name} (sha256 {self.sha256[:16]})" + (
            f": {self.name}" if self.name else ""
        )


def _line(text: str, table: str, key: str | None = None) -> int | None:
    """The line of ``[table]`` (or of ``key`` inside it) in the file, for messages: tomllib
    gives no positions, so the text is scanned (dotted tables, quoted keys)."""
    header = re.compile(r"^\s*\[\s*(.+?)\s*\]\s*(#.*)?$")
    current, found = None, None
    for n, line in enumerate(text.splitlines(), 1):
        m = header.match(line)
        if m:
            current = ".".join(
                part.strip().strip('"').strip("'")
                for part in re.split(r"\.(?=(?:[^\"]*\"[^\"]*\")*[^\"]*$)", m[1])
            )
            if key is None and current == table:
                return n
            continue
        if (
            key is not None
            and current == table
            and re.match(rf"^\s*[\"']?{re.escape(key)}[\"']?\s*=", line)
        ):
            return n
        if (
            key is None
            and found is None
            and re.match(rf"^\s*[\"']?{re.escape(table)}[\"']?\s*=", line)
        ):
            found = n  # an inline table: "table = {...}"
    return found


class BenchmarkError(UsageError):
    """A benchmark file that cannot be run as written (exit code 2)."""


def _fail(bench: Path, text: str, what: str, table: str, key: str | None = None) -> BenchmarkError:
    line = _line(text, table, key)
    where = (
        f"{bench}"
        + (f", line {line}" if line else "")
        + f", [{table}]"
        + (f" {key}" if key else "")
    )
    return BenchmarkError(f"{where}: {what}")


def _checked(bench: Path, text: str, data: dict) -> dict:
    """The file's tables, every key known and of its type."""
    for name, value in data.items():
        if name not in TABLES:
            raise _fail(
                bench,
                text,
                f"unknown table or key {name!r}; a benchmark file has the tables "
                f"{', '.join(f'[{t}]' for t in TABLES)}",
                name,
            )
        if not isinstance(value, dict):
            raise _fail(bench, text, f"{name!r} must be a table ([{name}])", name)
    for name, schema in SCHEMA.items():
        for key, value in data.get(name, {}).items():
            if key not in schema:
                raise _fail(
                    bench,
                    text,
                    f"unknown key {key!r}; [{name}] takes {', '.join(schema)}",
                    name,
                    key,
                )
            types, meaning = schema[key]
            if isinstance(value, bool) and bool not in (
                types if isinstance(types, tuple) else (types,)
            ):
                raise _fail(bench, text, f"{key} must be {meaning}, got {value!r}", name, key)
            if not isinstance(value, types):
                raise _fail(bench, text, f"{key} must be {meaning}, got {value!r}", name, key)
    for kind in ("detectors", "protocols"):
        for plugin, params in data.get(kind, {}).items():
            if not isinstance(params, dict):
                raise _fail(
                    bench,
                    text,
                    f"{plugin!r} must be a table of its parameters ([{kind}.{plugin}])",
                    kind,
                    plugin,
                )
    if not data.get("detectors"):
        raise _fail(
            bench,
            text,
            "no detector: add a table [detectors.<id>] per detector (see `slipbench list`)",
            "detectors",
        )
    if not data.get("protocols"):
        raise _fail(
            bench,
            text,
            "no protocol: add a table [protocols.<id>] per protocol (see `slipbench list`)",
            "protocols",
        )
    return data


def load_benchmark(path: str | Path, here: bool = True) -> Benchmark:
    """Read and check a benchmark file (syntax, tables, keys and their types; plugin names and
    parameters are checked by :func:`plan_runs`). Not ``here``: a bench another machine ran
    (a results folder's record), read for what it measures, so its workers and scheduler are
    not checked against this machine."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise UsageError(f"{path}: no such benchmark file") from None
    except IsADirectoryError:
        raise UsageError(f"{path}: a folder, not a benchmark file (TOML)") from None
    try:
        text = raw.decode("utf-8")
        data = tomllib.loads(text)
    except UnicodeDecodeError as exc:
        raise UsageError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except tomllib.TOMLDecodeError as exc:
        raise UsageError(f"{path}: not valid TOML: {exc}") from None
    except RecursionError:
        raise UsageError(f"{path}: {TOO_DEEP}") from None
    data = _checked(path, text, data)
    home = path.resolve().parent
    b, d, r = data.get("benchmark", {}), data.get("dataset", {}), data.get("run", {})

    def check(ok: bool, what: str, table: str, key: str) -> None:
        if not ok:
            raise _fail(path, text, what, table, key)

    formats = [b["report"]] if isinstance(b.get("report"), str) else b.get("report", ["md"])
    for f in formats:
        check(
            f in FORMATS,
            f"unknown report format {f!r}; one of {', '.join(FORMATS)}",
            "benchmark",
            "report",
        )
    check(
        b.get("metric", "accuracy") in METRICS,
        f"metric must be one of {', '.join(METRICS)}",
        "benchmark",
        "metric",
    )
    check(
        "path" in d or "train" not in d,
        "train needs path: the dataset to test on",
        "dataset",
        "train",
    )
    check(
        "train" in d or "sensor_map" not in d,
        "sensor_map matches a test dataset's sensors to a training dataset's: it needs train",
        "dataset",
        "sensor_map",
    )
    check(
        "path" not in d or not ({"scale", "seed"} & set(d)),
        "scale and seed describe the simulated dataset; a dataset with a path has neither",
        "dataset",
        "scale" if "scale" in d else "seed",
    )
    check(0 < d.get("scale", 0.05) <= 10, "scale must be in (0, 10]", "dataset", "scale")
    check(d.get("seed", 0) >= 0, "seed must be >= 0", "dataset", "seed")
    check(
        r.get("split", "paper") in ("paper", "grouped"),
        "split must be paper or grouped",
        "run",
        "split",
    )
    check(
        r.get("labels", "scenario") in ("scenario", "majority", "any", "last"),
        "labels must be scenario, majority, any or last",
        "run",
        "labels",
    )
    check(
        r.get("input", "univariate") in ("univariate", "channels", "both"),
        "input must be univariate, channels or both",
        "run",
        "input",
    )
    check(0 <= r.get("seed", 0) < 2**32, "seed must be in [0, 2**32 - 1]", "run", "seed")
    from slipbench.engine.limits import jobs_problem, scheduler_problem

    check(r.get("repeats", 1) >= 1, "repeats must be >= 1", "run", "repeats")
    seeds = repeats_problem(r.get("seed", 0), r.get("repeats", 1))
    check(seeds is None, f"repeats {r.get('repeats', 1)}: {seeds}", "run", "repeats")
    check(r.get("jobs", 1) >= 0, "jobs must be >= 0", "run", "jobs")
    workers = jobs_problem(r.get("jobs", 1)) if "scheduler" not in r and here else None
    check(workers is None, f"jobs {r.get('jobs')}: {workers}", "run", "jobs")
    where = scheduler_problem(r["scheduler"]) if "scheduler" in r and here else None
    check(where is None, f"scheduler {r.get('scheduler')!r}: {where}", "run", "scheduler")
    check(
        r.get("cell_timeout", 1) >= 0,
        "cell_timeout must be >= 0 seconds (0: none)",
        "run",
        "cell_timeout",
    )
    for item in d.get("sensor_map", []):
        check(
            isinstance(item, str) and "=" in item,
            f'sensor_map entries are "TEST=TRAIN" strings, got {item!r}',
            "dataset",
            "sensor_map",
        )
    for folder in r.get("plugins", []):
        check(
            isinstance(folder, str), f"plugins holds folder names, got {folder!r}", "run", "plugins"
        )
    g = data.get("gate", {})
    check(
        g.get(BUDGET, r.get("repeats", 1)) >= r.get("repeats", 1),
        f"budget ({g.get(BUDGET)}) must be at least run.repeats ({r.get('repeats', 1)}): the "
        "seeds of the first look",
        "gate",
        BUDGET,
    )
    check(
        BUDGET not in g or r.get("repeats", 1) >= 2,
        "a budget grows seeds in steps of run.repeats, which must then be >= 2 (one seed a "
        "side measures no retraining noise)",
        "gate",
        BUDGET,
    )
    return Benchmark(
        path=path,
        text=text,
        sha256=hashlib.sha256(raw).hexdigest(),
        out=home / b.get("out", "results"),
        report=list(dict.fromkeys(formats)),
        plots=b.get("plots", True),
        paper=b.get("paper", False),
        intervals=b.get("intervals", False),
        metric=b.get("metric", "accuracy"),
        name=b.get("name", ""),
        dataset=home / d["path"] if "path" in d else None,
        scale=float(d.get("scale", 0.05)),
        data_seed=d.get("seed"),
        train=home / d["train"] if "train" in d else None,
        sensor_map=list(d.get("sensor_map", [])),
        split="datasets" if "train" in d else r.get("split", "paper"),
        labels=r.get("labels", "scenario"),
        input=r.get("input", "univariate"),
        seed=r.get("seed", 0),
        repeats=r.get("repeats", 1),
        jobs=r.get("jobs", 1),
        cell_timeout=float(r["cell_timeout"]) if "cell_timeout" in r else None,
        scheduler=r.get("scheduler"),
        plugins=[home / p for p in r.get("plugins", [])],
        detectors={k: dict(v) for k, v in data["detectors"].items()},
        protocols={k: dict(v) for k, v in data["protocols"].items()},
        gate=_gate(path, text, {k: v for k, v in g.items() if k != BUDGET}),
        budget=g.get(BUDGET),
        slurm=_slurm(path, text, data.get("slurm", {}), tuple(data["detectors"])),
    )


def _slurm(path: Path, text: str, table: dict, detectors: tuple[str, ...]) -> dict:
    """The [slurm] table, every key and value checked (a bad one named with its line)."""
    from slipbench.engine.slurm import SlurmKeyError, resources

    try:
        resources(table, detectors)
    except SlurmKeyError as exc:
        where, _, key = exc.key.rpartition(".")
        if not where and isinstance(table.get(key), dict):  # a sub-table: its header's line
            raise _fail(path, text, exc.what, f"slurm.{key}") from None
        raise _fail(path, text, exc.what, f"slurm.{where}" if where else "slurm", key) from None
    return table


def _gate(path: Path, text: str, table: dict) -> dict[str, float]:
    """The [gate] table's figures: figure -> tolerance, each > 0."""
    for name, value in table.items():
        if not value > 0:
            raise _fail(path, text, f"{name} must be a tolerance > 0, got {value!r}", "gate", name)
    return {name: float(value) for name, value in table.items()}


def plan_runs(bench: Benchmark, echo=print, check_gate: bool = True) -> list:
    """The runs the file declares, every plugin loaded and every parameter checked (a bad one
    names the file, line and table); plugin folders are registered first. A plugin whose
    optional dependency is not installed here is skipped with a line to ``echo`` (one file
    serves machines with and without it); a kind left with none is refused (exit 3). With
    ``check_gate``, a ``[gate]`` tolerance the file's calibration says it cannot decide is
    refused (:func:`gate_decides`)."""
    from slipbench.app.selection import available, readable
    from slipbench.engine import registry
    from slipbench.engine.runner import Run

    for folder in bench.plugins:
        if not folder.is_dir():
            raise _fail(
                bench.path, bench.text, f"plugin folder {folder} does not exist", "run", "plugins"
            )
        registry.add_plugin_folder(folder)

    def made(kind: str, reg, name: str, params: dict):
        try:
            return reg.get(name)(**params)
        except TypeError:
            plugin = reg.get(name)()
            unknown = [k for k in params if k not in plugin.get_params()]
            raise _fail(
                bench.path,
                bench.text,
                f"{kind} {name!r} has no parameter {unknown[0] if unknown else '?'}; its "
                f"parameters: {', '.join(plugin.get_params()) or 'none'}",
                f"{kind}s.{name}",
                unknown[0] if unknown else None,
            ) from None
        except SlipbenchError as exc:
            raise _fail(
                bench.path, bench.text, str(exc), f"{kind}s.{name}", _param_in(str(exc), params)
            ) from None

    chosen = {}
    for kind, reg, declared in (
        ("detector", registry.detectors, bench.detectors),
        ("protocol", registry.protocols, bench.protocols),
    ):
        names = [n for n in declared if n in reg.names()]  # an unknown one: made() names it
        runnable = available(reg, names, echo) + [n for n in declared if n not in names]
        if not runnable:
            raise PluginError(
                f"{bench.path}: every {kind} it declares is unavailable here (see the lines above)"
            )
        chosen[kind] = {n: made(kind, reg, n, declared[n]) for n in declared if n in runnable}
    detectors, protocols = chosen["detector"], chosen["protocol"]
    runs = []
    for dn, det in detectors.items():
        for kind, (pn, pro) in product(readable(dn, det, bench.input, echo), protocols.items()):
            for r in range(bench.repeats):
                run = Run(det, pro, bench.split, bench.seed + r, bench.labels, input=kind)
                try:
                    run.validate()
                except SlipbenchError as exc:
                    table, key = (f"detectors.{dn}", _param_in(str(exc), bench.detectors[dn]))
                    if key is None:
                        table, key = f"protocols.{pn}", _param_in(str(exc), bench.protocols[pn])
                    raise _fail(bench.path, bench.text, str(exc), table, key) from None
                runs.append(run)
    if not runs:
        raise _fail(
            bench.path,
            bench.text,
            f"no detector it declares reads the {bench.input} input (see `slipbench list`)",
            "run",
            "input",
        )
    if check_gate:
        gate_decides(bench, runs, echo)
    return runs


def gate_decides(bench: Benchmark, runs: list, echo=print) -> None:
    """Refuse (exit 2, at the ``[gate]`` key) a tolerance the bench cannot decide at its
    budget, by the calibration beside it where that holds; say which detectors it no longer
    holds for. Without a calibration nothing is known of the noise, and nothing is refused."""
    from slipbench.app.calibrate import status
    from slipbench.app.gateplan import plan_gate, refusal

    found = status(bench, runs)
    if found.calibration is None:
        return
    for line in found.lines():
        echo(line)
    refused = refusal(plan_gate(bench, runs, found), bench)
    if refused is not None:
        raise _fail(bench.path, bench.text, refused[1], "gate", refused[0])


def _param_in(message: str, params: dict) -> str | None:
    """The parameter a validation message names ("The 'keep' parameter of ..."), if given here."""
    m = re.search(r"The '([^']+)' (?:parameter|option)", message)
    return m[1] if m and m[1] in params else None


def with_overrides(bench: Benchmark, **overrides) -> Benchmark:
    """``bench`` with the fields a command line gives (``out``, ``jobs``, ``seed``); a None
    keeps the file's value. ``seed`` also seeds the simulated data unless ``[dataset]`` gives
    its own."""
    return dataclasses.replace(bench, **{k: v for k, v in overrides.items() if v is not None})


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


def slurm_of(bench: Benchmark):
    """The resources of the file's SLURM run (``[slurm]``, folder relative to the file), or
    None where it runs elsewhere."""
    from dataclasses import replace

    from slipbench.engine.limits import SCHEDULERS
    from slipbench.engine.slurm import resources

    if bench.scheduler not in SCHEDULERS:
        return None
    res = resources(bench.slurm, tuple(bench.detectors))
    if res.folder:
        res = replace(res, folder=str(bench.path.resolve().parent / res.folder))
    return res


def record(bench: Benchmark, out: Path, runs: list | None = None) -> None:
    """Keep the file's text with the results: ``benchmark.toml`` (a copy) and ``benchmark.json``
    (its SHA-256, where it came from, when it ran and, with ``runs``, what a calibration of the
    file is checked against: its settings' digest and each detector's parameters and own code
    as this run had them, so that a comparison made with other code can tell whether the
    calibration holds for these rows)."""
    from slipbench.atomic import make_folder, write_text_atomic

    make_folder(out)
    write_text_atomic(out / BENCHMARK_FILE, bench.text)
    write_text_atomic(
        out / RECORD_FILE,
        json.dumps(
            {
                "sha256": bench.sha256,
                "file": str(bench.path),
                "name": bench.name,
                "seed": bench.seed,
                "started_at": datetime.now(timezone.utc).isoformat(),
                **({"calibration_key": _calibration_key(bench, runs)} if runs else {}),
            },
            indent=2,
        )
        + "\n",
    )


def _calibration_key(bench: Benchmark, runs: list) -> dict:
    from slipbench.app.calibrate import detector_identities, digest, settings

    return {
        "settings_digest": digest(settings(bench, runs)),
        "detectors": {
            name: {"params": params, "own_code": code}
            for name, (params, code) in detector_identities(runs).items()
        },
    }


def bench_dataset(bench: Benchmark, echo=print):
    """The dataset the file declares: its folder (:func:`read_data`), or the simulated one at
    its scale and seed (the run's seed where ``[dataset]`` gives none)."""
    from slipbench.data.defaults import default_dataset

    if bench.dataset is not None:
        return read_data(bench, echo)
    data_seed = bench.seed if bench.data_seed is None else bench.data_seed
    return default_dataset(bench.scale, data_seed, echo=echo)


def run_benchmark(bench: Benchmark, force: bool = False, progress: bool = True, echo=print):
    """Run what ``bench`` declares and write its reports into ``bench.out``.

    A command line's overrides (``--out``, ``--jobs``, ``--seed``) are applied to ``bench``
    before (``with_overrides``); the seed is recorded in ``benchmark.json``.

    Returns
    -------
    (rows, paths): the result rows of the declared runs, and the report and figure files written.
    """
    from slipbench.app.selection import recorded_plugins
    from slipbench.engine.limits import cell_limit, limit_words
    from slipbench.engine.runner import evaluate
    from slipbench.report.document import build_report, render, write_figures
    from slipbench.report.render import renderer
    from slipbench.store.results import ResultsStore

    out = bench.out
    runs = plan_runs(
        bench, echo
    )  # every name and parameter before the dataset is read or simulated
    ds = bench_dataset(bench, echo)
    record(bench, out, runs)
    echo(limit_words(bench.cell_timeout, bench.jobs, bench.scheduler))
    rows = evaluate(
        ds,
        runs,
        ResultsStore(out),
        force=force,
        jobs=bench.jobs,
        scheduler=bench.scheduler,
        cell_timeout=cell_limit(bench.cell_timeout, bench.jobs, bench.scheduler),
        progress=progress,
        slurm=slurm_of(bench),
    )
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
    from slipbench.atomic import write_text_atomic

    for fmt in bench.report:
        path = out / f"report.{renderer(fmt).suffix}"
        write_text_atomic(path, render(blocks, fmt, standalone=True, files=files, link_from=out))
        paths.append(path)
    return rows, paths
