"""The two result sets a comparison reads, paired cell by cell.

Cells are paired on (protocol, cell key, split), and on the detector as well when both sides
hold the same detectors (comparing one detector's two versions); when each side holds a single
detector, they are compared with each other (comparing two detectors). Not on the seed: a side
may hold several seeds of a cell (``evaluate --repeats``), and the sides' seeds may differ. Two
result sets from different datasets (``dataset_fingerprint``) are refused before anything is
compared, and so is a side that holds a row twice (the same key, or the same cell and seed
under other settings); a cell and seed run again later with other code counts once, the latest
run (:func:`slipbench.stats.factors.latest_runs`), and the notes say how many were left out.

Each shared cell is planned once (:func:`plan_cells`): both sides' rows, statuses and seeds,
its predictions where both sides finished it, whether the two are identical (the same content
keys and figures, or the same predictions under the same seeds) and low-n.
"""

from __future__ import annotations

import json
import os

import numpy as np
import pandas as pd

from slipbench.errors import DataError, UsageError
from slipbench.stats.factors import (
    SETTINGS,
    differing_settings,
    factor_values,
    latest_runs,
    named_entrants,
    setting_name,
)
from slipbench.stats.metrics import FIGURES
from slipbench.store import columns
from slipbench.store.resolved import resolve, rewritten
from slipbench.store.results import (
    check_unique_keys,
    read_predictions,
    read_results,
    results_folder,
)

# the streaming figures compared (the gate's)
STREAM_FIGURES = columns.names(columns.STREAMED, gated=True)
#: what pairs two sides' cells: the cell and the settings a result is named by (the detector
#: too where both sides hold the same; not the seed: a side may hold several per cell)
PAIRED = (
    *columns.identity(columns.CELL_ROLE, named=True),
    *columns.identity(columns.SETTING, named=True),
)
#: what names a one-sided cell: the result's name, then the settings it is kept apart by
NAMED = columns.identity(*columns.ROLES, named=True)


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
    on = list(PAIRED)
    for side, rows in (("BASE", base), ("CANDIDATE", cand)):
        missing = {*on, "seed"} - set(rows.columns)
        if missing:
            raise DataError(f"{side}: results lack the columns {', '.join(sorted(missing))}")
    b, c = set(base["detector"]), set(cand["detector"])
    if b == c or (b & c and (b <= c or c <= b)):  # one side's detectors lost or added: named
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
    base, cand = (named_entrants(resolve(r).rows) for r in (base, cand))
    apart = [c for c in SETTINGS if c in differing_settings(base) or c in differing_settings(cand)]
    apart = [c for c in apart if c not in PAIRED]  # cells pair on these already
    base, cand = (rewritten(r, {c: factor_values(r, c) for c in apart}) for r in (base, cand))
    notes = []
    for c in SETTINGS:
        if c in apart or c in PAIRED or not (c in base or c in cand):
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


def is_stream(row: dict) -> bool:
    """A streaming cell's row (its figures are delays and alarms, not accuracy)."""
    return pd.notna(row.get("stream_s", np.nan))


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


def read_sides(
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


def plan_cells(
    base: pd.DataFrame, cand: pd.DataFrame, on: list[str], paths: tuple
) -> tuple[list, pd.DataFrame, pd.DataFrame]:
    """The cells both sides hold, each (entry, base rows, candidate rows, predictions, same
    seeds), and the cells of one side only."""
    ident = [*NAMED, *on[len(_pairing(base, cand)) :]]
    ident += ["status"] if "status" in base and "status" in cand else []  # lost work: finished
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
    entry["base_detector"] = str(b_rows[0]["detector"])  # whose measured noise it takes
    entry["seed"] = _seed_text(b_rows, c_rows)
    sb, sc = _side_status(b_rows), _side_status(c_rows)
    entry["base_status"], entry["candidate_status"] = sb, sc
    entry["n_seeds_base"], entry["n_seeds_cand"] = len(b_rows), len(c_rows)
    for side, rows in (("base", b_rows), ("candidate", c_rows)):
        for name in ("accuracy", *STREAM_FIGURES):
            entry[f"{side}_{name}"] = float(np.mean([float(r.get(name, np.nan)) for r in rows]))
    entry["stream"] = is_stream(b_rows[0]) and is_stream(c_rows[0])
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
    entry["shared"] = _shared_key(b_rows, c_rows)
    return entry, b_rows, c_rows, preds, same_seeds


#: what a cell's test set is, besides its model (whose key holds its training data and seed)
TEST_SET = columns.recording("test", "stream")


def _shared_key(b_rows: list[dict], c_rows: list[dict]) -> str:
    """What makes two protocols' cells one (the same models tested on the same test set, a
    window-size cell on cross-instance's diagonal): each side's model keys and test sets;
    "" where the rows hold no model key (nothing to tell them apart by)."""
    if not all(r.get("model_key") for r in (*b_rows, *c_rows)):
        return ""
    return json.dumps(
        [
            [[str(r.get(k, "")) for k in ("model_key", *TEST_SET)] for r in rows]
            for rows in (b_rows, c_rows)
        ]
    )


def finished(e: dict) -> bool:
    return e["base_status"] == e["candidate_status"] == "ok"


def decidable(e: dict) -> bool:
    """A cell in the cell family: both sides finished it, it changed, it is not low-n."""
    return finished(e) and not e["identical"] and not e["low_n"]
