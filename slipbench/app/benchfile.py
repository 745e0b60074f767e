"""Running a benchmark file (:mod:`slipbench.app.benchspec`, its parsed form): its runs planned
with every plugin and parameter checked, its dataset, its record in the results folder and its
reports. The file's text is copied into the results folder (``benchmark.toml``) and its SHA-256
written beside it (``benchmark.json``), so results say which declaration made them.

Where the file has a calibration (``slipbench calibrate``: ``bench.calibration.json`` beside
it, or the file ``[benchmark] calibration`` names) that holds for its settings and detectors, a ``[gate]`` tolerance the bench cannot
decide even at its budget is refused when its runs are planned (:func:`plan_runs`), with the
budget, tolerance or scale that would decide it (:mod:`slipbench.app.gateplan`).
"""

from __future__ import annotations

import json
import re
from datetime import datetime, timezone
from itertools import product
from pathlib import Path

from slipbench.app.benchside import bench_dataset, write_reports
from slipbench.app.benchspec import Benchmark, bench_error
from slipbench.errors import PluginError, SlipbenchError

BENCHMARK_FILE = "benchmark.toml"
RECORD_FILE = "benchmark.json"


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
            raise bench_error(
                bench.path, bench.text, f"plugin folder {folder} does not exist", "run", "plugins"
            )
        registry.add_plugin_folder(folder)

    def made(kind: str, reg, name: str, params: dict):
        try:
            return reg.get(name)(**params)
        except TypeError:
            plugin = reg.get(name)()
            unknown = [k for k in params if k not in plugin.get_params()]
            raise bench_error(
                bench.path,
                bench.text,
                f"{kind} {name!r} has no parameter {unknown[0] if unknown else '?'}; its "
                f"parameters: {', '.join(plugin.get_params()) or 'none'}",
                f"{kind}s.{name}",
                unknown[0] if unknown else None,
            ) from None
        except SlipbenchError as exc:
            raise bench_error(
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
                    raise bench_error(bench.path, bench.text, str(exc), table, key) from None
                runs.append(run)
    if not runs:
        raise bench_error(
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
        raise bench_error(bench.path, bench.text, refused[1], "gate", refused[0])


def _param_in(message: str, params: dict) -> str | None:
    """The parameter a validation message names ("The 'keep' parameter of ..."), if given here."""
    m = re.search(r"The '([^']+)' (?:parameter|option)", message)
    return m[1] if m and m[1] in params else None


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


def run_benchmark(bench: Benchmark, force: bool = False, progress: bool = True, echo=print):
    """Run what ``bench`` declares and write its reports into ``bench.out``.

    A command line's overrides (``--out``, ``--jobs``, ``--seed``) are applied to ``bench``
    before (``with_overrides``); the seed is recorded in ``benchmark.json``.

    Returns
    -------
    (rows, paths): the result rows of the declared runs, and the report and figure files written.
    """
    from slipbench.engine.limits import cell_limit, limit_words
    from slipbench.engine.runner import evaluate
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
    return rows, write_reports(bench, rows, out)
