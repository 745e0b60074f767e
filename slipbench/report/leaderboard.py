"""The leaderboard said: the tables of :func:`slipbench.stats.leaderboard.leaderboard` (mean
ranks per scope; mean figures with intervals and cells won; the groups per scope and the
pairwise table, both from :func:`slipbench.stats.leaderboard.pairwise`) with the figures' names
and the notes that say how to read them; the line to beat (:func:`versus_baseline`)."""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np
import pandas as pd

from slipbench.report.blocks import BELOW_CONSTANT_MARK, LOW_MARK, Table
from slipbench.report.order import rank
from slipbench.report.outline import references
from slipbench.report.tables import figure_label, ordered_keys, summarize
from slipbench.report.versus import DIFFER_WORDS, VERSUS, add_versus
from slipbench.stats.contrast import (
    SHOWN,
    UNDECIDED,
    Contrast,
    is_decided,
    pair_seeds,
    paired_change,
    summary_figure,
)
from slipbench.stats.factors import ENTRANT_ID, one_class, setting_labels
from slipbench.stats.leaderboard import (
    ALL,
    ALPHA,
    CONSTANT,
    MEAN_METRICS,
    ONE_BLOCK,
    ONE_RUN,
    Leaderboard,
    Scope,
)
from slipbench.store.columns import ACCURACY
from slipbench.vocabulary import DETECTOR_ORDER, LOW_N, SENSOR_TYPE, label

# the intervals of a board whose entrants ran several seeds (slipbench.stats.leaderboard.crossed_interval)
_SEEDS_INTERVAL = (
    "[95 % interval over blocks and seeds (up to {n} seeds per block): the variance over the ranked "
    "blocks of their figures plus that over the seeds of the seeds' means, a seed being one split and "
    "one detector seed for every block, so retraining noise that every block shares is inside it; "
    "each part with its own t quantile (Banerjee), which errs wide.]"
)


def _p(p: float) -> str:
    return "< 0.001" if p < 0.001 else f"{p:.3f}"


def _percent(mean: float, lo: float, hi: float) -> str:
    if not np.isfinite(mean):
        return "NA"
    return f"{100 * mean:.1f}" + (
        f" [{100 * lo:.1f}, {100 * hi:.1f}]" if np.isfinite(lo) and np.isfinite(hi) else ""
    )


def leaderboard_tables(board: Leaderboard) -> list[Table]:
    """The leaderboard as tables: mean ranks per scope; mean figures with intervals and cells
    won; the groups per scope; the pairs."""
    overall = board.scopes[0] if board.scopes else None
    if overall is None or overall.n_cells == 0:
        excluded = overall.n_excluded if overall else 0
        return [
            Table(
                "Leaderboard.",
                ["Detector"],
                "",
                ["Mean rank"],
                [],
                [],
                "tab:leaderboard",
                notes=[
                    f"No cell was finished by every detector ({excluded} cells): nothing to rank."
                    if excluded or not board.n_one_class
                    else "No cell to rank.",
                    *_one_class_note(board),
                ],
            )
        ]
    order = board.order
    name = figure_label(board.metric)
    scopes = [s for s in board.scopes if s.n_cells]
    columns = [f"{'all' if s.name == ALL else s.name} ({s.n_cells})" for s in scopes]
    cells = [[f"{s.ranks[e]:.2f}{_low(s, e)}" for s in scopes] for e in order]
    dup = overall.n_duplicates
    notes = [
        f"Mean rank of {name.lower()} over blocks, in parentheses the blocks ranked (1 = best): per block the "
        "detectors are ranked by their figure (mean over seeds), ties sharing the mean rank. A block is one "
        "model tested on one set of test windows: "
        + (
            f"{overall.n_cells + dup} finished cells were ranked as {overall.n_cells} blocks, {dup} "
            f"{'duplicate' if dup == 1 else 'duplicates'} merged (cells with the same model key and test part, "
            "e.g. the sampling rate's full-rate cells and window-size's window 200)"
            if dup
            else f"{overall.n_cells} finished cells were ranked, no duplicate among them"
        )
        + ". Only cells every detector finished are ranked"
        + (
            f"; {overall.n_excluded} {'cell was' if overall.n_excluded == 1 else 'cells were'} not (failed, skipped "
            "or absent for some detector)."
            if overall.n_excluded
            else "; every cell was."
        )
    ]
    if len(order) == 1:
        notes.append("One detector: nothing to rank it against.")
    notes += _one_class_note(board) + _low_notes(scopes)
    tables = [
        Table(
            f"Leaderboard: detectors ranked by {name.lower()}.",
            ["Place", "Detector"],
            "Mean rank (blocks)",
            columns,
            [(str(i + 1), e) for i, e in enumerate(order)],
            cells,
            "tab:leaderboard",
            notes=notes,
        )
    ]
    shown = [
        m for m in MEAN_METRICS if board.means[f"{m}_cells"].max() > 0
    ]  # figures the rows hold
    mean_cols = [f"{figure_label(m)} (%)" for m in shown] + ["Blocks won"]
    mean_cells = [
        [_percent(*board.means.loc[e, [m, f"{m}_lo", f"{m}_hi"]]) + _low(overall, e) for m in shown]
        + [f"{int(overall.wins[e])}{_low(overall, e)}"]
        for e in order
    ]
    constant_notes = _constant_column(board, shown, mean_cols, mean_cells)
    below = [e for e, line in zip(order, mean_cells) if BELOW_CONSTANT_MARK in " ".join(line)]
    if below and board.metric == ACCURACY.name:
        tables[0].notes.append(
            f"{BELOW_CONSTANT_MARK} {', '.join(below)}: accuracy not above the constant answer's "
            "(the means table): these ranks order detectors by a figure that answering one class "
            "throughout would match."
        )
    fewer = [
        f"{figure_label(m)} exists on {int(board.means[f'{m}_cells'].min())} of them (not on a one-class "
        "test set)"
        for m in shown
        if board.means[f"{m}_cells"].min() < overall.n_cells
    ]
    tables.append(
        Table(
            f"Mean figures over the {overall.n_cells} ranked blocks.",
            ["Detector"],
            "",
            mean_cols,
            [(e,) for e in order],
            mean_cells,
            "tab:leaderboard-means",
            notes=[
                (
                    _SEEDS_INTERVAL.format(n=board.n_seeds)
                    if board.n_seeds > 1
                    else "[95 % interval: percentile bootstrap over the ranked blocks, each block's figure "
                    "fixed: how the mean depends on which conditions make up the benchmark, not the test "
                    "noise within a cell, which the per-cell intervals show.]"
                )
                + " Blocks won: blocks where the detector ranked first (a tie counts for each)."
                + (" " + "; ".join(fewer) + "." if fewer else ""),
                *constant_notes,
                *_low_notes([overall]),
            ],
        )
    )
    if len(order) >= 2:
        tables.append(_groups_table(scopes, board))
        tables.append(_pairs_table(board, name))
    return tables


def _constant_column(
    board: Leaderboard, shown: list[str], columns: list[str], cells: list[list[str]]
) -> list[str]:
    """The means table (``columns``, ``cells``, in place) with what the constant answer scores
    beside the accuracy, and the accuracy of a detector not above it marked; returns the notes
    that say so. On an imbalanced test set accuracy is read beside it: a detector that scores
    less than always giving the larger class's answer has not shown it tells the classes apart."""
    if ACCURACY.name not in shown:
        return []
    means = board.means
    if not means["constant_cells"].gt(0).any():
        return [
            "The rows hold no test windows per class (test_slip_windows, test_nonslip_windows, or "
            "tp, tn, fp, fn): what the constant answer scores on these test sets is not shown."
        ]
    at = shown.index(ACCURACY.name) + 1
    columns.insert(at, "Constant answer (%)")
    below = []
    for e, line in zip(board.order, cells):
        n = int(means.loc[e, "constant_cells"])
        constant, accuracy = means.loc[e, [CONSTANT, "constant_accuracy"]]
        line.insert(at, f"{100 * constant:.1f}" if n else "—")
        if n and accuracy <= constant:
            line[at - 1] += BELOW_CONSTANT_MARK
            below.append(f"{e} {100 * accuracy:.1f} against {100 * constant:.1f}")
    n_blocks = board.scopes[0].n_cells
    counted = means["constant_cells"].astype(int)
    never = means["constant_never"].astype(int)
    over = (
        f"over the {n_blocks} ranked blocks"
        if counted.eq(n_blocks).all()
        else f"over the {counted.min()}-{counted.max()} ranked blocks whose rows give their test "
        "windows per class"
    )
    notes = [
        'Constant answer: the accuracy of answering "never slip" to every window, or "always '
        "slip\", whichever scores more on each block's test set (the larger class's share of its "
        f'windows), mean {over}; "never slip" on {never.max()} of them. Balanced accuracy and '
        "AUROC of a constant answer are 50 %. On an imbalanced test set accuracy is read beside it."
    ]
    if below:
        notes.append(
            f"{BELOW_CONSTANT_MARK} accuracy not above the constant answer's on the same blocks "
            f"({'; '.join(below)}): the detector does not beat answering one class throughout; "
            "read its balanced accuracy."
        )
    return notes


NO_BASELINE = (
    "No baseline ran on these cells: none of these detectors is the registered reference (the "
    f"one that slipbench list marks), so no '{VERSUS}' column."
)


def versus_baseline(
    tables: list[Table],
    rows: pd.DataFrame,
    predictions: Sequence[str | os.PathLike] = (),
    metric: str = ACCURACY.name,
) -> None:
    """The leaderboard ``tables`` (:func:`leaderboard_tables` of ``rows``) with the line to beat:
    the means table's 'vs baseline' column (:func:`versus_column`, in ``metric``, the figure
    the board ranks) over the cells the leaderboard may rank (none tested on one class); where
    no reference ran, one line saying so, under the ranks. ``predictions``: the results folders
    holding the cells' test predictions."""
    rows = rows[~one_class(rows)]
    reference = references(rows)
    if not reference:
        tables[0].notes.append(NO_BASELINE)
    elif len(tables) > 1:  # else nothing ranked: no means table
        versus_column(tables[1], rows, reference, predictions, metric)


def versus_column(
    table: Table,
    rows: pd.DataFrame,
    reference: Sequence[str],
    predictions: Sequence[str | os.PathLike] = (),
    metric: str = ACCURACY.name,
) -> None:
    """``table`` (a line per entrant of ``rows``) with its 'vs baseline' column: each line's
    seed-paired change from the ``reference`` detectors' rows
    (:func:`slipbench.stats.contrast.paired_change`) in ``metric`` (the report's ``--metric``),
    or in a stream's detection rate where the rows hold no value of it (streaming rows have no
    accuracy); the reference's own lines marked; nothing where the reference has no rows among
    ``rows``."""
    ids = rows[ENTRANT_ID] if ENTRANT_ID in rows else rows["detector"]
    is_ref = ids.isin(reference)
    if not is_ref.any():
        return
    held = metric in rows and rows[metric].notna().any()
    figure = metric if held else summary_figure(rows)
    changes: list[tuple[Contrast, int] | None] = []
    for (entrant,) in table.rows:
        mine = rows["detector"] == entrant
        if is_ref[mine].all():
            changes.append(None)
            continue
        pairing = pair_seeds(rows[is_ref], rows[mine], figure, ("the reference", entrant))
        changes.append((paired_change(pairing, figure, predictions), pairing.low_n))
    add_versus(table, changes, ", ".join(reference), figure)


def _low(scope: Scope, entrant: str) -> str:
    """The low-n mark where some ranked block of ``scope`` rests on few test trials of
    ``entrant``'s."""
    return LOW_MARK if scope.low_n.get(entrant, 0) else ""


def _low_notes(scopes: Sequence[Scope]) -> list[str]:
    """What the low-n mark says of a board's figures, per scope where it appears."""
    marked = [s for s in scopes if s.low_n.gt(0).any()]
    if not marked:
        return []
    counts = "; ".join(
        f"{'all' if s.name == ALL else s.name}: "
        + ", ".join(f"{e} {n} of {s.n_cells}" for e, n in s.low_n.items() if n)
        for s in marked
    )
    return [
        f"{LOW_MARK} the detector's figures there rest on blocks of fewer than {LOW_N} test trials of "
        f"a class (low n; {counts} blocks): each such block's figure is not to be trusted, nor are "
        "the means, ranks and wins over them."
    ]


def _groups_table(scopes: list[Scope], board: Leaderboard) -> Table:
    """Per scope, the groups of detectors shown not to differ, from the scope's pairs: the
    decided count counts the pairs whose rows read "yes" or "no", nothing else."""
    cells = []
    for s in scopes:
        decided = int(s.pairs["state"].map(is_decided).sum()) if len(s.pairs) else 0
        differ = int((s.pairs["state"] == SHOWN).sum()) if len(s.pairs) else 0
        groups = "; ".join("{" + ", ".join(g) + "}" for g in s.groups)
        if not groups:
            groups = (
                "none: every pair differs"
                if differ == len(s.pairs)
                else "none: no pair decided"
                if decided == 0
                else "none"
            )
        cells.append([str(s.n_cells), f"{decided} of {len(s.pairs)}", groups])
    return Table(
        "Do the detectors differ? Groups per scope, from the pairwise contrasts over blocks and seeds.",
        ["Scope"],
        "",
        ["Blocks", "Pairs decided", "Groups shown not to differ"],
        [("all" if s.name == ALL else s.name,) for s in scopes],
        cells,
        "tab:leaderboard-tests",
        wrap={3: 0.5},
        notes=[
            f"{DECIDED_TEXT} A group lists detectors, in rank order, every pair of which is shown not "
            "to differ: its interval (the pairwise table's, over the scope's blocks and seeds, "
            f"{_family_text(board)}) lies inside the margin. A detector in no group differs from every "
            "other or is undecided against it. An undecided pair joins no group: its interval straddles "
            f"the margin, or lacks a noise its claim needs where {UNDECIDED_WHY}. Blocks share recordings (window "
            "50 of a unit appears in several protocols, with another model or test set), so they are "
            "not independent and the intervals are optimistic."
        ],
    )


#: what "decided" means, in every leaderboard table that counts or draws pairs
DECIDED_TEXT = (
    "Decided: the pair's printed interval settles it, lying beyond the margin (differ: yes) or "
    "inside it (differ: no); a pair whose interval holds both is undecided and counts as such."
)


#: why a pair has no full interval, in the tables' notes
UNDECIDED_WHY = (
    "an entrant ran one seed (nothing measures the luck its one run had in every block; run "
    "`evaluate --repeats 2` or more) or the scope has one block (nothing measures how the "
    "difference varies between conditions)"
)


def _family_text(board: Leaderboard) -> str:
    """The pairs' level and margin, in words."""
    return (
        f"each at {100 * board.level:.4g} %, Bonferroni over every scope's testable pairs so that "
        f"all hold at once with 95 %; the margin ±{100 * board.margin:g} points"
    )


def _one_class_note(board: Leaderboard) -> list[str]:
    n = board.n_one_class
    if not n:
        return []
    return [
        f"{n} finished {'cell tests' if n == 1 else 'cells test'} on one class only and {'is' if n == 1 else 'are'} "
        'not ranked: there a detector that always says "slip" (or never does) scores 100 %; the table of '
        "one-class test sets shows them beside it."
    ]


UNIT = (SENSOR_TYPE, "sensor_instance")


def one_class_table(rows: pd.DataFrame) -> Table | None:
    """The finished cells that test on one class only (:func:`slipbench.stats.factors.one_class`),
    which no leaderboard ranks: per protocol, detector and unit, the rate they measure (the TP
    rate of a slip-only set, the TN rate of a non-slip one; mean over the cells of each cell's
    mean over seeds, with its range) beside what a constant "slip" detector scores there."""
    lone = rows[one_class(rows)]
    if lone.empty:
        return None
    unit = [c for c in UNIT if c in lone]
    constant, slips = (
        pd.to_numeric(lone[c], errors="coerce") if c in lone else pd.Series(np.nan, lone.index)
        for c in ("constant_slip_accuracy", "test_slip_windows")
    )
    slip_only = constant.fillna(slips.gt(0).astype(float))
    lone = lone.assign(
        _class=slip_only.map(lambda v: "slip" if v >= 0.5 else "non-slip"),
        _setting=setting_labels(lone),
    )
    detectors = rank(lone["detector"].unique(), DETECTOR_ORDER)
    lone = lone.assign(_place=lone["detector"].map(detectors.index))
    by = ["protocol", "_setting", "_place", "detector", *unit, "_class"]
    per_cell = summarize(lone, [*by, "cell"] if "cell" in lone else by)
    lines, cells = [], []
    for key in ordered_keys(per_cell, by):
        protocol, where, _, detector, *units, kind = key
        mean = per_cell.loc[(per_cell[by] == pd.Series(key, index=by)).all(axis=1), "mean"]
        spread = f" ({100 * mean.min():.1f}–{100 * mean.max():.1f})" if mean.nunique() > 1 else ""
        lines.append(
            (
                protocol + (f" ({where})" if where else ""),
                detector,
                *(label(c, v) for c, v in zip(unit, units)),
            )
        )
        cells.append(
            [
                kind,
                str(len(mean)),
                f"{'TP' if kind == 'slip' else 'TN'} rate {100 * mean.mean():.1f}{spread}",
                "100.0" if kind == "slip" else "0.0",
            ]
        )
    return Table(
        "Test sets of one class: not ranked.",
        ["Protocol", "Detector", *(("Sensor", "Finger")[: len(unit)])],
        "",
        [
            "Class tested",
            "Cells",
            "Rate (%): mean (range) over cells",
            'A constant "slip" detector (%)',
        ],
        lines,
        cells,
        "tab:one-class",
        notes=[
            "On a test set of one class, accuracy is that class's rate, and a detector that always "
            'says "slip" scores 100 % on slip-only data (0 % on non-slip-only): the figures say how '
            "often a detector calls that class, not whether it tells slip from non-slip, so no "
            "leaderboard or test ranks them."
        ],
    )


def _points(diff: float, lo: float, hi: float) -> str:
    text = f"{100 * diff:+.1f}"
    return text + (
        f" [{100 * lo:+.1f}, {100 * hi:+.1f}]" if np.isfinite(lo) and np.isfinite(hi) else ""
    )


#: why a pair lacks a full interval, in a word
_LACKS = {ONE_BLOCK: "one block", ONE_RUN: "one seed"}


def _differ(r) -> str:
    """``yes``, ``no``, or ``undecided`` with the noise its interval lacks."""
    if r.state != UNDECIDED:
        return DIFFER_WORDS[r.state]
    lacks = [word for reason, word in _LACKS.items() if reason in r.missing]
    return DIFFER_WORDS[UNDECIDED] + (f" ({', '.join(lacks)})" if lacks else "")


def _pairs_table(board: Leaderboard, name: str) -> Table:
    """Each pair of detectors: the mean difference over the ranked blocks with the interval its
    state reads, at the family's level."""
    pairs, overall = board.pairs, board.scopes[0]
    cells = [
        [
            _points(r.diff, r.lo, r.hi) + (_low(overall, r.a) or _low(overall, r.b)),
            "—" if not np.isfinite(r.p) else _p(r.p),
            _differ(r),
        ]
        for r in pairs.itertuples(index=False)
    ]
    n = overall.n_cells
    return Table(
        f"Pairwise: {name.lower()} of A minus B over the {n} ranked blocks (points).",
        ["A", "B"],
        "",
        [f"A − B [{100 * board.level:.4g} % interval]", "p (Bonferroni)", "Differ"],
        [(r.a, r.b) for r in pairs.itertuples(index=False)],
        cells,
        "tab:leaderboard-pairs",
        notes=[
            "A − B: the mean over the ranked blocks of A's figure minus B's (each the mean over its "
            "seeds); "
            + (
                _SEEDS_INTERVAL.format(n=board.n_seeds)[:-2]
                + "; paired seed by seed where both ran "
                "the same seeds"
                if board.n_seeds > 1
                else "[interval over the blocks alone, a t-interval on their spread"
            )
            + f"; {_family_text(board)}]. Differ: yes where the interval lies beyond the margin, no "
            "where it lies inside it, else undecided (the groups table's decided pairs are the yes and "
            "no rows); p: the Bonferroni-adjusted p-value of a change "
            f"within the margin, below {ALPHA:g} exactly where the pair differs; undecided, without p, "
            f"where {UNDECIDED_WHY}. Like the ranks, the interval covers which conditions make up the "
            "benchmark"
            + (" and the seeds" if board.n_seeds > 1 else "")
            + ", not the test noise within a block.",
            *_low_notes([overall]),
        ],
    )
