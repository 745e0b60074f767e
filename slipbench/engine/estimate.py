"""What a run will cost, said before its first cell: per detector, the cells cached and to run,
and the seconds each model to run should take, from the measured rows of that detector
(any run, any scale, this store's or another's).

A model's cost is its training windows' samples x the detector's measured microseconds per
training sample, plus scoring its own training windows, plus each of its cells' test (windows x
the measured seconds per test window, scoring, figures and intervals together) or stream
(recordings x the measured seconds per streamed recording). Each rate is a ratio of sums over
the measured rows, so it weighs rows by their size as the total does; rows of the detector
with the same parameters and input are used where there are any, else the detector's rows of
any parameters (said so). Planned windows come from the plan itself, so a run at another scale
or on another dataset is charged for its own windows.
"""

from __future__ import annotations

import heapq
import json
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from slipbench.engine.plan import Batch, Plan, PlannedCell, Task


@dataclass(frozen=True)
class Rates:
    """A detector's measured costs: microseconds per training sample of a fit, per window
    scored, per test window (scored, with figures and intervals); seconds per streamed test
    recording (None: no streaming cell measured); and the measured rows behind them."""

    fit_us_per_sample: float
    score_us_per_window: float
    test_us_per_window: float
    stream_s_per_recording: float | None
    rows: int
    alike: bool = True  # measured with the same parameters and input

    def model_seconds(self, task: Task) -> float | None:
        """A model's estimated seconds: fit, scoring its training windows, its cells' tests."""
        first = task.first
        n_train = len(first.windows("train"))
        seconds = (
            n_train * (self.fit_us_per_sample * _length(first) + self.score_us_per_window) / 1e6
        )
        for pc in task.cells:
            if pc.streams is not None:
                if self.stream_s_per_recording is None:
                    return None
                seconds += self.stream_s_per_recording * len(pc.streams["test"])
            else:
                seconds += self.test_us_per_window * len(pc.windows("test")) / 1e6
        return seconds


def _length(pc: PlannedCell) -> int:
    """Samples of one of the cell's windows as the model sees them (after downsampling)."""
    return max(pc.cell.window // max(pc.cell.downsample, 1), 1)


def _number(value: object) -> bool:
    return (
        isinstance(value, (int, float)) and not isinstance(value, bool) and bool(np.isfinite(value))
    )


def rates(rows: Iterable[dict]) -> dict[tuple[str, str, str], Rates]:
    """Measured rates per (detector, parameters as JSON, input) from finished rows; the key
    (detector, "", "") holds the detector's rates over any parameters and input."""
    sums: dict[tuple[str, str, str], np.ndarray] = {}
    fitted: set[tuple[tuple[str, str, str], str]] = set()
    for row in rows:
        if row.get("status") != "ok":
            continue
        exact = (str(row.get("detector")), str(row.get("detector_params")), str(row.get("input")))
        for key in (exact, (exact[0], "", "")):
            acc = sums.setdefault(key, np.zeros(9))
            _add(acc, row, (key, str(row.get("model_key"))) not in fitted)
            fitted.add((key, str(row.get("model_key"))))
    out = {}
    for key, s in sums.items():
        fit_us, samples, score_us, scored, test_s, tested, stream_s, streamed, n = s
        if samples and scored:
            out[key] = Rates(
                fit_us / samples,
                score_us / scored,
                test_s * 1e6 / tested if tested else score_us / scored,
                stream_s / streamed if streamed else None,
                int(n),
                alike=bool(key[1]),
            )
    return out


def _add(acc: np.ndarray, row: dict, new_model: bool) -> None:
    """Add one row's measured seconds and sizes to ``acc`` (its fit once per model)."""
    acc[8] += 1
    train_s, n_train, window = row.get("train_s"), row.get("n_train"), row.get("window")
    if new_model and _number(train_s) and _number(n_train) and _number(window):
        length = max(int(window) // max(int(row.get("downsample") or 1), 1), 1)  # type: ignore[arg-type]
        acc[0] += float(train_s) * 1e6  # type: ignore[arg-type]
        acc[1] += float(n_train) * length  # type: ignore[arg-type]
    per_window, n_test = row.get("infer_us_per_window"), row.get("n_test")
    if _number(per_window) and _number(n_test):
        acc[2] += float(per_window) * float(n_test)  # type: ignore[arg-type]
        acc[3] += float(n_test)  # type: ignore[arg-type]
        if _number(row.get("test_s")):
            acc[4] += float(row["test_s"])
            acc[5] += float(n_test)  # type: ignore[arg-type]
    stream_s, recordings = row.get("stream_s"), row.get("n_test_recordings")
    if _number(stream_s) and _number(recordings) and recordings:
        acc[6] += float(stream_s)  # type: ignore[arg-type]
        acc[7] += float(recordings)


def rates_of(measured: dict[tuple[str, str, str], Rates], pc: PlannedCell) -> Rates | None:
    """The rates of a cell's detector: its own parameters' and input's, else any of its."""
    run = pc.run
    params = json.dumps(_plain(run.detector.get_params()), sort_keys=True)
    return measured.get((run.detector_name, params, run.input)) or measured.get(
        (run.detector_name, "", "")
    )


def _plain(params: dict) -> object:
    from slipbench.store.keys import canonical

    return canonical(params)


@dataclass
class Cost:
    """One detector's share of a run: cells cached, skipped (they cannot run on this data) and
    to run, models to fit, each model's estimated seconds (None: nothing measured to go by),
    the measured rows behind them and whether they had the same parameters."""

    cached: int = 0
    skipped: int = 0
    to_run: int = 0
    models: int = 0
    model_s: list[float] = field(default_factory=list)
    measured: int = 0
    alike: bool = True
    unknown: int = 0  # models to run that nothing measured prices (a kind of cell never run)

    @property
    def seconds(self) -> float | None:
        """The estimated models' seconds; None where none is estimated."""
        return float(sum(self.model_s)) if self.model_s or not self.unknown else None


def costs(plan: Plan, done: set[str], stored: dict[str, dict]) -> dict[str, Cost]:
    """Per detector of ``plan``, its :class:`Cost`: ``done`` the keys of cached cells,
    ``stored`` the measured rows (any run) the rates come from."""
    measured = rates(stored.values())
    out: dict[str, Cost] = {}
    for pc in plan.cells:
        cost = out.setdefault(pc.run.detector_name, Cost())
        if pc.key in done:
            cost.cached += 1
        else:
            cost.skipped += 1  # unless a task holds it, below
    for task in plan.tasks:
        cost = out[task.first.run.detector_name]
        cost.models += 1
        cost.to_run += len(task.cells)
        cost.skipped -= len(task.cells)
        found = rates_of(measured, task.first)
        seconds = None if found is None else found.model_seconds(task)
        if seconds is None:
            cost.unknown += 1
        else:
            cost.model_s.append(seconds)
            cost.measured, cost.alike = found.rows, cost.alike and found.alike  # type: ignore[union-attr]
    return out


def task_seconds(plan: Plan, stored: dict[str, dict], tasks: list[Task | Batch]) -> list[float]:
    """Each task's (a model's, or a lockstep batch's) estimated seconds; NaN where unknown."""
    measured = rates(stored.values())
    out = []
    for task in tasks:
        total = 0.0
        for t in task.tasks if isinstance(task, Batch) else [task]:
            found = rates_of(measured, t.first)
            seconds = None if found is None else found.model_seconds(t)
            total += np.nan if seconds is None else seconds
        out.append(total)
    return out


def makespan(seconds: list[float], workers: int) -> float:
    """The last to finish when ``seconds`` of work go longest first onto the least loaded of
    ``workers`` (within 4/3 of the best schedule)."""
    loads = [0.0] * max(workers, 1)
    for s in sorted(seconds, reverse=True):
        heapq.heapreplace(loads, loads[0] + s)
    return max(loads)


def describe(costs: dict[str, Cost], jobs: int) -> list[str]:
    """The lines a run prints before its first cell: one per detector and the total."""
    lines = []
    for name, c in costs.items():
        skipped = f", {c.skipped} skipped" if c.skipped else ""
        head = f"{name}: {c.cached} cells cached{skipped}, {c.to_run} to run ({c.models} models)"
        if not c.to_run:
            lines.append(head)
        elif c.seconds is None:
            lines.append(f"{head}; no estimate yet (no measured cell of {name} in this store)")
        else:
            other = "" if c.alike else " of other parameters"
            partly = f"; {c.unknown} models with cells of a kind never measured" * bool(c.unknown)
            lines.append(
                f"{head}; about {duration(c.seconds)} of work (from {c.measured} measured "
                f"cells{other}{partly})"
            )
    cached, to_run = sum(c.cached for c in costs.values()), sum(c.to_run for c in costs.values())
    known = [s for c in costs.values() if c.to_run and c.model_s for s in c.model_s]
    unknown = [n for n, c in costs.items() if c.to_run and c.seconds is None]
    total = f"total: {cached} cells cached, {to_run} to run"
    if known:
        workers = max(jobs, 1)
        total += f"; about {duration(makespan(known, workers))} with {workers} worker(s)"
        if unknown:
            total += f", plus {', '.join(unknown)} (no estimate yet)"
    elif to_run:
        total += "; no estimate yet"
    return [*lines, total]


def duration(seconds: float) -> str:
    """``45 s``, ``12 min``, ``3.5 h``: what a user plans by."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"
