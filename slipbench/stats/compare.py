"""Two result sets -> per-cell changes with paired intervals, pooled tests per protocol and
detector, and a CI verdict.

Cells are paired on (protocol, cell key, split), and on the detector as well when both sides
hold the same detectors (comparing one detector's two versions); when each side holds a single
detector, they are compared with each other (comparing two detectors). Not on the seed: a side
may hold several seeds of a cell (``evaluate --repeats``), and the sides' seeds may differ. Two
result sets from different datasets (``dataset_fingerprint``) are refused before anything is
compared, and so is a side that holds a row twice (the same key, or the same cell and seed
under other settings); a cell and seed run again later with other code counts once, the latest
run (:func:`slipbench.stats.factors.latest_runs`), and the notes say how many were left out.

Seeds. A cell with one seed per side, the same on both, is compared window by window (below).
A cell with several seeds on a side, or different seeds, gets the two-level bootstrap over seeds
and trials of :func:`slipbench.stats.metrics.over_seeds` (its change: mean over the candidate's
seeds minus mean over the base's), so retraining noise is inside its interval; where both sides
ran the same seeds, seed k of each shares its split and the seeds pair (``paired=True``: the
seeds' differences are drawn, so the split's luck cancels). With one seed per side it is not,
and :func:`repeats_note` says so: a side needs ``MIN_SEEDS`` (2) seeds for a seed-to-seed
spread to exist; ``RECOMMENDED_REPEATS`` (3) is what the null study
(``benchmarks/bench_compare_null.py``) runs and what CI should.

The change of every figure (candidate - base) gets an interval. Where both sides stored their
test predictions (``predictions/<key>.parquet``), the windows are joined on (recording_id,
window_index) and the interval is the paired stratified cluster bootstrap of
:func:`slipbench.stats.metrics.paired_comparison` (clusters: the ``trial`` column where both
predictions files hold one, else the recording). Otherwise the change is judged from the two
rows alone (unpaired): the figures' bootstrap standard errors combined as independent, with the
smaller of the two rows' degrees of freedom. Two detectors tested on the same windows err
together more often than not, which only the paired path can see, so the unpaired interval errs
wide: on simulated cells (``tests/stats/test_compare.py``) it was wider in 39 of 40 cells (median 1.45
times) and found 0 of the 7 regressions the paired path found. Keep predictions to compare with
power.

Verdicts. The gate's figures and tolerances (:class:`slipbench.stats.gate.Gate`: accuracy, TN
and TP rate of windowed cells; false alarms per minute, detection rate and median delay of
streaming cells) are tested at ``ALPHA`` (5 %), split by the union bound: ``POOLED_ALPHA``
(2.5 %) for the pooled tests, one per protocol, detector and figure (:mod:`slipbench.stats.pooled`,
Holm over them, their intervals Bonferroni), and ``CELL_ALPHA`` (2.5 %) for the cells: Holm over
every figure of the cells both sides finished that changed and are not low-n, each a t-test of
the change against its tolerance; the intervals shown are at ``1 - CELL_ALPHA / m``, ``m`` those
tests. A cell *regressed* when a figure is worse than its tolerance, or when the candidate
failed, timed out or skipped a cell the base finished; *improved* when one is better and none
worse; *within margin* when every figure's interval lies inside plus or minus its tolerance;
*inconclusive* when the cell is low-n (its intervals undercover) or its interval, deciding
nothing, is wider than ``max_width`` points (``MAX_WIDTH``, 40); otherwise *no significant
change*. A pooled test that flags nothing states its power and may be *undecided*
(:mod:`slipbench.stats.gate`); :attr:`Comparison.state` turns all of it into the exit code.

Streaming cells (rows without ``accuracy``, with the streaming figures of
:mod:`slipbench.stream.cell`) are judged on their median delay, false alarms per minute and
detection rate at the detector's own threshold: figures counted on the streams' samples, the
same on every machine. The compute time per hop is this machine's; it is a separate check
(:func:`compare_compute`: is the candidate within the real-time budget, the hop period) that is
reported and never makes a verdict. Rows written before delays left out the compute time (they
hold ``compute_ms`` and no ``compute_ms_per_hop``) have machine-dependent delays and detection
rates (the compute time shortened the horizon): those two are not judged on them, only false
alarms. No per-onset predictions are stored, so the
change is unpaired: each row's 95 % bootstrap interval over trials gives its standard error
(half-width / 1.96; for delays at least hop / sqrt(12), the resolution of a score once a hop),
the two combined as independent, at the same simultaneous level as every
other cell. Both sides stream the same test trials, so their errors are positively correlated and
the independent combination overstates the spread of the change: the test is conservative (it
misses small regressions; it does not invent them). Each figure is judged against its
tolerance in the gate, as every other cell's.

This module decides; it writes no text. The pull-request comment and the JSON for bots are
written from a :class:`Comparison` by the report wing.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
import scipy  # scipy.stats loads on first use (see slipbench.stats)

from slipbench.errors import EXIT_REGRESSION, EXIT_UNDECIDED, DataError, UsageError
from slipbench.stats.bootstrap import IntervalSpec, SeedPool
from slipbench.stats.factors import (
    SETTINGS,
    differing_settings,
    factor_values,
    latest_runs,
    named_entrants,
    setting_name,
)
from slipbench.stats.gate import (
    SCALE,
    WORSE,
    Gate,
    holm,
    needed,
    resolution,
    scaled_resolution,
    two_sided_p,
    unit,
)
from slipbench.stats.metrics import FIGURES, LEVEL, Predictions, over_seeds, paired_comparison
from slipbench.stats.pooled import (
    RATE_MASKS,
    CellSides,
    pooled_change,
    pooled_from_rows,
    protocol_seed_pool,
)
from slipbench.store.results import (
    check_unique_keys,
    read_predictions,
    read_results,
    results_folder,
)
from slipbench.vocabulary import LOW_N

ALPHA = 1 - LEVEL
# The family: the chance that a run calls anything regressed or improved wrongly is held at
# ALPHA, split evenly between the pooled tests (Holm over protocols x detectors) and the cells
# (Bonferroni over the cells compared); by the union bound the two levels together hold ALPHA.
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
    "improved",
    "within margin",
    "no significant change",
    "inconclusive",
    "identical",
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
    # figure's units, its joint interval (at ``pooled_level``), Holm-adjusted p-value, power
    # (``resolution``, ``detectable``) and verdict
    pooled: pd.DataFrame = field(default_factory=pd.DataFrame)
    pooled_level: float = LEVEL
    # seeds per cell on each side: the fewest over the compared cells (1: retraining noise of
    # that side is not in the intervals)
    min_seeds_base: int = 1
    min_seeds_candidate: int = 1

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
        """ "regressed": a cell the base finished failed on the candidate, or a figure regressed
        with retraining noise inside the intervals; "undecided": a figure regressed on one seed
        per side, or a pooled test cannot see a regression of its tolerance (too few seeds or
        trials); else "no regression"."""
        failed = self.regressions["method"].astype(str).str.startswith("status").any()
        if failed or (
            self.retraining_covered and (len(self.regressions) or len(self.pooled_regressions))
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


def family_level(n_cells: int, alpha: float = ALPHA) -> float:
    """The level of each of ``n_cells`` intervals that holds them all at once with probability
    at least ``1 - alpha`` (Bonferroni): ``1 - alpha / n_cells``."""
    return 1 - alpha / max(1, n_cells)


def check_same_dataset(base: pd.DataFrame, cand: pd.DataFrame) -> list[str]:
    """Refuse two result sets computed on different datasets; notes where it cannot be checked."""
    fingerprints = []
    for rows in (base, cand):
        col = rows["dataset_fingerprint"] if "dataset_fingerprint" in rows else pd.Series(dtype=str)
        fingerprints.append(set(col.dropna().astype(str)) - {""})
    fb, fc = fingerprints
    if fb and fc and fb != fc:
        raise DataError(
            f"BASE and CANDIDATE were computed on different datasets (fingerprints {', '.join(sorted(fb))} vs "
            f"{', '.join(sorted(fc))}): their cells test different windows and cannot be compared; evaluate "
            "both on the same dataset"
        )
    if not (fb and fc):
        return [
            "A side holds no dataset fingerprint, so that both used the same dataset was not checked."
        ]
    return []


def _pairing(base: pd.DataFrame, cand: pd.DataFrame) -> list[str]:
    on = ["protocol", "cell", "split"]  # not the seed: a side may hold several per cell
    for side, rows in (("BASE", base), ("CANDIDATE", cand)):
        missing = {*on, "seed"} - set(rows.columns)
        if missing:
            raise DataError(f"{side}: results lack the columns {', '.join(sorted(missing))}")
    b, c = set(base["detector"]), set(cand["detector"])
    if b == c:
        return [*on, "detector"]
    if len(b) == 1 and len(c) == 1:
        return on
    raise UsageError(
        f"cannot pair detectors: BASE holds {', '.join(sorted(b))}, CANDIDATE holds {', '.join(sorted(c))}; "
        "compare results of the same detectors, or of one detector on each side"
    )


def _kept_apart(
    base: pd.DataFrame, cand: pd.DataFrame
) -> tuple[pd.DataFrame, pd.DataFrame, list[str], list[str]]:
    """Both sides with each detector named as its entrant (parameters, input, normalization:
    :func:`slipbench.stats.factors.entrant_names`), the settings that differ within a side (so
    that cells pair on them too, never pooling two of their values as seeds of one cell), and a
    note per setting the two sides differ in (each cell then compares one value with the other)."""
    base, cand = named_entrants(base), named_entrants(cand)
    apart = [c for c in SETTINGS if c in differing_settings(base) or c in differing_settings(cand)]
    apart = [c for c in apart if c != "split"]  # cells pair on the split already
    base, cand = (r.assign(**{c: factor_values(r, c) for c in apart}) for r in (base, cand))
    notes = []
    for c in SETTINGS:
        if c in apart or c == "split" or not (c in base or c in cand):
            continue
        b, k = (sorted(set(factor_values(r, c)) - {""}) for r in (base, cand))
        if b and k and b != k:
            notes.append(
                f"The sides differ in {setting_name(c)}: BASE {', '.join(b)}, CANDIDATE "
                f"{', '.join(k)}; each cell compares one with the other."
            )
    if apart:
        notes.append(
            "A side holds rows that differ in "
            + ", ".join(map(setting_name, apart))
            + ": cells pair on them too, and no figure pools two of their values."
        )
    return base, cand, apart, notes


def _unique(rows: pd.DataFrame, on: list[str], side: str) -> pd.DataFrame:
    dup = rows.duplicated(on, keep=False)
    if dup.any():
        first = rows[dup].iloc[0]
        raise DataError(
            f"{side} holds {int(dup.sum())} rows for one cell ({first['protocol']}, {first['detector']}, "
            f"cell {first['cell']}, seed {first['seed']}): runs with different parameters or datasets "
            "share the folder; compare folders that hold one run per cell"
        )
    return rows


def paired_cell(
    base: pd.DataFrame | None, cand: pd.DataFrame | None, seed: int, level: float
) -> dict | None:
    """Paired figures from the two cells' predictions, or None when they cannot be joined."""
    if base is None or cand is None:
        return None
    joined = base.merge(cand, on=["recording_id", "window_index"], suffixes=("_b", "_c"))
    if joined.empty or (joined["y_true_b"] != joined["y_true_c"]).any():
        return None
    by_trial = "trial_b" in joined  # both files hold trials: a trial shared by units is one cluster
    out: dict[str, Any] = paired_comparison(
        joined["y_true_b"].to_numpy(),
        joined["score_b"].to_numpy() >= 0.5,
        joined["score_c"].to_numpy() >= 0.5,
        joined["trial_b" if by_trial else "recording_id"].to_numpy(),
        seed,
        level=level,
        base_scores=joined["score_b"].to_numpy(),
        cand_scores=joined["score_c"].to_numpy(),
    )
    shared = "" if len(joined) == len(base) == len(cand) else f", {len(joined)} shared windows"
    out["method"] = f"paired over {'trials' if by_trial else 'recordings'}{shared}"
    return out


def _same_predictions(base: pd.DataFrame | None, cand: pd.DataFrame | None) -> bool:
    """Both sides scored the same windows alike (the same model run twice, a self-compare)."""
    if base is None or cand is None or len(base) != len(cand):
        return False
    on = ["recording_id", "window_index"]
    b, c = (f.sort_values(on).reset_index(drop=True) for f in (base, cand))
    return bool(
        (b[on].to_numpy() == c[on].to_numpy()).all()
        and (b["y_true"].to_numpy() == c["y_true"].to_numpy()).all()
        and np.array_equal(b["score"].to_numpy(), c["score"].to_numpy())
    )


def _as_predictions(frame: pd.DataFrame, by_trial: bool) -> Predictions:
    score = frame["score"].to_numpy()
    groups = frame["trial" if by_trial else "recording_id"].astype(str).to_numpy()
    return Predictions(frame["y_true"].to_numpy().astype(bool), score >= 0.5, groups, score)


def seed_sides(base: list[pd.DataFrame], cand: list[pd.DataFrame]) -> tuple[list, list]:
    """Each seed's predictions as Predictions, clustered by trial where every file holds one."""
    by_trial = all("trial" in f for f in (*base, *cand))
    return [_as_predictions(f, by_trial) for f in base], [
        _as_predictions(f, by_trial) for f in cand
    ]


def cell_sides(
    base: list[pd.DataFrame], cand: list[pd.DataFrame], base_rows: list, cand_rows: list
) -> CellSides:
    """A compared cell as the pooled tests take it: each seed's predictions per side and the
    seeds their rows ran, in the same order."""
    return CellSides(
        *seed_sides(base, cand),
        [r.get("seed") for r in base_rows],
        [r.get("seed") for r in cand_rows],
    )


def cell_over_seeds(
    base: list[pd.DataFrame],
    cand: list[pd.DataFrame],
    spec: IntervalSpec,
    paired: bool = False,
    seed_pool: dict[str, SeedPool] | None = None,
) -> dict:
    """The two-level bootstrap (over seeds and trials) of a cell run under several seeds on a
    side, or under different seeds (:func:`slipbench.stats.metrics.over_seeds`); ``paired``
    where both sides ran the same seeds, which then pair seed by seed. ``seed_pool``: the seed
    variance its protocol's cells share (:func:`seed_pools`)."""
    b, c = seed_sides(base, cand)
    out: dict[str, Any] = over_seeds(
        b,
        c,
        spec.seed,
        level=spec.level,
        n_resamples=spec.n_resamples,
        method=spec.method,
        figures=FIGURES,
        paired=paired,
        seed_pool=seed_pool,
    )
    how = "paired seed by seed" if paired else f"{len(b)} → {len(c)} seeds"
    out["method"] = f"over seeds and trials ({how})"
    return out


def unpaired_cell(base_rows: list[dict], cand_rows: list[dict], level: float) -> dict:
    """Change judged from the rows: their bootstrap standard errors combined as independent.

    Rows written before standard errors were stored give theirs as the 95 % half-width over
    1.96, with normal quantiles (method says so). A side of several seeds gives the mean over
    its seeds, with the mean of their standard errors (as if their test noise moved together:
    the seeds draw on the same trials) plus the between-seed variance over the number of seeds
    (retraining noise)."""
    out: dict = {"method": "unpaired"}
    if len(base_rows) > 1 or len(cand_rows) > 1:
        out["method"] = f"unpaired over seeds ({len(base_rows)} → {len(cand_rows)} seeds)"
    dfs: list[Any] = [r.get("df") for r in (*base_rows, *cand_rows)]  # numbers or None
    df = (
        min(float(d) for d in dfs)
        if all(d is not None and np.isfinite(float(d)) for d in dfs)
        else np.inf
    )
    for name in FIGURES:
        means, ses = [], []
        for rows in (base_rows, cand_rows):
            values = np.array([float(r.get(name, np.nan)) for r in rows])
            side_se = []
            for r in rows:
                if f"{name}_se" in r:
                    side_se.append(float(r[f"{name}_se"]))
                else:
                    side_se.append(
                        (float(r.get(f"{name}_hi", np.nan)) - float(r.get(f"{name}_lo", np.nan)))
                        / (2 * scipy.stats.norm.ppf(1 - ALPHA / 2))
                    )
                    df, out["method"] = np.inf, "unpaired (standard errors from 95 % bounds)"
            var = float(np.mean(side_se)) ** 2
            if len(rows) > 1:
                var += float(values.var(ddof=1)) / len(rows)
                df = min(df, len(rows) - 1)
            means.append(float(values.mean()))
            ses.append(np.sqrt(var))
        d = means[1] - means[0]
        se = float(np.hypot(ses[0], ses[1]))
        half = scipy.stats.t.ppf(1 - (1 - level) / 2, df) * se
        lo, hi = (
            (d - half, d + half) if np.isfinite(se) else (-1.0, 1.0)
        )  # no spread known: the whole range
        out[f"d_{name}"], out[f"d_{name}_se"] = d, se
        out[f"d_{name}_lo"], out[f"d_{name}_hi"] = (
            (max(lo, -1.0), min(hi, 1.0)) if np.isfinite(d) else (np.nan, np.nan)
        )
    out["df"] = df
    return out


# streaming figures compared: name -> the sign of a worse change (+1: larger is worse)
STREAM_FIGURES = {"median_delay_ms": 1, "false_alarms_per_min": 1, "detection_rate": -1}


def _is_stream(row: dict) -> bool:
    """A streaming cell's row (its figures are delays and alarms, not accuracy)."""
    return pd.notna(row.get("stream_s", np.nan))


def machine_timed(row: dict) -> bool:
    """A streaming row whose delays hold the compute time measured on its machine: written
    before delays were counted on the stream alone (``compute_ms``, no ``compute_ms_per_hop``)."""
    return pd.notna(row.get("compute_ms", np.nan)) and pd.isna(
        row.get("compute_ms_per_hop", np.nan)
    )


def compare_compute(base_row: dict, cand_row: dict) -> dict:
    """The compute time per hop of both sides and the candidate's against its real-time budget
    (the hop period): reported beside the verdict, never part of it, since it is each
    machine's own figure. Its ``compute_check`` is "over the real-time budget", "within the
    real-time budget" or "" (not measured: rows from before the check)."""
    c_ms, budget = (
        float(cand_row.get("compute_ms_per_hop", np.nan)),
        float(cand_row.get("compute_budget_ms", np.nan)),
    )
    out: dict = {
        "base_compute_ms_per_hop": float(base_row.get("compute_ms_per_hop", np.nan)),
        "candidate_compute_ms_per_hop": c_ms,
        "candidate_compute_budget_ms": budget,
        "base_processor": str(base_row.get("compute_processor") or ""),
        "candidate_processor": str(cand_row.get("compute_processor") or ""),
    }
    known = np.isfinite(c_ms) and np.isfinite(budget)
    out["compute_check"] = (
        ("over the real-time budget" if c_ms > budget else "within the real-time budget")
        if known
        else ""
    )
    return out


def _streamed(base_row: dict, cand_row: dict, level: float) -> dict:
    """Unpaired changes of the streaming figures (candidate - base) with intervals at
    ``level``: standard errors from each row's 95 % bootstrap bounds, combined as independent.
    The delays and the detection rate of a :func:`machine_timed` row are not judged (no
    interval). The compute check (:func:`compare_compute`) rides along."""
    out: dict = {"method": "unpaired streams (standard errors from 95 % bounds over trials)"}
    stale = [side for side, r in (("BASE", base_row), ("CANDIDATE", cand_row)) if machine_timed(r)]
    if stale:
        out["method"] += (
            f"; delays and detection rate not judged: {' and '.join(stale)} holds delays with "
            "its machine's compute time (rows from before delays were counted on the stream)"
        )
    out |= compare_compute(base_row, cand_row)
    z = scipy.stats.norm.ppf(1 - (1 - level) / 2)
    for name in STREAM_FIGURES:
        d = float(cand_row.get(name, np.nan)) - float(base_row.get(name, np.nan))
        ses = [
            max(
                (float(r.get(f"{name}_hi", np.nan)) - float(r.get(f"{name}_lo", np.nan)))
                / (2 * scipy.stats.norm.ppf(1 - ALPHA / 2)),
                _resolution(r) if name.endswith("_ms") else 0.0,
            )
            for r in (base_row, cand_row)
        ]
        se = float(np.hypot(*ses))
        ok = np.isfinite(d) and np.isfinite(se) and not (stale and name != "false_alarms_per_min")
        out[f"d_{name}"], out[f"d_{name}_se"] = d, se
        out[f"d_{name}_lo"], out[f"d_{name}_hi"] = (
            (d - z * se, d + z * se) if ok else (np.nan, np.nan)
        )
    return out


def _resolution(row: dict) -> float:
    """The standard error a delay has at least: a score comes once a hop, so a delay is known
    to one hop (uniform rounding, hop / sqrt(12)). Without this floor, cells whose onsets all
    fall at the same phase of the hop give zero-width bootstrap intervals, and any change of a
    delay, however small, would read as a significant change."""
    hop, rate = float(row.get("hop", np.nan)), float(row.get("sampling_rate_hz", np.nan))
    return hop / rate * 1000.0 / np.sqrt(12.0) if np.isfinite(hop) and rate > 0 else 0.0


def _ok(row: dict) -> bool:
    return row.get("status", "ok") == "ok"


def _side_status(rows: list[dict]) -> str:
    """A side's status of a cell: ok when every seed finished, else the first other status."""
    return next((str(r.get("status")) for r in rows if not _ok(r)), "ok")


def _flag(row: dict, column: str) -> bool:
    value = row.get(column, False)
    return bool(value) if pd.notna(value) else False


def _same_figures(a: dict, b: dict) -> bool:
    for name in (*FIGURES, *STREAM_FIGURES):
        x, y = a.get(name, np.nan), b.get(name, np.nan)
        if not (pd.isna(x) and pd.isna(y)) and x != y:
            return False
    return True


def _seed_text(base: list[dict], cand: list[dict]) -> str:
    b, c = (",".join(str(int(r["seed"])) for r in rows) for rows in (base, cand))
    return b if b == c else f"{b} → {c}"


def compare(
    base_path: str | os.PathLike,
    candidate_path: str | os.PathLike,
    gate: Gate | None = None,
    seed: int = 0,
) -> Comparison:
    """Compare CANDIDATE against BASE cell by cell, and per protocol, detector and figure pooled.

    Parameters
    ----------
    base_path, candidate_path
        Results files or folders (as ``evaluate --out`` writes them).
    gate : Gate
        The figures judged and the tolerance of each (default: every figure,
        ``slipbench.stats.gate.DEFAULT_TOLERANCE``).
    seed : int
        Seeds the paired bootstraps.

    Raises
    ------
    DataError
        The sides come from different datasets, a side repeats a key or a cell and seed, or
        they share no cell.
    """
    gate = gate or Gate()
    base, cand, on, notes = _read_sides(base_path, candidate_path)
    plans, only_base, only_cand = _plan_cells(base, cand, on, (base_path, candidate_path))
    n_tests = sum(len(gate.figures(e["stream"])) for e, *_ in plans if _decidable(e))
    level = family_level(n_tests, CELL_ALPHA)
    pools = seed_pools(plans)
    cells = _judge_cells(
        pd.DataFrame([_changes(plan, seed, level, pools.get(_pool_of(plan))) for plan in plans]),
        gate,
    )
    seeds = [(e["n_seeds_base"], e["n_seeds_cand"]) for e, *_ in plans if _finished(e)]
    pooled, pooled_level = _pooled_tests(plans, cells, seed, gate)
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
    )
    if not pooled.empty:
        cmp.pooled = _pooled_verdicts(pooled, gate, cmp.retraining_covered)
    return cmp


def _read_sides(
    base_path: str | os.PathLike, candidate_path: str | os.PathLike
) -> tuple[pd.DataFrame, pd.DataFrame, list[str], list[str]]:
    """Both sides read and checked, the columns cells pair on, and the notes so far."""
    base, cand = read_results(base_path), read_results(candidate_path)
    notes = check_same_dataset(base, cand)
    base, cand = (
        check_unique_keys(base, f"BASE {base_path}"),
        check_unique_keys(cand, f"CANDIDATE {candidate_path}"),
    )
    (base, b_again), (cand, c_again) = latest_runs(base), latest_runs(cand)
    notes += [
        f"{side} holds {n} earlier {'row' if n == 1 else 'rows'} of a cell and seed run again "
        "later (other code into the same folder): left out, the latest run of each compared."
        for side, n in (("BASE", b_again), ("CANDIDATE", c_again))
        if n
    ]
    base, cand, apart, differ = _kept_apart(base, cand)
    on = [*_pairing(base, cand), *apart]
    base, cand = _unique(base, [*on, "seed"], "BASE"), _unique(cand, [*on, "seed"], "CANDIDATE")
    return base, cand, on, notes + differ


def _plan_cells(
    base: pd.DataFrame, cand: pd.DataFrame, on: list[str], paths: tuple
) -> tuple[list, pd.DataFrame, pd.DataFrame]:
    """The cells both sides hold, each (entry, base rows, candidate rows, predictions, same
    seeds), and the cells of one side only."""
    ident = ["protocol", "detector", "split", "seed", "cell", *on[len(_pairing(base, cand)) :]]
    # cells pair by everything but the seed: a side may hold several seeds of a cell
    groups = [dict(iter(rows.groupby(on, sort=False, dropna=False))) for rows in (base, cand)]
    shared = [k for k in groups[0] if k in groups[1]]
    only_base, only_cand = (
        pd.concat([g[k] for k in g if k not in other], ignore_index=True)[ident]
        if any(k not in other for k in g)
        else pd.DataFrame(columns=ident)
        for g, other in ((groups[0], groups[1]), (groups[1], groups[0]))
    )
    if not shared:
        raise DataError(
            f"BASE {paths[0]} and CANDIDATE {paths[1]} share no cell "
            f"(protocols {sorted(set(base['protocol']))} vs {sorted(set(cand['protocol']))}; "
            "cells pair across seeds, so the seeds are not the reason)"
        )
    folders = tuple(results_folder(p) for p in paths)
    plans = [
        _plan(
            dict(zip(on, k if isinstance(k, tuple) else (k,))),
            [g[k].sort_values("seed").to_dict("records") for g in groups],
            folders,
        )
        for k in shared
    ]
    return plans, only_base, only_cand


def _plan(entry: dict, sides: list[list[dict]], folders: tuple) -> tuple:
    """One shared cell: its entry (statuses, seeds, both sides' figures, low n, identical) and
    what its changes are computed from."""
    b_rows, c_rows = sides
    if "detector" not in entry:
        entry["detector"] = f"{b_rows[0]['detector']} → {c_rows[0]['detector']}"
    entry["seed"] = _seed_text(b_rows, c_rows)
    sb, sc = _side_status(b_rows), _side_status(c_rows)
    entry["base_status"], entry["candidate_status"] = sb, sc
    entry["n_seeds_base"], entry["n_seeds_cand"] = len(b_rows), len(c_rows)
    for side, rows in (("base", b_rows), ("candidate", c_rows)):
        for name in ("accuracy", *STREAM_FIGURES):
            entry[f"{side}_{name}"] = float(np.mean([float(r.get(name, np.nan)) for r in rows]))
    entry["stream"] = _is_stream(b_rows[0]) and _is_stream(c_rows[0])
    both = sb == sc == "ok"
    entry["low_n"] = both and any(_flag(r, "low_n") for r in (*b_rows, *c_rows))
    # the same content keys with the same figures: the same result, read twice
    same_keys = [r["key"] for r in b_rows] == [r["key"] for r in c_rows] and all(
        _same_figures(x, y) for x, y in zip(b_rows, c_rows)
    )
    preds: tuple[list, list] = ([], [])
    if both and not entry["stream"] and not same_keys:
        preds = tuple(  # type: ignore[assignment]
            [read_predictions(f, r["key"]) for r in rows]
            for f, rows in zip(folders, (b_rows, c_rows))
        )
    same_seeds = [r["seed"] for r in b_rows] == [r["seed"] for r in c_rows]
    same_preds = all(_same_predictions(x, y) for x, y in zip(*preds)) and len(preds[0]) > 0
    entry["identical"] = both and (same_keys or (same_seeds and same_preds))
    return entry, b_rows, c_rows, preds, same_seeds


def _finished(e: dict) -> bool:
    return e["base_status"] == e["candidate_status"] == "ok"


def _decidable(e: dict) -> bool:
    """A cell in the cell family: both sides finished it, it changed, it is not low-n."""
    return _finished(e) and not e["identical"] and not e["low_n"]


def _over_seeds(plan: tuple) -> bool:
    """A finished, changed windowed cell whose seeds' predictions are all at hand and that ran
    more than one seed on a side or different seeds: it is judged over seeds and trials."""
    entry, b_rows, c_rows, (pb, pc), same_seeds = plan
    one_each = len(b_rows) == len(c_rows) == 1
    return (
        _finished(entry)
        and not entry["identical"]
        and not entry["stream"]
        and not (one_each and same_seeds)
        and all(p is not None for p in (*pb, *pc))
        and len(pb) > 0
    )


def _pool_of(plan: tuple) -> tuple[str, str, bool]:
    """The cells that share a seed pool: one protocol and detector, paired or not."""
    return (str(plan[0].get("protocol")), str(plan[0].get("detector")), bool(plan[4]))


def seed_pools(plans: list[tuple]) -> dict[tuple[str, str, bool], dict[str, SeedPool]]:
    """Per protocol and detector, the seed variance its cells judged over seeds share
    (:func:`slipbench.stats.pooled.protocol_seed_pool`), so that more seeds narrow each cell's
    interval: the cell's own two or three seeds no longer carry its seed term alone."""
    groups: dict[tuple[str, str, bool], list[CellSides]] = {}
    for plan in filter(_over_seeds, plans):
        _, b_rows, c_rows, (pb, pc), _ = plan
        groups.setdefault(_pool_of(plan), []).append(cell_sides(pb, pc, b_rows, c_rows))
    return {key: protocol_seed_pool(cells, FIGURES, paired=key[2]) for key, cells in groups.items()}


def _changes(
    plan: tuple, seed: int, level: float, seed_pool: dict[str, SeedPool] | None = None
) -> dict:
    """A planned cell's changes with intervals at ``level``, by the method its rows allow."""
    entry, b_rows, c_rows, (pb, pc), same_seeds = plan
    one_each = len(b_rows) == len(c_rows) == 1
    if not _finished(entry):
        entry["method"] = f"status {entry['base_status']} → {entry['candidate_status']}"
    elif entry["identical"]:
        entry |= _identical(entry, b_rows, c_rows)
    elif entry["stream"] and one_each:
        entry |= _streamed(b_rows[0], c_rows[0], level)
    elif entry["stream"]:
        entry["method"] = "streams over several seeds: not compared"
    elif one_each and same_seeds:
        entry |= paired_cell(pb[0], pc[0], seed, level) or unpaired_cell(b_rows, c_rows, level)
    elif all(p is not None for p in (*pb, *pc)):
        entry |= cell_over_seeds(pb, pc, IntervalSpec(seed, level), same_seeds, seed_pool)
    else:
        entry |= unpaired_cell(b_rows, c_rows, level)
    for col in (
        f"d_{n}{s}" for n in (*FIGURES, *STREAM_FIGURES) for s in ("", "_lo", "_hi", "_se")
    ):
        entry.setdefault(col, np.nan)
    return entry


def _identical(entry: dict, b_rows: list[dict], c_rows: list[dict]) -> dict:
    out: dict[str, Any] = {"method": "identical (same result keys or predictions)"}
    for name in STREAM_FIGURES if entry["stream"] else FIGURES:
        known = pd.notna(b_rows[0].get(name, np.nan))
        for bound in ("", "_lo", "_hi", "_se"):
            out[f"d_{name}{bound}"] = 0.0 if known else np.nan
    if entry["stream"] and len(b_rows) == len(c_rows) == 1:
        # the same stream on another machine: its compute time is still its own check
        out |= compare_compute(b_rows[0], c_rows[0])
    return out


def _tests(frame: pd.DataFrame, figure: str, gate: Gate) -> tuple[np.ndarray, np.ndarray]:
    """Per row: the p-values of ``figure`` worse and better than its tolerance, from its
    change and standard error in the figure's units and the row's degrees of freedom."""
    scale, sign, tol = SCALE[figure], WORSE[figure], gate.tolerances[figure]
    d = scale * pd.to_numeric(frame[f"d_{figure}"], errors="coerce").to_numpy(float)
    se = scale * pd.to_numeric(frame[f"d_{figure}_se"], errors="coerce").to_numpy(float)
    df = pd.to_numeric(frame["df"], errors="coerce").fillna(np.inf).to_numpy(float)
    return two_sided_p(sign * d, se, df, tol)


def _judge_cells(cells: pd.DataFrame, gate: Gate) -> pd.DataFrame:
    """Each cell's verdict: Holm at ``CELL_ALPHA`` over every (cell, figure) test of the cells
    that can decide; the figures that regressed are named."""
    if "df" not in cells:
        cells["df"] = np.inf
    cells["df"] = np.where(cells["stream"].astype(bool), np.inf, cells["df"])
    decidable = cells.apply(_decidable, axis=1).to_numpy(bool)
    keys, p, worse = [], [], []
    for figure in (*gate.figures(False), *gate.figures(True)):
        if f"d_{figure}" not in cells:
            continue  # no cell of its kind
        p_reg, p_imp = _tests(cells, figure, gate)
        of_kind = cells["stream"].to_numpy(bool) == (figure in STREAM_FIGURES)
        for i in np.flatnonzero(decidable & of_kind):
            keys.append((int(i), figure))
            p.append(min(p_reg[i], p_imp[i]))
            worse.append(p_reg[i] <= p_imp[i])
    adj = holm(np.array(p)) if p else np.array([])
    flagged: dict[int, dict[str, list[str]]] = {}
    for (row, figure), q, w in zip(keys, adj, worse):
        if q <= CELL_ALPHA:
            flagged.setdefault(row, {"regressed": [], "improved": []})[
                "regressed" if w else "improved"
            ].append(figure)
    verdicts = [
        _cell_verdict(r, flagged.get(i, {}), gate) for i, r in enumerate(cells.to_dict("records"))
    ]
    cells["verdict"] = [v for v, _ in verdicts]
    cells["inconclusive_reason"] = [why for _, why in verdicts]
    cells["regressed_figures"] = [
        ", ".join(flagged.get(i, {}).get("regressed", [])) for i in range(len(cells))
    ]
    return cells


def _cell_verdict(r: dict, flagged: dict, gate: Gate) -> tuple[str, str]:
    """A cell's verdict and, where inconclusive, why."""
    if not _finished(r):
        if r["base_status"] == "ok":
            return "regressed", ""  # the candidate no longer finishes a cell the base finished
        return ("improved" if r["candidate_status"] == "ok" else "no significant change"), ""
    if r["identical"]:
        return "identical", ""
    if r["method"] == "streams over several seeds: not compared":
        return "inconclusive", "streaming cells over several seeds are not compared"
    if r["low_n"]:
        return "inconclusive", f"low n (fewer than {LOW_N} test trials of a class)"
    if flagged.get("regressed"):
        return "regressed", ""
    if flagged.get("improved"):
        return "improved", ""
    width = primary_change(r, "_hi") - primary_change(r, "_lo")
    if not width <= gate.max_width:
        return "inconclusive", f"interval wider than {gate.max_width:g} points"
    return ("within margin" if _inside(r, gate) else "no significant change"), ""


def _inside(r: dict, gate: Gate) -> bool:
    """Every judged figure's interval inside plus or minus its tolerance."""
    for figure in gate.figures(bool(r["stream"])):
        lo, hi = r.get(f"d_{figure}_lo", np.nan), r.get(f"d_{figure}_hi", np.nan)
        tol = gate.tolerances[figure] / SCALE[figure]
        if not (-tol <= lo and hi <= tol):
            return False
    return True


def _pooled_groups(plans: list, cells: pd.DataFrame) -> dict[tuple, list]:
    """Per protocol and detector, the finished cells that are compared (not streams over
    several seeds), each (row, (base preds, candidate preds, base rows, candidate rows))."""
    groups: dict[tuple, list] = {}
    for (entry, b_rows, c_rows, preds, _), r in zip(plans, cells.to_dict("records")):
        if _finished(entry) and not str(r["method"]).startswith("streams over several"):
            groups.setdefault((entry["protocol"], entry["detector"]), []).append(
                (r, (*preds, b_rows, c_rows))
            )
    return {g: m for g, m in groups.items() if any(not r["identical"] for r, _ in m)}


def _pooled_tests(
    plans: list, cells: pd.DataFrame, seed: int, gate: Gate
) -> tuple[pd.DataFrame, float]:
    """Per protocol, detector and judged figure: the mean change over the cells both sides
    finished (identical ones count 0), with its interval at the Bonferroni level over the
    pooled tests; verdicts come from :func:`_pooled_verdicts`."""
    groups = _pooled_groups(plans, cells)
    tests = [
        (g, figure)
        for g, members in groups.items()
        for figure in gate.figures(bool(members[0][0]["stream"]))
    ]
    level = family_level(len(tests), POOLED_ALPHA)
    lines = [_pooled_line(g, groups[g], figure, seed, level) for g, figure in tests]
    return pd.DataFrame(lines), level


def _pooled_line(group: tuple, members: list, figure: str, seed: int, level: float) -> dict:
    """One pooled test: the mean change of ``figure`` over a protocol's cells, in its units."""
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
    if figure in RATE_MASKS and all(x is not None for b, c, *_ in preds for x in (*b, *c)):
        res = pooled_change([cell_sides(*p) for p in preds], seed, level, figure=figure)
        line["method"] = "joint cluster bootstrap over the trials the cells share" + (
            f" and {res['seed_design']}" if res["seeds"] else ""
        )
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
        line[f"change{'' if name == 'd' else '_' + name}"] = SCALE[figure] * share * res[name]
    line["df"] = res["df"]
    return line


def _pooled_verdicts(pooled: pd.DataFrame, gate: Gate, retrained: bool) -> pd.DataFrame:
    """Holm over the pooled tests at ``POOLED_ALPHA``; a test that flags nothing states its
    power (``resolution``, ``detectable``) and is "undecided" where it cannot see a regression
    of its tolerance, its data are low-n or a side ran one seed."""
    pooled = pooled.copy()
    sign = pooled["figure"].map(WORSE).to_numpy(float)
    tol = pooled["figure"].map(gate.tolerances).to_numpy(float)
    se, df = pooled["change_se"].to_numpy(float), pooled["df"].to_numpy(float)
    p_reg, p_imp = two_sided_p(sign * pooled["change"].to_numpy(float), se, df, tol)
    pooled["p_holm"] = holm(np.minimum(p_reg, p_imp))
    pooled["tolerance"] = tol

    def resolve(s: float, d: float) -> float:
        return resolution(s, d, len(pooled), POOLED_ALPHA)

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
    judged = [
        _pooled_verdict(r, flagged, retrained)
        for r, flagged in zip(pooled.to_dict("records"), p_reg <= p_imp)
    ]
    pooled["verdict"] = [v for v, _ in judged]
    pooled["undecided_reason"] = [why for _, why in judged]
    return pooled


def _pooled_verdict(r: dict, worse: bool, retrained: bool) -> tuple[str, str]:
    if r["p_holm"] <= POOLED_ALPHA and not r["low_n"]:
        return ("regressed" if worse else "improved"), ""
    if r["low_n"]:
        return "undecided", f"low n (fewer than {LOW_N} test trials of a class)"
    if not retrained:
        return "undecided", "one seed per side: retraining noise is not in the interval"
    if not r["resolution"] <= r["tolerance"]:
        return "undecided", (
            f"it would flag a drop of {r['detectable']:.2g} {unit(r['figure'])} with 80 % power, "
            f"more than twice its tolerance"
        )
    inside = -r["tolerance"] <= r["change_lo"] and r["change_hi"] <= r["tolerance"]
    return ("within margin" if inside else "no significant change"), ""


def _figure(r: dict) -> str:
    """The figure a cell is summarised by: accuracy, or a stream's detection rate."""
    return "detection_rate" if r["stream"] else "accuracy"


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
        if r["figure"] in ("accuracy", "detection_rate")
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
