"""Two result sets -> per-cell changes with paired intervals and a CI verdict.

Cells are paired on (protocol, cell key, split, seed), and on the detector as well when both
sides hold the same detectors (comparing one detector's two versions); when each side holds a
single detector, they are compared with each other (comparing two detectors). Two result sets
from different datasets (``dataset_fingerprint``) are refused before anything is compared, and
so is a side that holds a row twice (the same key).

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

Verdicts. Every interval is simultaneous over ALL the cells the run compares: with ``m`` cells
compared (both sides finished), each is a t-interval at level ``1 - 0.05 / m`` (Bonferroni), so
the chance that any cell of the run is wrongly called regressed or improved is at most 5 %.
Measured (``tests/stats/test_compare.py``, ``SLIPBENCH_NULL_RUNS=100``): 100 simulated comparisons
of two equally good detectors that differ at random per recording, 280 cells each of 10-40
recordings per class, margin 0: no run called any cell regressed, where per-cell 95 %
intervals called one in all 100 runs. A cell *regressed*
when its accuracy interval lies entirely below ``-margin`` (upper bound < -margin), or when
the candidate failed, timed out or skipped a cell the base finished; *improved* when it lies
entirely above ``+margin``; *within margin* when it lies inside ``[-margin, +margin]``
(margin > 0); otherwise *no significant change*. McNemar's test over windows is gone: it
treats correlated windows as independent (issue 11 measured 17-23 % false rejections per cell).

Streaming cells (rows without ``accuracy``, with the streaming figures of
:mod:`slipbench.stream.cell`) are judged on their median delay, false alarms per minute and
detection rate at the detector's own threshold: figures counted on the streams' samples, the
same on every machine. The compute time per hop is this machine's; it is a separate check
(:func:`compute_check`: is the candidate within the real-time budget, the hop period) that is
reported and never makes a verdict. Rows written before delays left out the compute time (they
hold ``compute_ms`` and no ``compute_ms_per_hop``) have machine-dependent delays and detection
rates (the compute time shortened the horizon): those two are not judged on them, only false
alarms. No per-onset predictions are stored, so the
change is unpaired: each row's 95 % bootstrap interval over trials gives its standard error
(half-width / 1.96; for delays at least hop / sqrt(12), the resolution of a score once a hop),
the two combined as independent, at the same simultaneous level as every
other cell. Both sides stream the same test trials, so their errors are positively correlated and
the independent combination overstates the spread of the change: the test is conservative (it
misses small regressions; it does not invent them). A cell *regressed* when the median delay
rises beyond ``delay_margin_ms`` (interval lower bound > margin), false alarms per minute beyond
``alarm_margin``, or the detection rate falls beyond ``margin`` points; *improved* when one of
them improves beyond its margin and none regresses.

This module decides; it writes no text. The pull-request comment and the JSON for bots are
written from a :class:`Comparison` by the report wing.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.stats import norm
from scipy.stats import t as student_t

from slipbench.errors import DataError, UsageError
from slipbench.stats.metrics import FIGURES, LEVEL, paired_comparison
from slipbench.store.results import (
    check_unique_keys,
    read_predictions,
    read_results,
    results_folder,
)

ALPHA = 1 - LEVEL
# the verdicts a cell can get, in the order counts of them are given
VERDICTS = ("regressed", "improved", "within margin", "no significant change")


@dataclass
class Comparison:
    """The outcome of :func:`compare`."""

    # one row per paired cell: changes, simultaneous intervals, verdict; in the order the
    # pairing found them (the comment's writers put them in the paper's order)
    cells: pd.DataFrame
    only_base: pd.DataFrame  # cells in BASE only: protocol, detector, split, seed, cell
    only_candidate: pd.DataFrame
    base: str
    candidate: str
    margin: float  # percentage points
    notes: list[str] = field(default_factory=list)
    level: float = LEVEL  # the simultaneous level of every interval: 1 - 0.05 / cells compared
    delay_margin_ms: float = 0.0  # streaming cells: ms of median delay a cell may add
    alarm_margin: float = 0.0  # streaming cells: false alarms per minute a cell may add
    # both sides' result rows as read: what the writers lay the protocols out from
    rows: pd.DataFrame | None = None

    @property
    def regressions(self) -> pd.DataFrame:
        return self.cells[self.cells["verdict"] == "regressed"]

    @property
    def exit_code(self) -> int:
        """0 when nothing regressed beyond the margin, 1 when something did."""
        return int(len(self.regressions) > 0)


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
    on = ["protocol", "cell", "split", "seed"]
    for side, rows in (("BASE", base), ("CANDIDATE", cand)):
        missing = set(on) - set(rows.columns)
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


def _paired(base_row, cand_row, folders: tuple[Path, Path], seed: int, level: float) -> dict | None:
    """Paired figures from the two cells' predictions, or None when they cannot be joined."""
    base, cand = (read_predictions(f, r["key"]) for f, r in zip(folders, (base_row, cand_row)))
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


def _unpaired(base_row: dict, cand_row: dict, level: float) -> dict:
    """Change judged from the two rows: their bootstrap standard errors combined as independent.

    Rows written before standard errors were stored give theirs as the 95 % half-width over
    1.96, with normal quantiles (method says so)."""
    out: dict = {"method": "unpaired"}
    dfs: list[Any] = [r.get("df") for r in (base_row, cand_row)]  # numbers or None
    df = (
        min(float(d) for d in dfs)
        if all(d is not None and np.isfinite(float(d)) for d in dfs)
        else np.inf
    )
    for name in FIGURES:
        d = float(cand_row.get(name, np.nan)) - float(base_row.get(name, np.nan))
        ses = []
        for r in (base_row, cand_row):
            if f"{name}_se" in r:
                ses.append(float(r[f"{name}_se"]))
            else:
                ses.append(
                    (float(r.get(f"{name}_hi", np.nan)) - float(r.get(f"{name}_lo", np.nan)))
                    / (2 * norm.ppf(1 - ALPHA / 2))
                )
                df, out["method"] = np.inf, "unpaired (standard errors from 95 % bounds)"
        se = float(np.hypot(ses[0], ses[1]))
        half = student_t.ppf(1 - (1 - level) / 2, df) * se
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


def compute_check(base_row: dict, cand_row: dict) -> dict:
    """The compute time per hop of both sides and the candidate's against its real-time budget
    (the hop period): reported beside the verdict, never part of it, since it is each
    machine's own figure. ``compute_check`` is "over the real-time budget", "within the
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
    interval). The compute check (:func:`compute_check`) rides along."""
    out: dict = {"method": "unpaired streams (standard errors from 95 % bounds over trials)"}
    stale = [side for side, r in (("BASE", base_row), ("CANDIDATE", cand_row)) if machine_timed(r)]
    if stale:
        out["method"] += (
            f"; delays and detection rate not judged: {' and '.join(stale)} holds delays with "
            "its machine's compute time (rows from before delays were counted on the stream)"
        )
    out |= compute_check(base_row, cand_row)
    z = norm.ppf(1 - (1 - level) / 2)
    for name in STREAM_FIGURES:
        d = float(cand_row.get(name, np.nan)) - float(base_row.get(name, np.nan))
        ses = [
            max(
                (float(r.get(f"{name}_hi", np.nan)) - float(r.get(f"{name}_lo", np.nan)))
                / (2 * norm.ppf(1 - ALPHA / 2)),
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


def stream_verdict(r: dict, margin: float, delay_margin_ms: float, alarm_margin: float) -> str:
    """The verdict of a streaming cell that both sides finished, from its simultaneous
    intervals: ``margin`` in points of detection rate, ``delay_margin_ms`` in ms of median
    delay, ``alarm_margin`` in false alarms per minute. A figure without an interval (no
    detected onset, no non-slip time) decides nothing."""
    margins = {
        "median_delay_ms": delay_margin_ms,
        "false_alarms_per_min": alarm_margin,
        "detection_rate": margin / 100,
    }
    worse = better = False
    inside = True
    for name, sign in STREAM_FIGURES.items():
        lo, hi = r.get(f"d_{name}_lo", np.nan), r.get(f"d_{name}_hi", np.nan)
        if pd.isna(lo) or pd.isna(hi):
            inside = False
            continue
        lo, hi = (lo, hi) if sign > 0 else (-hi, -lo)  # now larger is worse for every figure
        m = margins[name]
        worse |= lo > m
        better |= hi < -m
        inside &= -m <= lo and hi <= m
    if worse:
        return "regressed"
    if better:
        return "improved"
    return "within margin" if inside and max(margins.values()) > 0 else "no significant change"


def compare(
    base_path: str | os.PathLike,
    candidate_path: str | os.PathLike,
    margin: float = 0.0,
    seed: int = 0,
    delay_margin_ms: float = 0.0,
    alarm_margin: float = 0.0,
) -> Comparison:
    """Compare CANDIDATE against BASE cell by cell.

    Parameters
    ----------
    base_path, candidate_path
        Results files or folders (as ``evaluate --out`` writes them).
    margin : float
        Percentage points of accuracy (streaming cells: of detection rate) a cell may lose
        without counting as a regression.
    delay_margin_ms, alarm_margin : float
        Streaming cells: ms of median delay and false alarms per minute a cell may add.
    seed : int
        Seeds the paired bootstraps.

    Raises
    ------
    DataError
        The sides come from different datasets, a side repeats a key or a cell, or they share
        no cell.
    """
    if not margin >= 0:
        raise UsageError(f"--margin must be >= 0 percentage points, got {margin}")
    if not (delay_margin_ms >= 0 and alarm_margin >= 0):
        raise UsageError(
            f"--delay-margin and --alarm-margin must be >= 0, got {delay_margin_ms} and {alarm_margin}"
        )
    base, cand = read_results(base_path), read_results(candidate_path)
    notes = check_same_dataset(base, cand)
    base, cand = (
        check_unique_keys(base, f"BASE {base_path}"),
        check_unique_keys(cand, f"CANDIDATE {candidate_path}"),
    )
    on = _pairing(base, cand)
    base, cand = _unique(base, on, "BASE"), _unique(cand, on, "CANDIDATE")
    merged = base.merge(cand, on=on, how="outer", suffixes=("_b", "_c"), indicator=True)
    ident = ["protocol", "detector", "split", "seed", "cell"]
    sides = []
    for tag, suffix in (("left_only", "_b"), ("right_only", "_c")):
        rows = merged[merged["_merge"] == tag]
        sides.append(
            (rows if "detector" in on else rows.assign(detector=rows[f"detector{suffix}"]))[ident]
        )
    only_base, only_cand = sides
    both = merged[merged["_merge"] == "both"]
    if both.empty:
        raise DataError(
            f"BASE {base_path} and CANDIDATE {candidate_path} share no cell "
            f"(protocols {sorted(set(base['protocol']))} vs {sorted(set(cand['protocol']))})"
        )
    folders = (results_folder(base_path), results_folder(candidate_path))
    rows = both.to_dict("records")
    pairs = [
        tuple(
            {k[:-2]: v for k, v in row.items() if k.endswith(sfx)} | {k: row[k] for k in on}
            for sfx in ("_b", "_c")
        )
        for row in rows
    ]
    # every cell both sides finished is one member of the family the error rate is held over
    level = family_level(
        sum(b.get("status", "ok") == c.get("status", "ok") == "ok" for b, c in pairs)
    )
    out = []
    for row, (b, c) in zip(rows, pairs):
        sb, sc = b.get("status", "ok"), c.get("status", "ok")
        entry = {k: row[k] for k in on}
        entry["detector"] = (
            row["detector"] if "detector" in on else f"{row['detector_b']} → {row['detector_c']}"
        )
        entry["base_accuracy"], entry["candidate_accuracy"] = (
            b.get("accuracy", np.nan),
            c.get("accuracy", np.nan),
        )
        entry["base_status"], entry["candidate_status"] = sb, sc
        entry["stream"] = _is_stream(b) and _is_stream(c)
        for name in STREAM_FIGURES:
            entry[f"base_{name}"], entry[f"candidate_{name}"] = (
                b.get(name, np.nan),
                c.get(name, np.nan),
            )
        if sb == sc == "ok" and entry["stream"]:
            entry |= _streamed(b, c, level)
        elif sb == sc == "ok":
            entry |= _paired(b, c, folders, seed, level) or _unpaired(b, c, level)
        else:
            entry["method"] = f"status {sb} → {sc}"
        out.append(entry)
    cells = pd.DataFrame(out)
    for col in (
        f"d_{n}{s}" for n in (*FIGURES, *STREAM_FIGURES) for s in ("", "_lo", "_hi", "_se")
    ):
        if col not in cells:
            cells[col] = np.nan
    cells["verdict"] = [
        stream_verdict(r, margin, delay_margin_ms, alarm_margin)
        if r["stream"] and r["base_status"] == r["candidate_status"] == "ok"
        else verdict(r, margin)
        for r in cells.to_dict("records")
    ]
    return Comparison(
        cells,
        only_base,
        only_cand,
        str(base_path),
        str(candidate_path),
        margin,
        notes,
        level,
        delay_margin_ms,
        alarm_margin,
        pd.concat([base, cand], ignore_index=True),
    )


def verdict(r: dict, margin: float) -> str:
    """The verdict of one compared cell from its statuses and its simultaneous accuracy
    interval ``d_accuracy_lo``/``_hi`` (fractions); ``margin`` in percentage points."""
    if r["base_status"] != r["candidate_status"]:
        if r["base_status"] == "ok":
            return "regressed"  # the candidate no longer finishes a cell the base finished
        if r["candidate_status"] == "ok":
            return "improved"
        return "no significant change"
    lo, hi = r.get("d_accuracy_lo", np.nan), r.get("d_accuracy_hi", np.nan)
    if pd.isna(lo) or pd.isna(hi):
        return "no significant change"
    m = margin / 100
    if hi < -m:
        return "regressed"
    if lo > m:
        return "improved"
    if margin > 0 and -m <= lo and hi <= m:
        return "within margin"
    return "no significant change"


def _figure(r: dict) -> str:
    """The figure a cell is summarised by: accuracy, or a stream's detection rate."""
    return "detection_rate" if r["stream"] else "accuracy"


def primary_change(r: dict, bound: str = "") -> float:
    """The change of a cell's summarising figure (accuracy, or a stream's detection rate) in
    points, or with ``bound`` "_lo"/"_hi" its interval's bound."""
    return 100 * float(r.get(f"d_{_figure(r)}{bound}", np.nan))


def summary(cmp: Comparison) -> pd.DataFrame:
    """Per protocol and detector (in the order of ``cmp.cells``): cells compared, regressed and
    improved, the mean change of the summarising figure and the cell that changed most for the
    worse (``worst_row``: its index in ``cmp.cells``, None when no cell has a change)."""
    lines = []
    for (protocol, detector), part in cmp.cells.groupby(["protocol", "detector"], sort=False):
        changes = [(primary_change(r), i, r) for i, r in zip(part.index, part.to_dict("records"))]
        finite = [c for c in changes if np.isfinite(c[0])]
        # the first of equal changes, as the cells are ordered
        worst = min(finite, key=lambda c: c[0]) if finite else None
        verdicts = part["verdict"].value_counts()
        lines.append(
            {
                "protocol": protocol,
                "detector": detector,
                "cells": len(part),
                "regressed": int(verdicts.get("regressed", 0)),
                "improved": int(verdicts.get("improved", 0)),
                "mean_change": float(np.mean([d for d, _, _ in finite])) if finite else np.nan,
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
