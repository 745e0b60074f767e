"""A table's line to beat: each entrant's change from the reference detector, and the words
of a contrast's state in a table."""

from __future__ import annotations

from collections.abc import Sequence

from slipbench.report.blocks import LOW_MARK, Table
from slipbench.report.tables import figure_label
from slipbench.stats.contrast import (
    CONTRADICTED,
    ONE_SEED,
    SHOWN,
    UNDECIDED,
    Contrast,
)
from slipbench.store.columns import ACCURACY, FIGURES
from slipbench.vocabulary import LOW_N

# ----------------------------------------------------------------------------- verdict words
#: a contrast's state (:mod:`slipbench.stats.contrast`) in a table's "Differ" column: the one
#: place these words are defined; "decided" counts the yes and no rows
DIFFER_WORDS = {SHOWN: "yes", CONTRADICTED: "no", UNDECIDED: "undecided"}


# ----------------------------------------------------------------------------- the line to beat
VERSUS = "vs baseline"


def change_text(change: Contrast) -> str:
    """A change of :func:`slipbench.stats.contrast.paired_change` in points (its figure a
    fraction): ``+3.2 [+1.0, +5.4]``; why there is none where no cell and seed was paired."""
    if change.n_cells == 0:
        return change.missing
    text = f"{100 * change.estimate:+.1f}"
    if change.judged:
        text += f" [{100 * change.lo:+.1f}, {100 * change.hi:+.1f}]"
    return text


def add_versus(
    table: Table,
    changes: Sequence[tuple[Contrast, int] | None],
    reference: str,
    figure: str,
) -> None:
    """``table`` (a line per entrant) with a last column: each line's change of ``figure`` from
    the ``reference`` detector (``changes``, in the table's line order: the change and how many
    of its paired cells are low-n; None: a reference line, marked so), and notes saying how,
    what was left out and what the intervals lack."""
    # accuracy is the default; another figure (``--metric``, a stream's rate) says which it is
    named = "" if figure == ACCURACY.name else f", {figure_label(figure).lower()}"
    header = f"{VERSUS}{named} ({reference})"
    table.columns.append(header)
    for line, pair in zip(table.cells, changes):
        low = pair is not None and pair[1] > 0
        line.append("reference" if pair is None else change_text(pair[0]) + LOW_MARK * low)
    shown = [(entrant, p[0]) for (entrant, *_), p in zip(table.rows, changes) if p is not None]
    how = "; ".join(sorted({c.method for _, c in shown if c.method}))
    table.notes.append(
        f"{header}: each detector's {FIGURES[figure].called} minus the reference's, in points, the "
        "mean over the cells and seeds both finished (the same cells, input and split), paired "
        "seed by seed, with its 95 % interval (each line's alone, not simultaneous)"
        f"{': ' + how if how else ''}."
    )
    if any(p is not None and p[1] for p in changes):
        table.notes.append(
            f"{header}: {LOW_MARK} the change rests on cells of few test trials (fewer than "
            f"{LOW_N} of a class): not to be trusted."
        )
    table.notes += [
        f"{header}, {entrant}: left out: {'; '.join(c.left_out)}."
        for entrant, c in shown
        if c.left_out and c.n_cells
    ]
    # what else a change lacks (its interval not estimable: the cells named), said beside it
    table.notes += [
        f"{header}, {entrant}: undecided: {c.missing}."
        for entrant, c in shown
        if c.n_cells and c.missing not in ("", ONE_SEED)
    ]
    one = [entrant for entrant, c in shown if c.n_cells and c.missing == ONE_SEED]
    if one:
        table.notes.append(
            f"{header}: {', '.join(one)} paired with the reference on one seed: the interval "
            "holds the test trials' noise only, not retraining noise, so it decides nothing "
            "(run `evaluate --repeats 2` or more on both)."
        )
