"""How long is the path a report's rows take through the code? Counted, not timed: a profiler
(:func:`sys.setprofile`) follows one ``build_report`` of a small results frame (every built-in
protocol with lstm, window-size with holweg at two parameter sets and tcn on the raw channels,
two label rules, the sampling rate with three seeds) with findings and intervals, and counts

- ``functions``: the distinct slipbench functions called;
- ``calls``: the calls into slipbench functions;
- ``derivations``: the calls into what names and tells rows apart (``stats/factors.py``,
  ``store/columns.py``, ``store/resolved.py``; the stand-ins, units as tested and simulation
  flags of ``report/outline.py`` and ``report/provenance.py``): a count that falls as fewer
  steps derive again what one resolved reader computed once;
- ``stays`` and ``returns``: the walk from module to module (one stay: calls in one module
  without leaving it; a return: a stay in a module the walk had already left).

    python benchmarks/report_path.py

(before and after issue 56: benchmarks/results/report_path.md). The figures depend on the code alone (the frame is made, not read), so one run is the figure.
"""

from __future__ import annotations

import sys
from collections import Counter
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]  # this checkout's slipbench, its test rows

from resultgen import all_rows, fake_rows  # noqa: E402

PACKAGE = str(ROOT / "slipbench")
DERIVING = {
    "stats/factors.py": None,  # every function
    "store/columns.py": None,
    "store/resolved.py": None,
    "report/outline.py": {"stand_ins", "as_tested"},
    "report/provenance.py": {"on_simulation"},
}


def frame() -> pd.DataFrame:
    """The rows reported: every protocol, several entrants and two settings."""
    holweg = fake_rows("window-size", "holweg")
    banded = holweg.assign(detector_params='{"band": [39, 100]}', key=holweg["key"] + "b")
    tcn = fake_rows("window-size", "tcn").assign(input="channels")
    majority = fake_rows("window-size").assign(labels="majority", key=lambda f: f["key"] + "m")
    rows = pd.concat(
        [all_rows(), banded, tcn, majority.assign(detector_params="{}")], ignore_index=True
    )
    return rows.assign(labels=rows["labels"].fillna("any") if "labels" in rows else "any")


def walk(rows: pd.DataFrame) -> dict[str, int]:
    """The counts of one ``build_report(rows)`` (see the module's text)."""
    from slipbench.report.document import build_report

    calls: Counter[tuple[str, str]] = Counter()
    seen: set[str] = set()
    path: list[str] = []

    def module(code) -> str | None:
        name = code.co_filename
        return name[len(PACKAGE) + 1 :] if name.startswith(PACKAGE) else None

    def enter(where: str | None) -> None:
        if where is not None and (not path or path[-1] != where):
            path.append(where)

    def profile(frame, event, _arg) -> None:
        if event == "call":
            where = module(frame.f_code)
            if where is not None:
                calls[(where, frame.f_code.co_qualname)] += 1
                seen.add(where)
            enter(where)
        elif event == "return" and frame.f_back is not None:
            enter(module(frame.f_back.f_code))

    sys.setprofile(profile)
    try:
        build_report(rows, paper=True, intervals=True)
    finally:
        sys.setprofile(None)
    left: set[str] = set()
    returns = 0
    for before, now in zip(path, path[1:]):
        left.add(before)
        returns += now in left
    deriving = sum(
        n
        for (where, name), n in calls.items()
        if where in DERIVING and (DERIVING[where] is None or name in DERIVING[where])
    )
    moves = Counter(zip(path, path[1:]))
    print(
        "most frequent moves:", ", ".join(f"{a} -> {b} {n}" for (a, b), n in moves.most_common(6))
    )
    return {
        "functions": len(calls),
        "calls": sum(calls.values()),
        "derivations": deriving,
        "stays": len(path),
        "returns": returns,
    }


def main() -> None:
    rows = frame()
    print(f"build_report of {len(rows)} rows")
    for name, value in walk(rows).items():
        print(f"{name:12} {value}")


if __name__ == "__main__":
    main()
