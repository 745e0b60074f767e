"""The leaderboard said: the tables of :func:`slipbench.stats.leaderboard.leaderboard` (mean
ranks per scope; mean figures with intervals and cells won; the Friedman and Wilcoxon-Holm
tests per scope) with the figures' names and the notes that say how to read them."""

from __future__ import annotations

import numpy as np

from slipbench.report.tables import Table
from slipbench.stats.leaderboard import ALL, ALPHA, MEAN_METRICS, Leaderboard
from slipbench.vocabulary import METRIC_NAMES


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
    won; the tests (Friedman, then Wilcoxon-Holm groups) per scope."""
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
                ],
            )
        ]
    order = board.order
    name = METRIC_NAMES.get(board.metric, board.metric)
    scopes = [s for s in board.scopes if s.n_cells]
    columns = [f"{'all' if s.name == ALL else s.name} ({s.n_cells})" for s in scopes]
    cells = [[f"{s.ranks[e]:.2f}" for s in scopes] for e in order]
    notes = [
        f"Mean rank of {name.lower()} over cells, in parentheses the cells ranked (1 = best): per cell the "
        "detectors are ranked by their figure (mean over seeds), ties sharing the mean rank. Only cells every "
        "detector finished are ranked"
        + (
            f"; {overall.n_excluded} {'cell was' if overall.n_excluded == 1 else 'cells were'} not (failed, skipped "
            "or absent for some detector)."
            if overall.n_excluded
            else "; every cell was."
        )
    ]
    if len(order) == 1:
        notes.append("One detector: nothing to rank it against.")
    tables = [
        Table(
            f"Leaderboard: detectors ranked by {name.lower()}.",
            ["Place", "Detector"],
            "Mean rank (cells)",
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
    mean_cols = [f"{METRIC_NAMES.get(m, m)} (%)" for m in shown] + ["Cells won"]
    mean_cells = [
        [_percent(*board.means.loc[e, [m, f"{m}_lo", f"{m}_hi"]]) for m in shown]
        + [str(int(overall.wins[e]))]
        for e in order
    ]
    fewer = [
        f"{METRIC_NAMES.get(m, m)} exists on {int(board.means[f'{m}_cells'].min())} of them (not on a one-class "
        "test set)"
        for m in shown
        if board.means[f"{m}_cells"].min() < overall.n_cells
    ]
    tables.append(
        Table(
            f"Mean figures over the {overall.n_cells} ranked cells.",
            ["Detector"],
            "",
            mean_cols,
            [(e,) for e in order],
            mean_cells,
            "tab:leaderboard-means",
            notes=[
                "[95 % interval: percentile bootstrap over the ranked cells, each cell's figure fixed: how "
                "the mean depends on which conditions make up the benchmark, not the test noise within a "
                "cell, which the per-cell intervals show.] Cells won: cells where the detector ranked first "
                "(a tie counts for each)." + (" " + "; ".join(fewer) + "." if fewer else "")
            ],
        )
    )
    if len(order) >= 2:
        test_cells = []
        for s in scopes:
            chi = "—" if s.friedman is None else f"{s.friedman[0]:.1f}"
            p = "—" if s.friedman is None else _p(s.friedman[1])
            groups = (
                "; ".join("{" + ", ".join(g) + "}" for g in s.groups) or "none: every pair differs"
            )
            if len(order) == 2:  # no Friedman test: the one pair's own p-value
                p2 = float(s.pairs["p"].iloc[0])
                groups += f" (Wilcoxon p {'< 0.001' if p2 < 0.001 else f'= {p2:.3f}'})"
            test_cells.append([str(s.n_cells), chi, p, groups])
        tables.append(
            Table(
                "Do the detectors differ? Friedman test per scope, then pairwise Wilcoxon signed-rank tests.",
                ["Scope"],
                "",
                ["Cells", "Friedman χ²", "p", f"Groups that do not differ (Holm, α = {ALPHA:g})"],
                [("all" if s.name == ALL else s.name,) for s in scopes],
                test_cells,
                "tab:leaderboard-tests",
                wrap={4: 0.4},
                notes=[
                    (
                        f"Friedman's χ² has {len(order) - 1} degrees of freedom. "
                        if len(order) >= 3
                        else "Friedman's test needs three detectors or more. "
                    )
                    + "A group lists detectors, in rank order, no pair of which differs after Holm's correction "
                    "across the scope's pairs; a detector in no group differs from every other. Cells share "
                    "recordings (window 50 of a unit appears in several protocols), so they are not "
                    "independent blocks and these p-values are optimistic."
                ],
            )
        )
    return tables
