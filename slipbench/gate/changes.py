"""A compared cell's change with its interval, by the method its rows allow.

Seeds. A cell with one seed per side, the same on both, is compared window by window (below).
A cell with several seeds on a side, or different seeds, gets the two-level bootstrap over seeds
and trials of :func:`slipbench.stats.metrics.over_seeds` (its change: mean over the candidate's
seeds minus mean over the base's), so retraining noise is inside its interval; where both sides
ran the same seeds, seed k of each shares its split and the seeds pair (``paired=True``: the
seeds' differences are drawn, so the split's luck cancels). With one seed per side it is not,
and :func:`slipbench.stats.compare.repeats_note` says so: a side needs ``MIN_SEEDS`` (2) seeds for a seed-to-seed
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
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
import scipy  # its submodules load on first use: reading stored rows pays none

from slipbench.gate.sides import STREAM_FIGURES, finished
from slipbench.stats.bootstrap import LEVEL, IntervalSpec
from slipbench.stats.metrics import FIGURES, over_seeds, paired_comparison
from slipbench.stats.noise import SeedNoise
from slipbench.stats.pooled import CellSides, cell_sides, protocol_seed_pool, seed_sides
from slipbench.store import columns

#: the level of the 95 % intervals rows store
ROW_LEVEL = LEVEL


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


def cell_over_seeds(
    base: list[pd.DataFrame],
    cand: list[pd.DataFrame],
    spec: IntervalSpec,
    paired: bool = False,
    seed_pool: dict[str, SeedNoise] | None = None,
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
                        / (2 * scipy.stats.norm.ppf(0.5 + ROW_LEVEL / 2))
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
                / (2 * scipy.stats.norm.ppf(0.5 + ROW_LEVEL / 2)),
                _resolution(r) if name.endswith("_ms") else 0.0,
            )
            for r in (base_row, cand_row)
        ]
        se = float(np.hypot(*ses))
        ok = (
            np.isfinite(d) and np.isfinite(se) and not (stale and name != columns.FALSE_ALARMS.name)
        )
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


def _over_seeds(plan: tuple) -> bool:
    """A finished, changed windowed cell whose seeds' predictions are all at hand and that ran
    more than one seed on a side or different seeds: it is judged over seeds and trials."""
    entry, b_rows, c_rows, (pb, pc), same_seeds = plan
    one_each = len(b_rows) == len(c_rows) == 1
    return (
        finished(entry)
        and not entry["identical"]
        and not entry["stream"]
        and not (one_each and same_seeds)
        and all(p is not None for p in (*pb, *pc))
        and len(pb) > 0
    )


def pool_of(plan: tuple) -> tuple[str, str, bool]:
    """The cells that share a seed pool: one protocol and detector, paired or not."""
    return (str(plan[0].get("protocol")), str(plan[0].get("detector")), bool(plan[4]))


def seed_pools(plans: list[tuple]) -> dict[tuple[str, str, bool], dict[str, SeedNoise]]:
    """Per protocol and detector, the seed variance its cells judged over seeds share
    (:func:`slipbench.stats.pooled.protocol_seed_pool`), so that more seeds narrow each cell's
    interval: the cell's own two or three seeds no longer carry its seed term alone."""
    groups: dict[tuple[str, str, bool], list[CellSides]] = {}
    for plan in filter(_over_seeds, plans):
        _, b_rows, c_rows, (pb, pc), _ = plan
        groups.setdefault(pool_of(plan), []).append(cell_sides(pb, pc, b_rows, c_rows))
    return {key: protocol_seed_pool(cells, FIGURES, paired=key[2]) for key, cells in groups.items()}


def cell_changes(
    plan: tuple, seed: int, level: float, seed_pool: dict[str, SeedNoise] | None = None
) -> dict:
    """A planned cell's changes with intervals at ``level``, by the method its rows allow."""
    entry, b_rows, c_rows, (pb, pc), same_seeds = plan
    one_each = len(b_rows) == len(c_rows) == 1
    if not finished(entry):
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
