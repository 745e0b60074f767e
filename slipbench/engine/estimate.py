"""What a run will cost, said before its first cell: per detector, the cells cached and to run,
and the time they should take from the cells of that detector already measured in the store."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from slipbench.engine.plan import Plan


@dataclass
class Cost:
    """One detector's share of a run: cells cached, skipped (they cannot run on this data) and
    to run, models to fit, and the median seconds of a fit and of a cell's test measured in
    earlier rows (None: none)."""

    cached: int = 0
    skipped: int = 0
    to_run: int = 0
    models: int = 0
    fit_s: float | None = None
    test_s: float | None = None
    measured: int = 0

    @property
    def seconds(self) -> float | None:
        if self.fit_s is None or self.test_s is None:
            return None
        return self.models * self.fit_s + self.to_run * self.test_s


def costs(plan: Plan, done: set[str], stored: dict[str, dict]) -> dict[str, Cost]:
    """Per detector of ``plan``, its :class:`Cost`: ``done`` the keys of cached cells,
    ``stored`` the store's finished rows (any run) the medians come from."""
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
    for name, cost in out.items():
        fits, tests = _measured(row for row in stored.values() if row.get("detector") == name)
        cost.measured = len(fits)
        if fits:
            cost.fit_s, cost.test_s = float(np.median(fits)), float(np.median(tests))
    return out


def _measured(rows: Iterable[dict]) -> tuple[list[float], list[float]]:
    """Fit seconds and test seconds (windows times microseconds per window) of measured rows."""
    fits, tests = [], []
    for row in rows:
        fit, per_window, n = row.get("train_s"), row.get("infer_us_per_window"), row.get("n_test")
        if row.get("status") == "ok" and _number(fit) and _number(per_window) and _number(n):
            fits.append(float(fit))  # type: ignore[arg-type]
            tests.append(float(per_window) * float(n) / 1e6)  # type: ignore[arg-type]
    return fits, tests


def _number(value: object) -> bool:
    return isinstance(value, (int, float)) and bool(np.isfinite(value))


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
            lines.append(
                f"{head}; about {duration(c.seconds)} of work (median {c.fit_s:.3g} s a fit, "
                f"{c.test_s:.3g} s a test, from {c.measured} measured cells)"
            )
    cached, to_run = sum(c.cached for c in costs.values()), sum(c.to_run for c in costs.values())
    known = [c.seconds for c in costs.values() if c.to_run and c.seconds is not None]
    unknown = [n for n, c in costs.items() if c.to_run and c.seconds is None]
    total = f"total: {cached} cells cached, {to_run} to run"
    if known:
        workers = max(jobs, 1)
        total += f"; about {duration(sum(known) / workers)} with {workers} worker(s)"
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
