"""Who judges a comparison: the base. ``compare`` takes its gate (figures, tolerances, seeds'
budget, detectors and protocols) from the bench file BASE's run recorded (``benchmark.toml``,
proved by the SHA-256 its ``benchmark.json`` holds), never from the candidate's, and says in
the comment's first line where the candidate's bench differs: a pull request cannot widen its
own tolerances, drop a figure from ``[gate]`` or a detector from the bench and pass.

A detector, protocol or cell the base's bench ran and BASE finished that CANDIDATE holds no row
of is *missing*: lost work, which fails the gate as a cell the candidate no longer finishes does.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd
import tomllib

from slipbench.app.benchfile import BENCHMARK_FILE, RECORD_FILE
from slipbench.app.benchspec import Benchmark, load_benchmark
from slipbench.errors import DataError, UsageError
from slipbench.gate.gate import DEFAULT_TOLERANCE
from slipbench.store.columns import ENTRANT_CELL, FIGURES
from slipbench.store.results import results_folder

#: keys of a bench that change how it runs, not what it measures: never a difference
RUNNING = {"run": {"jobs", "scheduler", "plugins"}}


@dataclass(frozen=True)
class Judge:
    """What a comparison is judged by: ``bench``, the base's bench (None where BASE holds no
    record and no ``--bench`` was given), ``recorded`` whether BASE's record proved it, and
    ``calibration_bench`` the bench file whose calibration may give the noise (``--bench``,
    checked to be the base's); ``headline``: what the comment's first line says of it."""

    bench: Benchmark | None
    recorded: bool
    calibration_bench: Path | None
    headline: list[str] = field(default_factory=list)


def recorded_bench(path: Path, side: str) -> Benchmark | None:
    """The bench file a results folder's run recorded (``benchmark.toml``), proved by the
    SHA-256 in its ``benchmark.json``; None where the folder holds no copy (``evaluate``'s,
    or an older slipbench's). A copy that does not match its record is a DataError (exit 2)."""
    folder = results_folder(path)
    copy, record = folder / BENCHMARK_FILE, folder / RECORD_FILE
    if not copy.is_file():
        return None
    try:
        written = json.loads(record.read_text(encoding="utf-8")).get("sha256")
    except FileNotFoundError:
        raise DataError(
            f"{side} {record}: missing beside {BENCHMARK_FILE}, so the bench {side} ran cannot "
            "be proved; run the bench into a fresh folder"
        ) from None
    except (ValueError, AttributeError, UnicodeDecodeError) as exc:
        raise DataError(f"{side} {record}: not a benchmark run's record ({exc})") from None
    actual = hashlib.sha256(copy.read_bytes()).hexdigest()
    if written != actual:
        raise DataError(
            f"{side} {copy}: its SHA-256 {actual[:16]} is not the {str(written)[:16]} its "
            f"{RECORD_FILE} records: the bench {side} ran cannot be proved; run the bench "
            "into a fresh folder"
        )
    return load_benchmark(copy, here=False)


def judge(base: Path, candidate: Path, bench: Path | None) -> Judge:
    """The base's bench as BASE recorded it; ``bench`` (``--bench``), where given, must be the
    same file (the same SHA-256): it names where the calibration is. Without a record in BASE,
    ``bench`` is the gate as given, and the first line says it could not be checked."""
    mine = recorded_bench(base, "BASE")
    given = load_benchmark(bench, here=False) if bench is not None else None
    if mine is not None and given is not None and given.sha256 != mine.sha256:
        raise UsageError(
            f"--bench {bench}: not the bench BASE ran (SHA-256 {given.sha256[:16]}, BASE's "
            f"{BENCHMARK_FILE} {mine.sha256[:16]}): pass the base's own bench file, whose "
            "calibration is beside it"
        )
    theirs = recorded_bench(candidate, "CANDIDATE")
    head = []
    if mine is None and given is not None:
        head.append(
            f"BASE holds no record of the bench it ran ({BENCHMARK_FILE}): the gate is "
            f"{given.path.name}'s as given, unchecked."
        )
    judged = mine or given
    if judged is not None and theirs is not None:
        changes = bench_changes(judged, theirs)
        if changes:
            head.append(
                "The candidate's bench differs from the base's, judged by the base's: "
                + "; ".join(changes)
                + "."
            )
    return Judge(judged, mine is not None, bench if given is not None else None, head)


def _gate_of(bench: Benchmark) -> dict[str, float]:
    return dict(bench.gate) if bench.gate else dict(DEFAULT_TOLERANCE)


def _called(figures: Iterable[str]) -> str:
    return ", ".join(FIGURES[f].called if f in FIGURES else f for f in figures)


def bench_changes(base: Benchmark, cand: Benchmark) -> list[str]:
    """Where the candidate's bench differs from the base's in what it measures or judges,
    each old → new: the gate's tolerances, figures and budget, the detectors and protocols
    (removed, added, parameters), the run's and dataset's settings."""
    old, new = _gate_of(base), _gate_of(cand)
    out = [
        f"tolerance {_called([f])} {old[f]:g} → {new[f]:g}"
        for f in old
        if f in new and new[f] != old[f]
    ]
    dropped = [f for f in old if f not in new]
    if dropped:
        out.append(f"{_called(dropped)} dropped from [gate]")
    added = [f for f in new if f not in old]
    if added:
        out.append(f"{_called(added)} added to [gate]")
    if base.seeds_budget != cand.seeds_budget:
        out.append(f"budget {base.seeds_budget} → {cand.seeds_budget}")
    b, c = tomllib.loads(base.text), tomllib.loads(cand.text)
    for kind in ("detectors", "protocols"):
        out += _plugins(kind, b.get(kind, {}), c.get(kind, {}))
    for table in ("run", "dataset"):
        out += _settings(table, b.get(table, {}), c.get(table, {}))
    return out


def _plugins(kind: str, old: dict, new: dict) -> list[str]:
    one = kind.rstrip("s")
    out = [f"{one} {name} removed" for name in old if name not in new]
    for name in old:
        if name in new and new[name] != old[name]:
            out += [f"{one} {name}: {s}" for s in _values(old[name], new[name])]
    out += [
        f"{one} {name} added (the base's bench does not run it)" for name in new if name not in old
    ]
    return out


def _settings(table: str, old: dict, new: dict) -> list[str]:
    skip = RUNNING.get(table, set())
    return [f"{table}.{s}" for s in _values(old, new, skip) if s]


def _values(old: dict, new: dict, skip: Iterable[str] = ()) -> list[str]:
    """Each key whose value differs, ``key old → new`` (``(none)`` where one side lacks it)."""
    keys = [k for k in dict.fromkeys([*old, *new]) if k not in set(skip)]
    return [
        f"{k} {_text(old.get(k))} → {_text(new.get(k))}" for k in keys if old.get(k) != new.get(k)
    ]


def _text(value: Any) -> str:
    return "(none)" if value is None else json.dumps(value) if not isinstance(value, str) else value


def missing(only_base: pd.DataFrame, bench: Benchmark) -> list[str]:
    """What BASE finished under its bench that CANDIDATE holds no row of (``only_base``, the
    cells of BASE only with their status): whole detectors and protocols by name, else the
    cells counted. Cells the base did not finish are no lost work."""
    if only_base.empty:
        return []
    lost = only_base[only_base["status"] == "ok"] if "status" in only_base else only_base
    lost = lost[lost["detector"].isin(bench.detectors) & lost["protocol"].isin(bench.protocols)]
    if lost.empty:
        return []
    out = []
    cells = lost.drop_duplicates(list(ENTRANT_CELL))
    for (detector, protocol), part in cells.groupby(["detector", "protocol"], sort=False):
        out.append(
            f"{len(part)} cell{'s' * (len(part) != 1)} of {detector} on {protocol} the base finished"
        )
    return out
