"""The report's section "What the reduction keeps": each detector run with both inputs, its
channels cells against their univariate twins (:mod:`slipbench.gate.reduction`), per sensor
type. The summary holds per sensor type the pooled change of each detector and protocol with
its simultaneous interval, a sentence reading it, and one figure; each detector's per-cell
table is a :class:`~slipbench.report.blocks.Detail` (the appendix of a split report), and so is
the list of cells that could not be paired."""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from functools import partial

import numpy as np
import pandas as pd

from slipbench.gate.compare import ALPHA, MAX_WIDTH, MIN_SEEDS, RECOMMENDED_REPEATS
from slipbench.gate.reduction import READINGS, InputComparison, compare_inputs, has_both_inputs
from slipbench.report.blocks import LOW_MARK, Detail, Heading, Table, Text
from slipbench.report.order import ordered, rank
from slipbench.report.outline import layouts, protocol_order
from slipbench.report.tables import CLASS_RATES
from slipbench.stats.contrast import margin_of
from slipbench.store.columns import ACCURACY
from slipbench.vocabulary import DETECTOR_ORDER, LOW_N, SENSOR_NAMES, SENSOR_TYPE, cell_label, label

REDUCTION_TITLE = "What the reduction keeps: univariate vs channels"
CHANGE = "channels − univariate"


def _level(level: float) -> str:
    return f"{100 * level:.4g} %"


def _points(line: dict | pd.Series, name: str, bounds: bool = True) -> str:
    """A change in points with its interval: "+6.3 [+3.1, +9.5]"."""
    d, lo, hi = (line.get(f"d_{name}{b}", np.nan) for b in ("", "_lo", "_hi"))
    if not np.isfinite(d):
        return "—"
    text = f"{100 * d:+.1f}"
    if bounds and np.isfinite(lo) and np.isfinite(hi):
        text += f" [{100 * lo:+.1f}, {100 * hi:+.1f}]"
    return text


def _percent(value: float) -> str:
    return f"{100 * value:.1f}" if np.isfinite(value) else "—"


def _short_cell(cell: str) -> str:
    """A cell's label without its sensor type (the table is of one sensor, or says it)."""
    try:
        key = json.loads(cell)
    except (TypeError, json.JSONDecodeError):
        return str(cell)
    key.pop(SENSOR_TYPE, None)
    return cell_label(key) or "(the sensor's only cell)"


def _order(frame: pd.DataFrame, protocols: list[str]) -> pd.DataFrame:
    """Rows by detector, protocol (the report's order) and split (grouped first)."""
    if frame.empty:
        return frame
    detectors = rank(frame["detector"].unique(), DETECTOR_ORDER)
    splits = rank(frame["split"].unique(), ("grouped", "paper"))

    def key(r: pd.Series) -> tuple:
        p = r["protocol"]
        return (
            detectors.index(r["detector"]),
            protocols.index(p) if p in protocols else len(protocols),
            str(p),
            splits.index(r["split"]),
        )

    order = sorted(frame.index, key=lambda i: key(frame.loc[i]))
    return frame.loc[order].reset_index(drop=True)


def _spread(values: pd.Series) -> str:
    """A count per cell as "12" or "10–14" (the range over cells)."""
    v = values.dropna()
    if v.empty:
        return "?"
    lo, hi = int(v.min()), int(v.max())
    return f"{lo}" if lo == hi else f"{lo}–{hi}"


def _count(n: int, what: str) -> str:
    return f"{n} {what}{'s' * (n != 1)}"


def _stands_on(cmp: InputComparison) -> str:
    """The data and settings behind the section: cells, detectors, seeds, trials, intervals."""
    cells = cmp.cells
    detectors = rank(cells["detector"].unique(), DETECTOR_ORDER)
    seeds = sorted(
        {s for text in cells["seeds"] for s in str(text).split(",")}, key=lambda s: (len(s), s)
    )
    fewest = int(cells[["n_seeds_univariate", "n_seeds_channels"]].min().min())
    methods = cells["method"].str.replace(r" \(.*", "", regex=True).value_counts()
    how = "; ".join(f"{m}: {_count(n, 'cell')}" for m, n in methods.items())
    text = (
        f"Each detector run with both inputs ({', '.join(detectors)}), the raw channels against the "
        "paper's univariate signal s_t = ||a_t|| - ||a_{t-1}|| on the same cells, windows, splits and "
        f"seeds: {_count(len(cells), 'paired cell')} in "
        f"{_count(cmp.pooled['protocol'].nunique(), 'protocol')} and "
        f"{_count(cells['sensor_type'].nunique(), 'sensor type')}, "
        f"{'seed' if len(seeds) == 1 else 'seeds'} {', '.join(seeds)} "
        f"({_spread(cells['n_seeds_channels'])} per cell), test trials per cell "
        f"{_spread(cells['n_test_trials_slip'])} with slip and "
        f"{_spread(cells['n_test_trials_nonslip'])} without. "
        f"Figures are accuracy (%) and changes {CHANGE} in points. A cell's interval is its own "
        f"{_level(cmp.level)} interval ({how}). "
        "Per detector, protocol and sensor type, the mean change over the cells is bootstrapped once, "
        "jointly over the trials the cells share (and the seeds, paired where both inputs ran the same "
        "ones); "
        + (
            f"these {len(cmp.pooled)} pooled intervals hold together at {_level(1 - ALPHA)} "
            f"({_level(cmp.pooled_level)} each, Bonferroni), and they alone are read: "
            if len(cmp.pooled) > 1
            else f"its {_level(cmp.pooled_level)} interval alone is read: "
        )
        + f"channels better (interval above +{MARGIN_POINTS:g} point), worse (below "
        f"-{MARGIN_POINTS:g}), within the margin (inside ±{MARGIN_POINTS:g}), undecided (neither), or "
        f"inconclusive (fewer than {LOW_N} test trials of a class, one seed per side, or wider than "
        f"{MAX_WIDTH:g} points)."
    )
    if fewest < MIN_SEEDS:
        text += (
            " With one seed per cell, retraining noise is not inside the intervals, so they read "
            "inconclusive: run "
            f"`evaluate --input both --repeats {RECOMMENDED_REPEATS}` to include it."
        )
    return text


def _extremes(cells: pd.DataFrame) -> str:
    """The cells that changed least and most: "−2.1 (Index window 5) to +9.3 (Middle window 200)"."""
    known = cells[np.isfinite(cells["d_accuracy"])]
    if known.empty:
        return "—"
    lo, hi = known.loc[known["d_accuracy"].idxmin()], known.loc[known["d_accuracy"].idxmax()]
    if len(known) == 1:
        return f"{100 * lo['d_accuracy']:+.1f}"
    return (
        f"{100 * lo['d_accuracy']:+.1f} ({_short_cell(lo['cell'])}) to "
        f"{100 * hi['d_accuracy']:+.1f} ({_short_cell(hi['cell'])})"
    )


def _pooled_table(cmp: InputComparison, sensor: str, protocols: list[str]) -> Table:
    pooled = _order(cmp.pooled[cmp.pooled[SENSOR_TYPE] == sensor], protocols)
    splits = cmp.pooled["split"].nunique() > 1
    rows, cells = [], []
    for r in pooled.to_dict("records"):
        rows.append((r["detector"], r["protocol"], *([r["split"]] if splits else [])))
        mine = cmp.cells[
            (cmp.cells["detector"] == r["detector"])
            & (cmp.cells["protocol"] == r["protocol"])
            & (cmp.cells["split"] == r["split"])
            & (cmp.cells[SENSOR_TYPE] == sensor)
        ]
        cells.append(
            [
                str(r["cells"]),
                _percent(r["univariate_accuracy"]),
                _percent(r["channels_accuracy"]),
                _points(r, "accuracy") + (LOW_MARK if r["low_n"] else ""),
                *(_points(r, name) for name in CLASS_RATES),
                _extremes(mine),
                r["reading"],
            ]
        )
    name = SENSOR_NAMES.get(sensor, sensor)
    methods = sorted(set(pooled["method"]))
    return Table(
        f"{name}: {CHANGE}, mean over each protocol's cells.",
        ["Detector", "Protocol", *(["Split"] if splits else [])],
        "",
        [
            "Cells",
            "Univariate",
            "Channels",
            f"Change [{_level(cmp.pooled_level)}]",
            "TP rate change",
            "TN rate change",
            "Cells, least to most",
            "Reading",
        ],
        rows,
        cells,
        f"tab:reduction-{sensor}",
        notes=[
            f"Univariate, channels: mean accuracy (%) over the cells (and their seeds). Change: {CHANGE} "
            f"in points, the mean over the cells [{_level(cmp.pooled_level)} interval, simultaneous "
            f"over the {len(cmp.pooled)} pooled changes: {'; '.join(methods)}]; TP and TN rates at "
            "the same level. Cells, least to most: the cells' own changes in accuracy.",
        ],
        wrap={8 + splits: 0.22, 9 + splits: 0.12},
    )


#: the margin the pooled changes are read against, in points
MARGIN_POINTS = 100 * margin_of(ACCURACY.name)

# how a sentence says each reading of the pooled changes it lists
CLAUSES = {
    "channels better": "the channels beat the univariate signal in {}",
    "channels worse": "the channels fall behind the univariate signal in {}",
    "within the margin": "the two are within the margin of each other in {}",
    "undecided": "no difference beyond the margin is resolved in {}",
    "inconclusive": "nothing can be read in {}",
}


def _where(r: dict, splits: bool) -> str:
    """A pooled change's protocol, its figure and, where it decides nothing, why."""
    where = r["protocol"] + (f", {r['split']} split" if splits else "")
    text = f"{_points(r, 'accuracy')} points, {r['cells']} cell{'s' * (r['cells'] > 1)}"
    if r["reading"] == "inconclusive":
        text += (
            f"; fewer than {LOW_N} test trials of a class"
            if r["low_n"]
            else "; one seed per side"
            if r["seeds"] < MIN_SEEDS
            else f"; interval wider than {MAX_WIDTH:g} points"
        )
    return f"{where} ({text})"


def _listed(items: list[str]) -> str:
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def _readings(cmp: InputComparison, sensor: str, protocols: list[str]) -> str:
    """One sentence per detector: what its pooled changes on this sensor say, by reading."""
    pooled = _order(cmp.pooled[cmp.pooled[SENSOR_TYPE] == sensor], protocols)
    splits = cmp.pooled["split"].nunique() > 1
    name = SENSOR_NAMES.get(sensor, sensor)
    out = []
    for detector, part in pooled.groupby("detector", sort=False):
        records = part.to_dict("records")
        clauses = [
            CLAUSES[reading].format(
                _listed([_where(r, splits) for r in records if r["reading"] == reading])
            )
            for reading in READINGS
            if any(r["reading"] == reading for r in records)
        ]
        out.append(f"On the {name}, with {detector}, {'; '.join(clauses)}.")
    return " ".join(out)


def _cells_table(cmp: InputComparison, detector: str, protocols: list[str]) -> Table:
    """A detector's every paired cell, by sensor type and protocol."""
    mine = cmp.cells[cmp.cells["detector"] == detector]
    sensors = ordered(mine[SENSOR_TYPE].unique(), SENSOR_TYPE)
    mine = _order(mine, protocols)
    mine = mine.iloc[
        sorted(range(len(mine)), key=lambda i: sensors.index(mine[SENSOR_TYPE].iloc[i]))
    ]
    splits = cmp.cells["split"].nunique() > 1
    rows, cells = [], []
    for r in mine.to_dict("records"):
        rows.append(
            (
                label(SENSOR_TYPE, r[SENSOR_TYPE]),
                r["protocol"],
                _short_cell(r["cell"]),
                *([r["split"]] if splits else []),
            )
        )
        cells.append(
            [
                r["seeds"],
                _percent(r["univariate_accuracy"]),
                _percent(r["channels_accuracy"]),
                _points(r, "accuracy") + (LOW_MARK if r["low_n"] else ""),
                *(_points(r, name, bounds=False) for name in CLASS_RATES),
            ]
        )
    return Table(
        f"{detector}: {CHANGE}, cell by cell.",
        ["Sensor", "Protocol", "Cell", *(["Split"] if splits else [])],
        "",
        [
            "Seeds",
            "Univariate",
            "Channels",
            f"Change [{_level(cmp.level)}]",
            "TP rate change",
            "TN rate change",
        ],
        rows,
        cells,
        f"tab:reduction-cells-{detector}",
        notes=[
            f"Change: {CHANGE} in points [each cell's own {_level(cmp.level)} interval: paired over the "
            "test trials, over seeds and trials where a cell ran several; not simultaneous, so "
            "not for reading cells one by one]."
        ],
    )


def _unpaired_tables(cmp: InputComparison) -> tuple[Table, Table]:
    """Cells that ran with channels but were not compared: counted by reason, and listed."""
    u = cmp.unpaired
    counts = u.groupby(["detector", "protocol", "inputs", "reason"], sort=False).size()
    summary = Table(
        "Not compared: cells of a detector and protocol run with channels that have no twin "
        "of the other input, or cannot be paired with it.",
        ["Detector", "Protocol"],
        "",
        ["Input held", "Reason", "Cells"],
        [(d, p) for d, p, _, _ in counts.index],
        [[i, why, str(n)] for (_, _, i, why), n in counts.items()],
        "tab:reduction-unpaired",
        wrap={3: 0.45},
    )
    listing = Table(
        "Not compared, cell by cell.",
        ["Detector", "Protocol", "Cell"],
        "",
        ["Split", "Seeds", "Input held", "Reason"],
        [
            (r["detector"], r["protocol"], cell_label(r["cell"]) if r["cell"] else "")
            for r in u.to_dict("records")
        ],
        [[str(r["split"]), r["seeds"], r["inputs"], r["reason"]] for r in u.to_dict("records")],
        "tab:reduction-unpaired-cells",
        wrap={6: 0.4},
    )
    return summary, listing


def reduction_blocks(
    rows: pd.DataFrame,
    predictions: Sequence[str | os.PathLike] = (),
    with_figures: bool = False,
    seed: int = 0,
) -> list:
    """The section's blocks, or none where no detector holds rows of both inputs.

    Parameters
    ----------
    rows : result rows of the report (stand-ins left out).
    predictions : results folders holding the cells' test predictions: with them, cells are
        paired window by window and pooled jointly; without, compared from the rows.
    with_figures : add the figure (:func:`slipbench.report.reduction_plot.input_changes`).
    seed : seeds the bootstraps.
    """
    if not has_both_inputs(rows):
        return []
    cmp = compare_inputs(rows, predictions, seed)
    blocks: list = [Heading(REDUCTION_TITLE, 2)]
    if cmp.cells.empty:
        blocks.append(
            Text("No channels cell could be paired with a univariate twin: nothing to compare.")
        )
    else:
        protocols = protocol_order(layouts(rows))
        blocks.append(Text(_stands_on(cmp)))
        for sensor in ordered(cmp.pooled[SENSOR_TYPE].unique(), SENSOR_TYPE):
            blocks += [
                Heading(f"{SENSOR_NAMES.get(sensor, sensor)}: univariate vs channels", 3),
                _pooled_table(cmp, sensor, protocols),
                Text(_readings(cmp, sensor, protocols)),
            ]
        if with_figures:
            from slipbench.report.plots import FigureSpec
            from slipbench.report.reduction_plot import input_changes

            pooled = _order(cmp.pooled, protocols)
            blocks.append(
                FigureSpec(
                    "reduction",
                    f"What the reduction keeps: {CHANGE} in accuracy (points), one panel per "
                    "sensor type; per detector and protocol the mean over its cells (marker) with "
                    f"its simultaneous {_level(cmp.pooled_level)} interval (bar), each cell's own "
                    "change a grey dot.",
                    REDUCTION_TITLE,
                    partial(input_changes, pooled, cmp.cells),
                )
            )
        for detector in rank(cmp.cells["detector"].unique(), DETECTOR_ORDER):
            blocks.append(Detail(REDUCTION_TITLE, [_cells_table(cmp, detector, protocols)]))
    if not cmp.unpaired.empty:
        summary, listing = _unpaired_tables(cmp)
        blocks += [summary, Detail(REDUCTION_TITLE, [listing])]
    return blocks
