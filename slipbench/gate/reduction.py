"""What the reduction keeps: a detector's channels cells against its univariate twins.

A detector evaluated with ``--input both`` has two rows for each of its cells: ``input``
"univariate" (the paper's s_t = ||a_t|| - ||a_{t-1}||) and "channels" (the raw channels), on the
same test windows. Rows written before the column existed are univariate. A channels cell's
*twin* is the univariate row equal to it in everything else: protocol and its parameters,
detector and its parameters, split, labels, normalization, cell key, decimation, test stream
and dataset (an ``input`` entry in the cell key or the parameters is not part of the
comparison). Twins pair across seeds as :func:`slipbench.gate.compare.compare` pairs base and
candidate, with the same machinery:

- one seed per side, the same: window by window, the paired stratified cluster bootstrap of
  :func:`slipbench.stats.metrics.paired_comparison` (:func:`~slipbench.gate.changes.paired_cell`);
- several seeds on a side: the two-level bootstrap over seeds and trials
  (:func:`~slipbench.gate.changes.cell_over_seeds`), so retraining noise is inside the interval,
  the seeds paired where both inputs ran the same ones (seed k made one split for both);
- a side without stored predictions: judged from the rows
  (:func:`~slipbench.gate.changes.unpaired_cell`), which errs wide.

Each cell's interval is at ``LEVEL`` (95 %) alone. Per detector, split, protocol and sensor type,
the mean change over the cells is bootstrapped once, jointly over the trials the cells share
(:func:`slipbench.stats.pooled.pooled_change`), the seeds crossed with the cells and paired as
compare's pooled tests take them: a seed's split moves every cell at once. In the committed
reproduction it does (the change's seed x cell layout: the seed's F 12.7-59.8, p < 0.001, in 11
of 18 detector, sensor and rate groups, p < 0.05 in 14; ``benchmarks/bench_seed_by_cell.py``),
so drawing each cell's seeds on its own held it too narrowly. Those pooled intervals are
simultaneous over every pooled change of the comparison (Bonferroni at ``ALPHA``), and they
alone are read, as every contrast is (:mod:`slipbench.stats.contrast`), against the accuracy's
margin (1 point): channels *better* where the interval lies above it, *worse* below -1 point,
*within the margin* where inside it, *undecided* where it holds a change within the margin and
one beyond it; *inconclusive* where the test trials are few, a side ran one seed (the interval
then holds the test trials' noise only), or the interval is wider than
:data:`~slipbench.gate.compare.MAX_WIDTH` points. Measured on simulated results with both inputs
equal, retraining noise and a split's luck shared by a sensor's cells
(``tests/stats/test_reduction.py``, 20 replications x 2 sensor types, each reading at 97.5 %):
with three seeds per cell, 1 of 40 readings called a difference (9 inconclusive: three splits
pin a split's luck down loosely); with one seed, read as above the interval alone, 10 of 40:
one seed is inconclusive, whatever its interval.

Cells of a detector and protocol that ran with channels but cannot be paired (no twin, a side not
finished, a streaming cell, a seed stored twice) are listed with the reason, never dropped.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from slipbench.gate.changes import cell_over_seeds, paired_cell, unpaired_cell
from slipbench.gate.compare import ALPHA, MAX_WIDTH, family_level
from slipbench.stats.bootstrap import IntervalSpec
from slipbench.stats.contrast import CONTRADICTED, ONE_SEED, SHOWN, Contrast, margin_of
from slipbench.stats.factors import CHANNELS, UNIVARIATE, inputs, plain
from slipbench.stats.metrics import LEVEL, RATES
from slipbench.stats.pooled import cell_sides, find_predictions, pooled_change, pooled_from_rows
from slipbench.store.columns import (
    ACCURACY,
    CELL_ROLE,
    ENTRANT,
    INPUT,
    READING,
    SETTING,
    identity,
)
from slipbench.vocabulary import SENSOR_TYPE

#: a paired cell's predictions and rows: (univariate, channels, their rows in the same order)
Sides = tuple[list, list, list[dict], list[dict]]
#: the rates compared, per cell and pooled
#: what a channels cell and its univariate twin share, where the rows hold the column (the seed
#: pairs apart, as compare pairs it): the key's columns but the input, and but those another of
#: them fixes already
TWIN_COLUMNS = identity(
    ENTRANT, READING, SETTING, CELL_ROLE, keyed=True, follows=False, but=(INPUT,)
)
_WITHOUT_INPUT = ("cell", "detector_params")  # JSON columns that may name the input
#: what names a compared cell (the seeds pool): the result's name, its cell key without the
#: input; its pooled group is the same but the cell key, per sensor type
_NAMED = identity(ENTRANT, SETTING, CELL_ROLE, named=True)
_POOLED = (*identity(ENTRANT, SETTING, CELL_ROLE, named=True, but=("cell",)), SENSOR_TYPE)
READINGS = ("channels better", "channels worse", "within the margin", "undecided", "inconclusive")


@dataclass
class InputComparison:
    """The outcome of :func:`compare_inputs`."""

    # one row per paired cell: identity, both sides' figures (means over seeds), d_<rate> with
    # _lo/_hi/_se at ``level``, seeds, test trials, low_n, method
    cells: pd.DataFrame
    # one row per detector, split, protocol and sensor type: cells, mean figures, the mean
    # change of each rate with its interval at ``pooled_level``, low_n, method, reading
    pooled: pd.DataFrame
    # one row per cell that ran with channels but was not compared: identity, inputs, reason
    unpaired: pd.DataFrame
    level: float = LEVEL
    pooled_level: float = LEVEL


def has_both_inputs(rows: pd.DataFrame) -> bool:
    """Whether some detector holds rows of both inputs."""
    if rows.empty or "detector" not in rows:
        return False
    held = inputs(rows).groupby(rows["detector"]).agg(set)
    return any({UNIVARIATE, CHANNELS} <= s for s in held)


def _without_input(value: Any) -> Any:
    """A JSON text of a key or parameters without its ``input`` entry."""
    if not isinstance(value, str):
        return value
    try:
        parsed = json.loads(value)
    except json.JSONDecodeError:
        return value
    if not isinstance(parsed, dict):
        return value
    parsed.pop("input", None)
    return json.dumps(parsed, sort_keys=True)


def twin_key(row: dict) -> str:
    """What a cell shares with its twin of the other input, as one text."""
    fields = {
        c: plain(_without_input(row[c]) if c in _WITHOUT_INPUT else row[c])
        for c in TWIN_COLUMNS
        if c in row
    }
    return json.dumps(fields, sort_keys=True, default=str)


def _sensor(row: dict) -> str:
    value = row.get(SENSOR_TYPE)
    if plain(value) is not None:
        return str(value)
    try:
        return str(json.loads(row.get("cell") or "{}").get(SENSOR_TYPE, ""))
    except (TypeError, json.JSONDecodeError):
        return ""


def _seed_order(row: dict) -> float:
    seed = plain(row.get("seed"))
    return float(seed) if seed is not None else -1.0


def _seeds(rows: list[dict]) -> str:
    """The seeds of a cell's rows, each once: "0,1,2"."""
    seeds = sorted({_seed_order(r) for r in rows})
    return ",".join(f"{s:g}" for s in seeds)


def _status(rows: list[dict]) -> str:
    """A side's status: "ok", or the first other status with its reason."""
    for r in rows:
        if r.get("status", "ok") != "ok":
            why = r.get("reason")
            return f"{r.get('status')}" + (f" ({why})" if plain(why) else "")
    return "ok"


def _why_not(uni: list[dict], ch: list[dict]) -> str:
    """Why a twin group cannot be compared, or "" where it can."""
    if not uni:
        return "no univariate twin: the univariate run holds no such cell"
    if not ch:
        return "no channels twin: the channels run holds no such cell"
    for side, rows in (("univariate", uni), ("channels", ch)):
        status = _status(rows)
        if status != "ok":
            return f"{side} {status}"
        seeds = [r.get("seed") for r in rows]
        if len(set(seeds)) < len(seeds):
            return f"{side}: a seed stored twice (two runs of one cell share the folder)"
    if any(plain(r.get("accuracy")) is None for r in (*uni, *ch)):
        return "no accuracy to pair (a streaming cell: its delays and alarms are not compared here)"
    return ""


def _identity(row: dict) -> dict:
    named = {c: row.get(c, "") for c in _NAMED} | {SENSOR_TYPE: _sensor(row)}
    return named | {"cell": _without_input(named["cell"])}


def _compare_cell(
    uni: list[dict], ch: list[dict], folders: Sequence[Path], seed: int
) -> tuple[dict, Sides | None]:
    """One paired cell's figures and change, and its predictions and rows per side (None where a
    side lacks predictions)."""
    entry = _identity(ch[0]) | {
        "seeds": _seeds(uni + ch),
        "n_seeds_univariate": len(uni),
        "n_seeds_channels": len(ch),
    }
    for side, rows in ((UNIVARIATE, uni), (CHANNELS, ch)):
        for name in RATES:
            values = [plain(r.get(name)) for r in rows]
            entry[f"{side}_{name}"] = (
                float(np.mean([float(v) for v in values])) if None not in values else np.nan
            )
    pu = [find_predictions(folders, str(r["key"])) for r in uni]
    pc = [find_predictions(folders, str(r["key"])) for r in ch]
    have = all(p is not None for p in (*pu, *pc))
    same_seeds = [r.get("seed") for r in uni] == [r.get("seed") for r in ch]
    result, note = None, ""
    if have and len(uni) == len(ch) == 1 and same_seeds:
        result = paired_cell(pu[0], pc[0], seed, LEVEL)
        note = " (the twins' test windows do not join)" if result is None else ""
    elif have:
        result = cell_over_seeds(pu, pc, IntervalSpec(seed, LEVEL), paired=same_seeds)
    preds = (pu, pc, uni, ch) if result is not None else None
    if result is None:
        result = unpaired_cell(uni, ch, LEVEL)
        result["method"] += note
    entry |= {k: v for k, v in result.items() if k.startswith("d_") or k in ("df", "method")}
    slip = [plain(r.get("n_test_clusters_slip")) for r in (*uni, *ch)]
    nonslip = [plain(r.get("n_test_clusters_nonslip")) for r in (*uni, *ch)]
    entry["n_test_trials_slip"] = result.get(
        "n_test_clusters_slip", max((v for v in slip if v is not None), default=np.nan)
    )
    entry["n_test_trials_nonslip"] = result.get(
        "n_test_clusters_nonslip", max((v for v in nonslip if v is not None), default=np.nan)
    )
    entry["low_n"] = bool(result.get("low_n", False)) or any(
        bool(plain(r.get("low_n"))) for r in (*uni, *ch)
    )
    return entry, preds


def _classes(preds: Sides) -> bool:
    """Every test set of the cell holds both classes (a TP or TN rate exists in each)."""
    return all(
        p["y_true"].astype(bool).any() and not p["y_true"].astype(bool).all()
        for side in preds[:2]
        for p in side
    )


def _pool(members: list[tuple[dict, Sides | None]], seed: int, level: float) -> dict:
    """The mean change of each rate over a group's cells: one joint bootstrap where every cell
    has its predictions, else from the rows."""
    cells = [e for e, _ in members]
    line: dict[str, Any] = {
        "cells": len(cells),
        "seeds": min(min(e["n_seeds_univariate"], e["n_seeds_channels"]) for e in cells),
    }
    for side in (UNIVARIATE, CHANNELS):
        for name in RATES:
            line[f"{side}_{name}"] = float(np.mean([e[f"{side}_{name}"] for e in cells]))
    preds = [p for _, p in members]
    joint = all(p is not None for p in preds)
    parts = [cell_sides(*p) for p in preds if p is not None] if joint else []
    line["method"] = (
        "joint cluster bootstrap over the trials the cells share"
        if joint
        else "mean of the cells' standard errors (not every cell has predictions to pool)"
    )
    line["low_n"] = all(bool(e["low_n"]) for e in cells)  # the joint bootstrap counts anew
    for name in RATES:
        if joint and (name == "accuracy" or all(_classes(p) for p in preds if p is not None)):
            res = pooled_change(parts, seed, level, figure=name)
            if name == "accuracy":
                line["low_n"] = bool(res["low_n"])
                line["method"] += f" and {res['seed_design']}" if res["seeds"] else ""
        elif not joint and all(np.isfinite(e[f"d_{name}"]) for e in cells):
            res = pooled_from_rows(
                [e[f"d_{name}"] for e in cells],
                [e[f"d_{name}_se"] for e in cells],
                [e.get("df", np.inf) for e in cells],
                level,
            )
        else:
            res = {"d": np.nan, "lo": np.nan, "hi": np.nan, "se": np.nan}
        for bound in ("", "_lo", "_hi", "_se"):
            line[f"d_{name}{bound}"] = float(res[bound[1:] or "d"])
    return line


def change_reading(line: dict, max_width: float = MAX_WIDTH) -> str:
    """What a pooled accuracy change says (one of ``READINGS``), read as every contrast is
    (:mod:`slipbench.stats.contrast`) against the accuracy's margin: beyond it, channels better
    or worse; inside it, within the margin; neither, undecided; inconclusive where the interval
    lacks what its claim needs: enough test trials, a second seed per side, or a width of at
    most ``max_width`` points."""
    width = 100 * (line["d_accuracy_hi"] - line["d_accuracy_lo"])
    change = Contrast(
        line["d_accuracy"],
        line["d_accuracy_lo"],
        line["d_accuracy_hi"],
        margin=margin_of(ACCURACY.name),
        missing="low n" if line["low_n"] else ONE_SEED if line["seeds"] < 2 else "",
    )
    if change.missing or not change.judged or not width <= max_width:
        return "inconclusive"
    if change.state == SHOWN:
        return "channels better" if change.direction > 0 else "channels worse"
    return "within the margin" if change.state == CONTRADICTED else "undecided"


def compare_inputs(
    rows: pd.DataFrame,
    folders: Sequence[str | os.PathLike] = (),
    seed: int = 0,
    max_width: float = MAX_WIDTH,
) -> InputComparison:
    """Pair every channels cell with its univariate twin, and pool the changes.

    Parameters
    ----------
    rows : result rows (:func:`slipbench.store.results.read_results`), of any detectors; only
        detectors and protocols that ran with channels are compared.
    folders : results folders that may hold the cells' predictions (``predictions/<key>.parquet``).
    seed : seeds every bootstrap.
    max_width : accuracy points; a pooled change whose interval is wider is inconclusive.

    Returns
    -------
    InputComparison
        Cells in the order the rows give them; pooled changes per detector, split, protocol and
        sensor type, each read by its simultaneous interval.
    """
    paths = [Path(f) for f in folders]
    frame = rows.assign(input=inputs(rows))
    records = frame.to_dict("records")
    ran = {(r["detector"], r["protocol"]) for r in records if r["input"] == CHANNELS}
    groups: dict[str, dict[str, list[dict]]] = {}
    for r in records:
        if (r["detector"], r["protocol"]) in ran and r["input"] in (UNIVARIATE, CHANNELS):
            sides = groups.setdefault(twin_key(r), {UNIVARIATE: [], CHANNELS: []})
            sides[r["input"]].append(r)
    compared, unpaired = [], []
    for sides in groups.values():
        uni, ch = (sorted(sides[s], key=_seed_order) for s in (UNIVARIATE, CHANNELS))
        why = _why_not(uni, ch)
        if why:
            first = (ch or uni)[0]
            unpaired.append(
                _identity(first)
                | {
                    "inputs": ", ".join(s for s in (UNIVARIATE, CHANNELS) if sides[s]),
                    "seeds": _seeds(uni + ch),
                    "reason": why,
                }
            )
            continue
        compared.append(_compare_cell(uni, ch, paths, seed))
    by_group: dict[tuple, list] = {}
    for entry, preds in compared:
        key = tuple(entry[c] for c in _POOLED)
        by_group.setdefault(key, []).append((entry, preds))
    pooled_level = family_level(len(by_group), ALPHA)
    lines = []
    for key, members in by_group.items():
        line = dict(zip(_POOLED, key)) | _pool(members, seed, pooled_level)
        line["reading"] = change_reading(line, max_width)
        lines.append(line)
    return InputComparison(
        pd.DataFrame([e for e, _ in compared]),
        pd.DataFrame(lines),
        pd.DataFrame(unpaired, columns=[*_NAMED, SENSOR_TYPE, "inputs", "seeds", "reason"]),
        LEVEL,
        pooled_level,
    )
