"""Two result sets -> per-cell changes with paired intervals, pooled tests per protocol and
detector, and a CI verdict.

Cells are paired as :mod:`slipbench.stats.sides` pairs them, and each cell's change gets
its interval as :mod:`slipbench.stats.changes` draws it.

Verdicts. The gate's figures and tolerances (:class:`slipbench.gate.gate.Gate`: accuracy, TP
and TN rate of windowed cells; detection rate, median delay and false alarms per minute of
streaming cells) are judged at ``ALPHA`` (5 %), split by the union bound: ``POOLED_ALPHA``
(2.5 %) for the pooled tests, one per protocol, detector and figure (:mod:`slipbench.stats.pooled`),
and ``CELL_ALPHA`` (2.5 %) for the cells, every figure of the cells both sides finished that
changed and are not low-n. Each family's intervals are Bonferroni's (``1 - alpha / m``, ``m``
its tests), and every verdict reads the interval printed beside it against its tolerance, as
every contrast does (:func:`slipbench.stats.contrast.state_of`): beyond the tolerance on the
worse side, *regressed*; on the better side, *improved*; inside it, *within margin*. (Holm's
step-down, used before, decided cells whose printed Bonferroni interval did not show it.) A cell
also *regressed* when the candidate failed, timed out or skipped a cell the base finished;
*improved* when a figure is better and none worse; *within margin* when every figure's is;
*inconclusive* when the cell is low-n (its intervals undercover) or its interval, deciding
nothing, is wider than ``max_width`` points (``MAX_WIDTH``, 40); otherwise *no significant
change*. A pooled test that flags nothing states its power and may be *undecided*
(:mod:`slipbench.gate.gate`); :attr:`Comparison.state` turns all of it into the exit code.

Looks. A gate with a budget (:class:`~slipbench.gate.gate.Gate` ``seeds`` and ``budget``, a
bench's ``repeats`` and ``[gate] budget``) decides at the look the stored seeds make
(:func:`look_at`): each family's intervals at that look's share of its error
(:func:`look_level`, Lan-DeMets O'Brien-Fleming), and before the last look a pooled test
passes only where the worse bound of its interval at the family's level lies inside its
tolerance. Noise. Seed noise measured outside the comparison (a bench's calibration; any
:class:`~slipbench.stats.noise.NoiseSource`) enters every cell and pooled test where a source
answers (:func:`measured_noise`, the one place where sources are combined).

This module decides; it writes no text. The pull-request comment and the JSON for bots are
written from a :class:`Comparison` by the report wing.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
import scipy  # its submodules load on first use: reading stored rows pays none

from slipbench.errors import EXIT_REGRESSION, EXIT_UNDECIDED
from slipbench.gate.changes import cell_changes, pool_of, seed_pools
from slipbench.gate.gate import (
    Gate,
    needed,
    resolution,
    scaled_resolution,
    two_sided_p,
    unit,
)
from slipbench.gate.power import Design, looks, nominal_levels
from slipbench.gate.sides import decidable, finished, plan_cells, read_sides
from slipbench.stats.bootstrap import IntervalSpec
from slipbench.stats.contrast import CONTRADICTED, SHOWN, family_level, level_text, state_of
from slipbench.stats.metrics import (
    FIGURES,
    LEVEL,
    RATES,
)
from slipbench.stats.noise import NoiseSource, SeedNoise, combined
from slipbench.stats.pooled import (
    cell_sides,
    pooled_change,
    pooled_from_rows,
)
from slipbench.store import columns
from slipbench.vocabulary import LOW_N

ALPHA = 1 - LEVEL
# The family: the chance that a run calls anything regressed or improved wrongly is held at
# ALPHA, split evenly between the pooled tests (Bonferroni over protocols x detectors x figures)
# and the cells (Bonferroni over the cells' figures); by the union bound the two hold ALPHA.
POOLED_ALPHA = ALPHA / 2
CELL_ALPHA = ALPHA / 2
# a cell whose change interval is wider than this (accuracy points, streams: detection rate)
# cannot tell a real change from none: "inconclusive", never "no significant change"
MAX_WIDTH = 40.0
# seeds per side from which retraining noise enters the intervals (two measure its spread
# at all, with one degree of freedom; three is what the null study runs and what CI should)
MIN_SEEDS = 2
RECOMMENDED_REPEATS = 3
# the verdicts a cell can get, in the order counts of them are given
VERDICTS = (
    "regressed",
    "mixed",
    "improved",
    "worse",
    "better",
    "within margin",
    "no significant change",
    "inconclusive",
    "identical",
)


@dataclass(frozen=True)
class Look:
    """Which look of the gate a comparison is: ``index`` (0: the first) of the looks at
    ``seeds`` per side; ``final`` where the budget is reached (or the gate looks once), else
    ``next_seeds``: the seeds per side of the next look."""

    index: int
    seeds: int
    final: bool
    next_seeds: int


def look_at(gate: Gate, held: int) -> Look:
    """The look of ``gate`` that ``held`` seeds per side (the fewest any compared cell holds)
    make: the last of its looks at or below them; final from the budget on."""
    if not gate.sequential:
        return Look(0, held, True, 0)
    at = looks(gate.seeds, gate.budget)
    index = max(0, sum(s <= held for s in at) - 1)
    final = held >= gate.budget
    return Look(index, held, final, 0 if final else next(s for s in at if s > held))


def look_level(gate: Gate, look: Look, tests: int, alpha: float) -> float:
    """The two-sided level of each of ``tests`` intervals of a family held at ``alpha`` at
    ``look``: Bonferroni's ``1 - alpha / tests`` where the gate looks once; with looks, twice
    the look's nominal one-sided level (Lan-DeMets O'Brien-Fleming over the budget,
    :func:`slipbench.stats.power.nominal_levels`) off 1."""
    if not gate.sequential:
        return family_level(tests, alpha)
    design = Design(gate.seeds, gate.budget, max(1, tests), alpha)
    return 1 - 2 * nominal_levels(design)[look.index]


def measured_noise(
    sources: Sequence[NoiseSource],
    cell: tuple[str, str, str | None],
    figure: str,
    paired: bool,
) -> SeedNoise | None:
    """The seed noise the gate takes from outside the comparison for ``cell`` (detector,
    protocol, and the cell or None for the protocol's mean) and ``figure``: every source's
    answer, combined (:func:`slipbench.stats.noise.combined`). None where none answers: the
    sides' own seeds carry it."""
    detector, protocol, name = cell
    return combined(
        n
        for s in sources
        if (n := s.seed_noise(detector, protocol, figure, name, paired)) is not None
    )


@dataclass
class Comparison:
    """The outcome of :func:`compare`."""

    # one row per paired cell: changes, simultaneous intervals, verdict and the figures that
    # regressed; in the order the pairing found them (the writers put them in the paper's order)
    cells: pd.DataFrame
    only_base: pd.DataFrame  # cells in BASE only: protocol, detector, split, seed, cell
    only_candidate: pd.DataFrame
    base: str
    candidate: str
    gate: Gate = field(default_factory=Gate)
    notes: list[str] = field(default_factory=list)
    level: float = LEVEL  # the simultaneous level of every cell's interval
    # both sides' result rows as read: what the writers lay the protocols out from
    rows: pd.DataFrame | None = None
    # one row per protocol, detector and figure: the mean change over its cells in the
    # figure's units, its joint interval (at ``pooled_level``), Bonferroni-adjusted p, power
    # (``resolution``, ``detectable``) and verdict
    pooled: pd.DataFrame = field(default_factory=pd.DataFrame)
    pooled_level: float = LEVEL
    # seeds per cell on each side: the fewest over the compared cells (1: retraining noise of
    # that side is not in the intervals)
    min_seeds_base: int = 1
    min_seeds_candidate: int = 1
    # the look the stored seeds imply (:func:`look_at`) and where the seed noise came from
    # besides the sides' own seeds (the sources' words, "" where none answered)
    look: Look = field(default_factory=lambda: Look(0, 1, True, 0))
    measured: str = ""
    # the level of the cells' intervals printed and read where the look flags nothing (the
    # cells' family's, Bonferroni at CELL_ALPHA, before the last look; ``level`` at it): a cell
    # the look flags (``read_at_look``) prints its interval at ``level``
    read_level: float = LEVEL
    # what the comment's first line says of who judged (the base's bench where the
    # candidate's differs, a calibration refused), and the work the base's bench ran that
    # the candidate lost (a detector, protocol or cells it holds no row of): a regression
    headline: list[str] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)

    @property
    def regressions(self) -> pd.DataFrame:
        return self.cells[self.cells["verdict"] == "regressed"]

    @property
    def pooled_regressions(self) -> pd.DataFrame:
        if self.pooled.empty:
            return self.pooled
        return self.pooled[self.pooled["verdict"] == "regressed"]

    @property
    def undecided(self) -> pd.DataFrame:
        if self.pooled.empty:
            return self.pooled
        return self.pooled[self.pooled["verdict"] == "undecided"]

    @property
    def state(self) -> str:
        """ "regressed": a cell the base finished failed on the candidate or is missing from it
        (:attr:`missing`), or a figure regressed
        with retraining noise inside the intervals; "undecided": a figure regressed on one seed
        per side, or a pooled test cannot see a regression of its tolerance (too few seeds or
        trials) or, before the gate's last look, cannot yet rule one out; else "no
        regression"."""
        failed = self.regressions["method"].astype(str).str.startswith("status").any()
        if (
            failed
            or self.missing
            or (self.retraining_covered and (len(self.regressions) or len(self.pooled_regressions)))
        ):
            return "regressed"
        if len(self.regressions) or len(self.pooled_regressions) or len(self.undecided):
            return "undecided"
        return "no regression"

    @property
    def exit_code(self) -> int:
        """0 no regression, 1 regressed, 6 undecided (:attr:`state`)."""
        return {"regressed": EXIT_REGRESSION, "undecided": EXIT_UNDECIDED}.get(self.state, 0)

    @property
    def unchanged(self) -> bool:
        """Every paired cell identical on both sides and no cell on one side only."""
        return bool(
            (self.cells["verdict"] == "identical").all()
            and self.only_base.empty
            and self.only_candidate.empty
        )

    @property
    def retraining_covered(self) -> bool:
        return min(self.min_seeds_base, self.min_seeds_candidate) >= MIN_SEEDS


def compare(
    base_path: str | os.PathLike,
    candidate_path: str | os.PathLike,
    gate: Gate | None = None,
    seed: int = 0,
    sources: Sequence[NoiseSource] = (),
) -> Comparison:
    """Compare CANDIDATE against BASE cell by cell, and per protocol, detector and figure pooled.

    Parameters
    ----------
    base_path, candidate_path
        Results files or folders (as ``evaluate --out`` writes them).
    gate : Gate
        The figures judged and the tolerance of each (default: every figure,
        ``slipbench.gate.gate.DEFAULT_TOLERANCE``), and its looks: the comparison decides at
        the look its stored seeds make (:func:`look_at`).
    seed : int
        Seeds the paired bootstraps.
    sources : NoiseSource
        Seed noise measured outside the comparison (a bench's calibration that holds): where
        one answers for a cell or a protocol's mean, it takes the place of the sides' own
        seed spread, with its degrees of freedom (:func:`measured_noise`).

    Raises
    ------
    DataError
        The sides come from different datasets, a side repeats a key or a cell and seed, or
        they share no cell.
    """
    gate = gate or Gate()
    base, cand, on, notes = read_sides(base_path, candidate_path)
    plans, only_base, only_cand = plan_cells(base, cand, on, (base_path, candidate_path))
    seeds = [(e["n_seeds_base"], e["n_seeds_cand"]) for e, *_ in plans if finished(e)]
    look = look_at(gate, min((min(b, c) for b, c in seeds), default=1))
    shared = shared_with([e for e, *_ in plans])
    n_tests = sum(
        len(gate.figures(e["stream"]))
        for (e, *_), s in zip(plans, shared)
        if decidable(e) and not s
    )
    level = look_level(gate, look, n_tests, CELL_ALPHA)
    pools = seed_pools(plans)
    noises = [_cell_noise(plan, pools, sources) for plan in plans]
    if look.final:
        cells = pd.DataFrame([cell_changes(p, seed, level, n) for p, n in zip(plans, noises)])
        cells["read_at_look"] = True
        read_level = level
    else:  # the look flags; a cell it does not flag is read at the family's level
        read_level = family_level(n_tests, CELL_ALPHA)
        at_look = [cell_changes(_copied(p), seed, level, n) for p, n in zip(plans, noises)]
        at_family = [cell_changes(p, seed, read_level, n) for p, n in zip(plans, noises)]
        flags = [_flags(r, gate) for r in at_look]
        cells = pd.DataFrame([a if f else b for a, b, f in zip(at_look, at_family, flags)])
        cells["read_at_look"] = flags
    cells = _judge_cells(cells, gate)
    cells["shared_with"] = shared
    pooled, pooled_level = _pooled_tests(plans, cells, IntervalSpec(seed, LEVEL), gate, sources)
    cmp = Comparison(
        cells,
        only_base,
        only_cand,
        str(base_path),
        str(candidate_path),
        gate,
        notes,
        level,
        pd.concat([base, cand], ignore_index=True),
        pooled,
        pooled_level,
        min((b for b, _ in seeds), default=1),
        min((c for _, c in seeds), default=1),
        look,
        _measured_sources(pooled),
        read_level,
    )
    if not pooled.empty:
        cmp.pooled = _pooled_verdicts(pooled, gate, cmp.retraining_covered, look)
    return cmp


def _copied(plan: tuple) -> tuple:
    """A cell's plan whose entry :func:`cell_changes` may fill without touching the plan's."""
    return (dict(plan[0]), *plan[1:])


def _flags(r: dict, gate: Gate) -> bool:
    """A cell's interval at the look's level lies beyond a figure's tolerance on either side:
    the look flags it."""
    return decidable(r) and any(
        _reading(r.get(f"d_{f}_lo", np.nan), r.get(f"d_{f}_hi", np.nan), f, gate.tolerances[f])
        in ("regressed", "improved")
        for f in gate.figures(bool(r["stream"]))
        if f"d_{f}" in r
    )


def shared_with(entries: list[dict]) -> list[str]:
    """Per cell, the protocol of an earlier cell that is the same cell (the same models
    tested on the same test set: :func:`slipbench.stats.sides._shared_key`), "" for the
    first of each: a cell shared by two protocols is one test in the family, counted once."""
    first: dict[str, str] = {}
    out = []
    for e in entries:
        key = str(e.get("shared") or "")
        out.append(first.get(key, "") if key else "")
        if key:
            first.setdefault(key, str(e["protocol"]))
    return out


def _cell_noise(
    plan: tuple, pools: dict, sources: Sequence[NoiseSource]
) -> dict[str, SeedNoise] | None:
    """A cell's seed noise per figure: the measured one (:func:`measured_noise`) where a
    source answers, else its protocol's cells' pooled spread (:func:`seed_pools`)."""
    entry, same_seeds = plan[0], bool(plan[4])
    where = (str(entry.get("base_detector")), str(entry["protocol"]), str(entry["cell"]))
    noise = dict(pools.get(pool_of(plan)) or {})
    for figure in FIGURES:
        found = measured_noise(sources, where, figure, same_seeds)
        if found is not None:
            noise[figure] = found
    return noise or None


def _measured_sources(pooled: pd.DataFrame) -> str:
    """The sources of measured seed noise the pooled tests took, in words ("" where none)."""
    return " and ".join(dict.fromkeys(str(x) for x in pooled.get("noise", []) if x))


def _reading(lo: float, hi: float, figure: str, tolerance: float) -> str:
    """What an interval of a change of ``figure`` (stored units) says against ``tolerance``
    (the figure's change units): "regressed" or "improved" where it lies beyond the tolerance
    on one side, "within margin" where inside it (the contrast's states,
    :func:`slipbench.stats.contrast.state_of`); "worse" or "better" where it lies wholly on
    one side of no change without clearing the tolerance (a change its interval shows, never
    "no significant change"); else ""."""
    declared = columns.FIGURES[figure]
    margin = tolerance / declared.scale
    state = state_of(lo, hi, margin)
    if state == CONTRADICTED:
        return "within margin"
    if state == SHOWN:
        up, words = lo > margin, ("regressed", "improved")
    elif lo > 0 or hi < 0:
        up, words = lo > 0, ("worse", "better")
    else:
        return ""
    return words[0] if up == (declared.worse > 0) else words[1]


def _beyond(r: dict, figure: str, tolerance: float) -> bool:
    """The cell's change of ``figure`` lies beyond its tolerance on the worse side (its
    estimate, whatever its interval)."""
    declared = columns.FIGURES[figure]
    d = float(r.get(f"d_{figure}", np.nan))
    return bool(declared.worse * d * declared.scale > tolerance)


def _judge_cells(cells: pd.DataFrame, gate: Gate) -> pd.DataFrame:
    """Each cell's verdict, read from its figures' intervals against their tolerances (at the
    look's level where the look flags the cell, ``read_at_look``, else at the cells' family's
    level: there a change beyond the tolerance is "worse" or "better", never flagged); the
    figures that regressed are named."""
    if "df" not in cells:
        cells["df"] = np.inf
    if "read_at_look" not in cells:
        cells["read_at_look"] = True
    cells["df"] = np.where(cells["stream"].astype(bool), np.inf, cells["df"])
    can = cells.apply(decidable, axis=1).to_numpy(bool)
    records = cells.to_dict("records")
    readings = [
        {
            f: _unflagged(
                _reading(
                    r.get(f"d_{f}_lo", np.nan), r.get(f"d_{f}_hi", np.nan), f, gate.tolerances[f]
                ),
                bool(r["read_at_look"]),
            )
            for f in gate.figures(bool(r["stream"]))
            if f"d_{f}" in r
        }
        if ok
        else {}
        for r, ok in zip(records, can)
    ]
    verdicts = [
        _cell_verdict(r, read, gate, any(_beyond(r, f, gate.tolerances[f]) for f in read))
        for r, read in zip(records, readings)
    ]
    cells["verdict"] = [v for v, _ in verdicts]
    cells["inconclusive_reason"] = [why for _, why in verdicts]
    cells["regressed_figures"] = [
        ", ".join(f for f, said in read.items() if said == "regressed") for read in readings
    ]
    return cells


#: a change beyond the tolerance that the look did not flag, read at the family's level
BEYOND_UNFLAGGED = "beyond its tolerance, not flagged at this look"


def _unflagged(word: str, at_look: bool) -> str:
    """A figure's reading where the look did not flag its cell: a change beyond the tolerance
    is claimed only where a look flags it, so it reads worse (or better)."""
    if at_look:
        return word
    return {"regressed": "worse: " + BEYOND_UNFLAGGED, "improved": "better"}.get(word, word)


def _cell_verdict(r: dict, read: dict[str, str], gate: Gate, beyond: bool) -> tuple[str, str]:
    """A cell's verdict from its figures' readings (:func:`_reading`) and, where inconclusive,
    why; ``beyond``: some figure's estimate lies beyond its tolerance on the worse side. A cell
    better beyond the tolerance on one figure and worse on another (shown worse, or its
    estimate beyond the tolerance) is "mixed", never "improved"."""
    if not finished(r):
        if r["base_status"] == "ok":
            return "regressed", ""  # the candidate no longer finishes a cell the base finished
        return ("improved" if r["candidate_status"] == "ok" else "no significant change"), ""
    if r["identical"]:
        return "identical", ""
    if r["method"] == "streams over several seeds: not compared":
        return "inconclusive", "streaming cells over several seeds are not compared"
    if r["low_n"]:
        return "inconclusive", f"low n (fewer than {LOW_N} test trials of a class)"
    said = {w.split(":")[0] for w in read.values()}
    if "regressed" in said:
        return "regressed", ""
    if said & {"improved", "better"} and ("worse" in said or beyond):
        return "mixed", ""
    if "improved" in said:
        return "improved", ""
    if "worse" in said:  # a change its interval shows, whatever its width
        return "worse", (BEYOND_UNFLAGGED if any(":" in w for w in read.values()) else "")
    if "better" in said:
        return "better", ""
    width = primary_change(r, "_hi") - primary_change(r, "_lo")
    if not width <= gate.max_width:
        return "inconclusive", f"interval wider than {gate.max_width:g} points"
    inside = len(read) > 0 and said == {"within margin"}
    return ("within margin" if inside else "no significant change"), ""


def _pooled_groups(plans: list, cells: pd.DataFrame) -> dict[tuple, list]:
    """Per protocol and detector, the finished cells that are compared (not streams over
    several seeds), each (row, (base preds, candidate preds, base rows, candidate rows))."""
    groups: dict[tuple, list] = {}
    for (entry, b_rows, c_rows, preds, _), r in zip(plans, cells.to_dict("records")):
        if finished(entry) and not str(r["method"]).startswith("streams over several"):
            groups.setdefault((entry["protocol"], entry["detector"]), []).append(
                (r, (*preds, b_rows, c_rows))
            )
    return {g: m for g, m in groups.items() if any(not r["identical"] for r, _ in m)}


def _pooled_tests(
    plans: list, cells: pd.DataFrame, spec: IntervalSpec, gate: Gate, sources: Sequence
) -> tuple[pd.DataFrame, float]:
    """Per protocol, detector and judged figure: the mean change over the cells both sides
    finished (identical ones count 0), with its interval at the level of the look (over the
    pooled tests, :func:`look_level`); verdicts come from :func:`_pooled_verdicts`."""
    groups = _pooled_groups(plans, cells)
    tests = [
        (g, figure)
        for g, members in groups.items()
        for figure in gate.figures(bool(members[0][0]["stream"]))
    ]
    seeds = [min(e["n_seeds_base"], e["n_seeds_cand"]) for e, *_ in plans if finished(e)]
    level = look_level(gate, look_at(gate, min(seeds, default=1)), len(tests), POOLED_ALPHA)
    lines = []
    for g, figure in tests:
        where = (str(groups[g][0][0].get("base_detector")), str(g[0]), None)

        def noise(paired: bool, where: tuple = where, figure: str = figure) -> SeedNoise | None:
            return measured_noise(sources, where, figure, paired)

        lines.append(_pooled_line(g, groups[g], figure, IntervalSpec(spec.seed, level), noise))
    return pd.DataFrame(lines), level


def _pooled_line(
    group: tuple,
    members: list,
    figure: str,
    spec: IntervalSpec,
    noise: Callable[[bool], SeedNoise | None],
) -> dict:
    """One pooled test: the mean change of ``figure`` over a protocol's cells, in its units;
    ``noise``: its seed noise measured elsewhere, for sides of the same seeds or apart."""
    seed, level = spec.seed, spec.level
    changed = [(r, p) for r, p in members if not r["identical"]]
    share = len(changed) / len(members)  # identical cells add 0 to the mean
    line: dict[str, Any] = {
        "protocol": group[0],
        "detector": group[1],
        "figure": figure,
        "cells": len(members),
        "changed_cells": len(changed),
        "seeds": min(min(len(p[2]), len(p[3])) for _, p in changed),
        "trials": np.nan,
    }
    preds = [p for _, p in changed]
    if figure in RATES and all(x is not None for b, c, *_ in preds for x in (*b, *c)):
        res = pooled_change([cell_sides(*p) for p in preds], seed, level, figure, noise)
        line["method"] = "joint cluster bootstrap over the trials the cells share" + (
            f" and {res['seed_design']}" if res["seeds"] else ""
        )
        line["noise"] = res["noise"]
        line["low_n"] = res["low_n"]
        line["trials"] = min(res["n_test_clusters_slip"], res["n_test_clusters_nonslip"])
    else:  # rows only: the cells' errors taken as moving together (the widest case)
        rows = [r for r, _ in changed if np.isfinite(r[f"d_{figure}"])]
        res = (
            pooled_from_rows(
                [r[f"d_{figure}"] for r in rows],
                [r[f"d_{figure}_se"] for r in rows],
                [r.get("df", np.inf) for r in rows],
                level,
            )
            if rows
            else dict.fromkeys(("d", "lo", "hi", "se", "df"), np.nan)
        )
        line["method"] = "mean of the cells' standard errors (no predictions to pool)"
        line["low_n"] = all(r["low_n"] for r, _ in changed)
    for name in ("d", "lo", "hi", "se"):
        line[f"change{'' if name == 'd' else '_' + name}"] = (
            columns.FIGURES[figure].scale * share * res[name]
        )
    line["df"] = res["df"]
    return line


def _pooled_verdicts(
    pooled: pd.DataFrame, gate: Gate, retrained: bool, look: Look | None = None
) -> pd.DataFrame:
    """Each pooled test read from one interval, the one the comment prints beside it
    (``read_lo``, ``read_hi`` at ``read_level``, in the figure's change units).

    A regression (or improvement) is flagged only where the interval at the ``look``'s level
    (``change_lo``, ``change_hi``: Bonferroni over the pooled tests, each look at its
    O'Brien-Fleming share of ``POOLED_ALPHA``) lies beyond the tolerance; that interval is the
    one read where it flags and at the last look. Before the last look, a test that does not
    flag is read from its interval at the family's level (Bonferroni over the pooled tests at
    ``POOLED_ALPHA``, no share spent: stopping to say "no regression" raises no false alarm):
    "no regression" where that interval's worse end (``bound``, the drop it leaves open) lies
    inside the tolerance. ``p``: the Bonferroni-adjusted p-value of a change within the
    tolerance (below ``POOLED_ALPHA`` exactly where the family's interval lies beyond it). A
    test that flags nothing is "undecided" where its data are low-n or a side ran one seed;
    before the last look, where ``bound`` lies beyond its tolerance; at the last look, where
    its power (``resolution``, ``detectable``) cannot see a regression of its tolerance."""
    look = look or Look(0, 1, True, 0)  # one look
    pooled = pooled.copy()
    sign = np.array([columns.FIGURES[f].worse for f in pooled["figure"]], float)
    scale = np.array([columns.FIGURES[f].scale for f in pooled["figure"]], float)
    tol = pooled["figure"].map(gate.tolerances).to_numpy(float)
    change = pooled["change"].to_numpy(float)
    se, df = pooled["change_se"].to_numpy(float), pooled["df"].to_numpy(float)
    p_reg, p_imp = two_sided_p(sign * change, se, df, tol)
    pooled["p"] = np.minimum(1.0, len(pooled) * np.minimum(p_reg, p_imp))
    pooled["tolerance"] = tol
    family = family_level(len(pooled), POOLED_ALPHA)
    at_look = look_level(gate, look, len(pooled), POOLED_ALPHA)
    with np.errstate(invalid="ignore"):
        q = scipy.stats.t.ppf(0.5 + family / 2, df)
    flags = np.array(
        [
            _reading(lo / k, hi / k, f, t) in ("regressed", "improved")
            for lo, hi, k, f, t in zip(
                pooled["change_lo"], pooled["change_hi"], scale, pooled["figure"], tol
            )
        ],
        bool,
    )
    from_look = flags | look.final
    pooled["flags"] = flags
    pooled["look_level"] = at_look
    pooled["read_level"] = np.where(from_look, at_look, family)
    pooled["read_lo"] = np.where(from_look, pooled["change_lo"], change - q * se)
    pooled["read_hi"] = np.where(from_look, pooled["change_hi"], change + q * se)
    # the drop the printed interval leaves open: its worse end, as a drop
    pooled["bound"] = np.where(sign > 0, pooled["read_hi"], -pooled["read_lo"])
    pooled["final"], pooled["next_seeds"] = look.final, look.next_seeds
    # the family's error at this look, as the resolution takes it
    alpha = len(pooled) * (1 - at_look)

    def resolve(s: float, d: float) -> float:
        return resolution(s, d, len(pooled), alpha)

    pooled["resolution"] = [resolve(s, d) for s, d in zip(se, df)]
    pooled["detectable"] = tol + pooled["resolution"]
    pooled["seeds_needed"] = [
        needed(n, t, scaled_resolution(n, s, d, True, resolve))
        if n >= MIN_SEEDS
        else RECOMMENDED_REPEATS
        for n, s, d, t in zip(pooled["seeds"], se, df, tol)
    ]
    pooled["trials_needed"] = [
        needed(n, t, scaled_resolution(n, s, d, False, resolve))
        for n, s, d, t in zip(pooled["trials"], se, df, tol)
    ]
    judged = [_pooled_verdict(r, retrained) for r in pooled.to_dict("records")]
    pooled["verdict"] = [v for v, _ in judged]
    pooled["undecided_reason"] = [why for _, why in judged]
    return pooled


def _pooled_verdict(r: dict, retrained: bool) -> tuple[str, str]:
    """One pooled test's verdict from the interval it reads (:func:`_pooled_verdicts`)."""
    scale = columns.FIGURES[r["figure"]].scale  # the change is in the figure's change units
    read = _reading(r["read_lo"] / scale, r["read_hi"] / scale, r["figure"], r["tolerance"])
    if r["flags"] and not r["low_n"]:
        return read, ""
    if r["low_n"]:
        return "undecided", f"low n (fewer than {LOW_N} test trials of a class)"
    if not retrained:
        return "undecided", "one seed per side: retraining noise is not in the interval"
    u = unit(r["figure"])
    if not r["final"]:
        wait = f"at {r['seeds']} seeds a side; the next look runs {r['next_seeds']}"
        if read == "regressed":  # beyond the tolerance at the family's level, not the look's
            return "undecided", (
                f"a drop beyond its tolerance, not flagged at this look (whose own "
                f"{level_text(r['look_level'])} interval is [{r['change_lo']:+.2g}, "
                f"{r['change_hi']:+.2g}] {u}) {wait}"
            )
        if r["bound"] <= r["tolerance"]:
            # a change beyond the tolerance is claimed only where a look flags it
            return {"improved": "better"}.get(read, read) or "no significant change", ""
        return "undecided", f"a drop of up to {r['bound']:.2g} {u} is not ruled out {wait}"
    if not r["resolution"] <= r["tolerance"]:
        return "undecided", (
            f"it would flag a drop of {r['detectable']:.2g} {u} with 80 % power, "
            f"more than twice its tolerance"
        )
    return (read or "no significant change"), ""


def _figure(r: dict) -> str:
    """The figure a cell is summarised by: accuracy, or a stream's detection rate."""
    return (columns.DETECTION_RATE if r["stream"] else columns.ACCURACY).name


def primary_change(r: dict, bound: str = "") -> float:
    """The change of a cell's summarising figure (accuracy, or a stream's detection rate) in
    points, or with ``bound`` "_lo"/"_hi" its interval's bound."""
    return 100 * float(r.get(f"d_{_figure(r)}{bound}", np.nan))


def summary(cmp: Comparison) -> pd.DataFrame:
    """Per protocol and detector (in the order of ``cmp.cells``): cells compared and their
    verdicts, the mean change of the summarising figure (the pooled estimate where there is
    one) and the cell that changed most for the worse among those that decided something
    (``worst_row``: its index in ``cmp.cells``, None when none; inconclusive and identical
    cells are never the worst)."""
    pooled = {
        (r["protocol"], r["detector"]): r
        for r in cmp.pooled.to_dict("records")
        if r["figure"] in (columns.ACCURACY.name, columns.DETECTION_RATE.name)
    }
    lines = []
    for (protocol, detector), part in cmp.cells.groupby(["protocol", "detector"], sort=False):
        decided = part[~part["verdict"].isin(["inconclusive", "identical"])]
        changes = [
            (primary_change(r), i, r) for i, r in zip(decided.index, decided.to_dict("records"))
        ]
        finite = [c for c in changes if np.isfinite(c[0])]
        all_changes = [primary_change(r) for r in part.to_dict("records")]
        all_finite = [c for c in all_changes if np.isfinite(c)]
        # the first of equal changes, as the cells are ordered
        worst = min(finite, key=lambda c: c[0]) if finite else None
        verdicts = part["verdict"].value_counts()
        p = pooled.get((protocol, detector))
        lines.append(
            {
                "protocol": protocol,
                "detector": detector,
                "cells": len(part),
                "regressed": int(verdicts.get("regressed", 0)),
                "improved": int(verdicts.get("improved", 0)),
                "inconclusive": int(verdicts.get("inconclusive", 0)),
                "identical": int(verdicts.get("identical", 0)),
                "mean_change": p["change"]
                if p is not None
                else (float(np.mean(all_finite)) if all_finite else np.nan),
                "worst_row": worst[1] if worst is not None else None,
                **{
                    f"worst_{name}": primary_change(worst[2], bound)
                    if worst is not None
                    else np.nan
                    for name, bound in (("change", ""), ("lo", "_lo"), ("hi", "_hi"))
                },
            }
        )
    return pd.DataFrame(lines)


def repeats_note(cmp: Comparison) -> str:
    """Empty when every compared cell ran at least ``MIN_SEEDS`` seeds per side; else what the
    intervals leave out and how many repeats would cover it."""
    if cmp.retraining_covered:
        return ""
    sides = [
        name
        for name, n in (("BASE", cmp.min_seeds_base), ("CANDIDATE", cmp.min_seeds_candidate))
        if n < MIN_SEEDS
    ]
    return (
        f"retraining noise is not covered: {' and '.join(sides)} ran one seed per cell, so the "
        "intervals hold test-set noise only and a reseeded but equal detector can read as a change; "
        f"run `evaluate --repeats {RECOMMENDED_REPEATS}` on both sides (at least {MIN_SEEDS} seeds "
        "per side measure the spread between trainings)"
    )
