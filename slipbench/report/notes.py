"""What a table says under it of the data behind it: figures on the simulation, units tested
as another dataset's, test sets of one class, and what its intervals are over seeds."""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import pandas as pd

from slipbench.stats.joint import JOINT_NOTE
from slipbench.store.columns import ENTRANT_CELL
from slipbench.vocabulary import label

#: a column the report sets on its rows: the test data is slipbench's simulation
SIMULATED = "_on_simulation"
#: a column the report sets on rows tested on another dataset's unit: the training unit's name
TRAINED_AS = "_trained_as"
SIMULATION_NOTE = (
    "Channels on simulated data of model version 3 or earlier: there, the force's direction alone "
    "separates slip (tangential load) from pressing (a mostly normal load; docs/explanation/simulation.md), so "
    "these channels figures measure the simulation, not what a sensor can tell."
)
# What a table's intervals are. A figure run under several seeds (--repeats) is their mean; its
# interval is the two-level bootstrap over test trials and seeds where the seeds' predictions are
# at hand (slipbench.stats.joint), else an interval from the seeds' rows, both with retraining
# noise inside (slipbench.stats.metrics.seeds_from_rows)
INTERVAL_NOTE = "[95 % interval: cluster bootstrap over test trials, stratified by class.]"
POOLED_TEXT = (
    "its interval a two-level bootstrap over test trials and seeds (each resample draws the test "
    "trials once for every seed, and draws the seeds), so retraining noise is inside it"
)
ROWS_TEXT = (
    "its interval from the seeds' rows (their mean standard error at the normal quantile and the "
    "spread of their figures over seeds at t's, combined as Banerjee's: retraining noise inside; "
    "keep predictions for the two-level bootstrap)"
)


def simulation_note(rows: pd.DataFrame) -> list[str]:
    """:data:`SIMULATION_NOTE` where ``rows`` hold channels cells the report marked as tested
    on the simulation (:data:`SIMULATED`)."""
    if SIMULATED not in rows or "input" not in rows:
        return []
    marked = rows[SIMULATED].fillna(False).astype(bool) & rows["input"].eq("channels")
    return [SIMULATION_NOTE] if marked.any() else []


def data_notes(rows: pd.DataFrame) -> list[str]:
    """What a table must say of the data behind its ``rows``: that channels cells on the
    simulation measure the simulation (rows the report marked :data:`SIMULATED`), and that rows
    tested on another dataset name the unit tested (:data:`TRAINED_AS`), and what a constant
    detector scores where cells test on one class only."""
    notes = one_class_note(rows) + simulation_note(rows)
    if TRAINED_AS in rows and rows[TRAINED_AS].notna().any():
        notes.append(
            "Trained on one dataset, tested on another: each row names the unit tested (the test "
            "dataset's), and in parentheses the training dataset's unit it was tested as (the sensor map)."
        )
    return notes


def one_class_note(rows: pd.DataFrame) -> list[str]:
    """Where cells test on one class only: what a detector that always says "slip" scores
    there (the rows' ``constant_slip_accuracy``), so a figure near 100 % reads as what it is."""
    if "constant_slip_accuracy" not in rows:
        return []
    ok = rows[rows["status"].eq("ok")] if "status" in rows else rows
    constant = pd.to_numeric(ok["constant_slip_accuracy"], errors="coerce").dropna()
    if constant.empty:
        return []
    scores = " or ".join(f"{100 * v:.0f} %" for v in sorted(constant.unique(), reverse=True))
    return [
        f"{len(constant)} of {len(ok)} finished cells test on one class only: there a constant "
        f'"slip" detector scores {scores} (column constant_slip_accuracy), and a figure near it '
        "says the detector calls that class, not that it tells slip from non-slip; no leaderboard "
        "ranks them."
    ]


def whole_range(values: Iterable[float]) -> str:
    """``3`` or ``2-3``: the range of whole numbers."""
    v = sorted({int(x) for x in values})
    return f"{v[0]}" if v[0] == v[-1] else f"{v[0]}-{v[-1]}"


def trials_text(counts: pd.DataFrame) -> str:
    """ "10-20 slip and 12-30 non-slip test trials" from ``n_test_clusters_slip``/``_nonslip``
    columns, or "" where they are not known."""
    cols = ["n_test_clusters_slip", "n_test_clusters_nonslip"]
    if not set(cols) <= set(counts) or counts[cols].isna().all().any():
        return ""
    slip, nonslip = (pd.to_numeric(counts[c], errors="coerce").dropna() for c in cols)
    return f"{whole_range(slip)} slip and {whole_range(nonslip)} non-slip test trials"


def seeds_notes(
    repeated: dict[tuple, int],
    pooled: dict[tuple, dict],
    intervals: bool,
    rows: pd.DataFrame,
    keys: list[str],
) -> list[str]:
    """What a table says of its figures run under several seeds (``repeated``: key -> seeds):
    without intervals, that they are means ± standard deviations; with intervals, what each
    interval is: the two-level bootstrap where ``pooled`` has the figure, the interval from the
    seeds' rows elsewhere (the note counts each kind), with the seeds and test trials behind them."""
    if not intervals:
        return ["Mean ± standard deviation across seeds."] if repeated else []
    if not repeated:
        return [INTERVAL_NOTE]
    at_hand = [k for k in repeated if k in pooled]
    rest = [k for k in repeated if k not in pooled]
    if at_hand:
        trials = trials_text(pd.DataFrame([pooled[k] for k in at_hand]))
    else:
        ok = rows[rows["status"].eq("ok")] if "status" in rows else rows
        per_seed = trials_text(ok[[tuple(v) in repeated for v in ok[keys].itertuples(index=False)]])
        trials = per_seed and f"{per_seed} per seed"
    head = (
        "[95 % interval: cluster bootstrap over test trials, stratified by class; a figure run under "
        f"{whole_range(repeated.values())} seeds{f' ({trials})' if trials else ''} is their mean, "
    )
    if not rest:
        return [f"{head}{POOLED_TEXT}.]"]
    if not at_hand:
        return [f"{head}{ROWS_TEXT}.]"]
    return [
        f"{head}{POOLED_TEXT}; for the {len(rest)} of the {len(repeated)} such figures whose "
        f"predictions are missing or unreadable, {ROWS_TEXT}.]"
    ]


def interval_note(
    joint: dict | None, intervals: bool, shown: Sequence[tuple], seeds: bool = False
) -> list[str]:
    """What the intervals of the ``shown`` averages (``(detector, sensor_type)`` keys) are: the
    joint bootstrap where ``joint`` has the group, the combined half-widths elsewhere; with
    ``seeds`` (the rows hold several seeds of a cell), how the seeds enter each."""
    if not intervals:
        return []
    independent = (
        "the fingers' half-widths combined as independent, which understates it where they share "
        "trials; keep predictions for a joint bootstrap"
    )
    joint_text = JOINT_NOTE
    if seeds:
        joint_text += (
            "; over several seeds, each seed's mean over fingers averaged over the seeds, the seeds "
            "drawn too, so retraining noise is inside it"
        )
        independent += "; each finger's interval over its seeds from the seeds' rows"
    fallback = [k for k in shown if k not in (joint or {})]
    if joint and not fallback:
        return [f"[95 % interval: {joint_text}.]"]
    if not joint or len(fallback) == len(shown):
        return [f"[95 % interval: {independent}.]"]
    which = ", ".join(f"{label('sensor_type', s)} ({d})" for d, s in fallback)
    return [
        f"[95 % interval: {joint_text}; for {which}, whose predictions are missing or unreadable, "
        f"{independent}.]"
    ]


def any_repeated(rows: pd.DataFrame) -> bool:
    """Some cell of ``rows`` ran under several seeds."""
    if "seed" not in rows or "cell" not in rows:
        return False
    by = [c for c in ENTRANT_CELL if c in rows]
    return bool((rows.groupby(by)["seed"].nunique() > 1).any())
