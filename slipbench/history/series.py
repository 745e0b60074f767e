"""What a series of the history is, its points over runs, and its seed spread.

A *series* is one figure of one cell of one detector (its entrant: the id, and the parameters,
input or normalization that tell two of a run's entrants apart,
:func:`slipbench.stats.factors.entrant_names`) under one protocol with its options, split and
labels: the cell key without the code identity and the seed. The code, the detector's
parameters where a run holds one set of them, the dataset where a run holds one, and the seed
are what a commit changes; they are recorded on every row (``code_identity``,
``detector_params``, ``dataset_fingerprint``, ``seed``), and a step at a commit names which of
them changed. Where one run holds rows that differ in one of those (two datasets, two slipbench
versions), they join the identity and name the series apart.

A *pooled series* is the mean of a figure over the cells of one protocol and detector, as the
gate's pooled tests read it: a change spread thinly over a protocol shows in it before any
cell's own series. Its identity holds the cells it is over, so that a run missing a cell is a
point of another series, never a mean over other cells.

The seed spread (:func:`seed_spread`) is what the gate's noise model takes from the history:
the spread of a series' figure between results of one code identity, which differ in their seed
alone, pooled with its degrees of freedom.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence

import numpy as np
import pandas as pd
import scipy  # its submodules load on first use: reading stored rows pays none

from slipbench.stats.factors import CELLS, DEFAULTS, factor_values, named_entrants
from slipbench.stats.metrics import LEVEL
from slipbench.stats.noise import SeedNoise, pool_seed_spreads
from slipbench.store.columns import BALANCE, DETECTOR, PROTOCOL, SETTING, identity
from slipbench.store.history import COLUMNS, FIGURES, RUN_COLUMNS
from slipbench.store.resolved import cell_labels, cell_text, resolve
from slipbench.store.results import row_digest

#: the settings (beyond the entrant and the cell's columns) that name a series: the conditions
#: chosen for a run (a setting at its default is left out of the name, as
#: :func:`slipbench.engine.plan.keys` leaves it out of a cell's key: a setting added later
#: renames no series of the runs before)
SETTINGS = identity(SETTING, version=False)
#: recorded on every row, a series' identity only where one run holds several of them: the
#: versions of what a run read (the data, the code, the interval method)
APART = identity(SETTING, version=True)
IDENTITY = (DETECTOR, *SETTINGS, *CELLS)
POOLED = "all cells"  # the cell of a pooled series, as labels show it
#: what a pooled series is the mean over the cells of (its label: the first and the last)
POOL = (
    PROTOCOL,
    *identity(SETTING, keyed=True, follows=False, version=False, but=(BALANCE,)),
    DETECTOR,
)
#: the source of a seed variance measured on a history (:func:`seed_spread`)
HISTORY = "the history of main"


def _digest(fields: object) -> str:
    return hashlib.sha256(json.dumps(fields, sort_keys=True).encode()).hexdigest()[:16]


def series_rows(rows: pd.DataFrame) -> pd.DataFrame:
    """One run's result rows as a history keeps them (the columns of
    :data:`slipbench.store.history.COLUMNS` but the run's): the detector
    named as its entrant (its plugin id in ``detector_id``), each figure's standard error
    (``<figure>_se``: a windowed figure's own, a streaming figure's from its 95 % bounds), and
    the row's ``series`` (a 16-hex digest of its identity) and ``series_label``.

    Raises
    ------
    ValueError
        Two rows of the run fall in one series under one seed: the rows do not say what tells
        them apart.
    """
    # resolved once (a file's own index may repeat): the texts and labels below are its
    named = named_entrants(resolve(rows.reset_index(drop=True)).rows)
    apart = [c for c in APART if c in named and factor_values(named, c).nunique() > 1]
    columns = [c for c in (*IDENTITY, *apart) if c in named]
    identity = pd.DataFrame({c: factor_values(named, c) for c in columns}, index=named.index)
    out = pd.DataFrame(index=named.index)
    for c in COLUMNS:
        if c not in RUN_COLUMNS:
            out[c] = named[c] if c in named else None
    for figure in FIGURES:
        out[f"{figure}_se"] = _standard_error(named, figure)
    out["row_digest"] = [row_digest(r) for r in rows.to_dict("records")]  # as read
    out["proven"] = _proven(rows).to_numpy()
    named_by = [
        {c: v for c, v in r.items() if v != DEFAULTS.get(c)} for r in identity.to_dict("records")
    ]
    out["series"] = [_digest(r) for r in named_by]
    out["series_label"] = [
        _label(r, cell) for r, cell in zip(identity.to_dict("records"), cell_labels(named))
    ]
    twice = out.duplicated(["series", "seed"], keep=False)
    if twice.any():
        raise ValueError(
            f"{int(twice.sum())} rows fall in one series under one seed (e.g. "
            f"{out.loc[twice, 'series_label'].iloc[0]}): the run holds results its columns "
            "do not tell apart"
        )
    return out.reset_index(drop=True)


def _proven(rows: pd.DataFrame) -> pd.Series:
    """Whether each row proved itself by its digest when read: its ``proven`` column, else
    not one of the keys :func:`slipbench.store.results.read_results` names in
    ``attrs["unproven_keys"]``; rows read otherwise prove nothing."""
    if "proven" in rows:
        return rows["proven"].fillna(False).astype(bool)
    if "unproven_keys" not in rows.attrs:
        return pd.Series(False, index=rows.index)
    return ~rows["key"].astype(str).isin(set(rows.attrs["unproven_keys"]))


def _standard_error(rows: pd.DataFrame, figure: str) -> pd.Series:
    """A figure's standard error: its own column, else its 95 % bounds' half-width / z."""
    if f"{figure}_se" in rows:
        return pd.to_numeric(rows[f"{figure}_se"], errors="coerce")
    if f"{figure}_lo" not in rows or f"{figure}_hi" not in rows:
        return pd.Series(np.nan, index=rows.index)
    hi, lo = (pd.to_numeric(rows[f"{figure}{b}"], errors="coerce") for b in ("_hi", "_lo"))
    return (hi - lo) / (2 * scipy.stats.norm.ppf(1 - (1 - LEVEL) / 2))


def _label(identity: dict, cell: str) -> str:
    """``window-size · holweg · Nano17 Index window 50 · grouped``: how pages and steps name
    it, the cell by its label (:func:`slipbench.store.resolved.cell_labels`, as the
    pull-request comment and the report name it)."""
    parts = [identity.get("protocol", ""), identity.get("detector", ""), cell]
    parts += [identity[c] for c in ("split", "labels") if identity.get(c)]
    parts += [f"{c} {identity[c][:12]}" for c in APART if identity.get(c)]
    return " · ".join(p for p in parts if p)


def shown_labels(labels: pd.Series) -> np.ndarray:
    """Series labels as people read them: a label a history recorded with its cell as JSON
    (before cells had short labels) gets the short one, computed once per distinct label."""
    codes, uniques = pd.factorize(labels.fillna("").astype(str))
    short = [" · ".join(cell_text(p) for p in u.split(" · ")) for u in uniques]
    return np.asarray(short, dtype=object)[codes] if len(short) else np.asarray([], dtype=object)


def seed_spread(
    frame: pd.DataFrame, figure: str, identities: Sequence[str] | None = None
) -> dict[str, SeedNoise]:
    """The seed spread of every series of ``figure`` in a history: its variance between
    results of one code identity (and one parameter set), which differ in their seed alone,
    pooled over the identities with their degrees of freedom (seeds - 1 each;
    :func:`slipbench.stats.noise.pool_seed_spreads`), as the noise a contrast takes (source
    :data:`HISTORY`). A result kept by several runs (same code, same seed: the same cell key)
    counts once.

    Parameters
    ----------
    frame : history rows (:func:`slipbench.store.history.read_history`).
    figure : a windowed or streaming figure the history keeps (``accuracy``, ``tn_rate``, ...).
    identities : only results of these code identities (the base's, for the gate); every
        identity where None.

    Returns
    -------
    dict
        Series (its 16-hex digest) to its :class:`~slipbench.stats.noise.SeedNoise`, for every
        series that some identity ran under two seeds or more; the variance in the figure's
        stored unit (a fraction for rates).
    """
    ok = frame[(frame["status"] == "ok") & frame[figure].notna()].drop_duplicates("key")
    if identities is not None:
        ok = ok[ok["code_identity"].isin(list(identities))]
    ok = ok[ok["code_identity"].fillna("") != ""]  # rows from before it was recorded
    found = {}
    for series, part in ok.groupby("series", sort=False):
        spreads = [
            (float(np.var(pd.to_numeric(g[figure]).to_numpy(float), ddof=1)), len(g))
            for _, g in part.groupby(["code_identity", "detector_params"], dropna=False)
            if len(g) > 1
        ]
        pool = pool_seed_spreads(spreads)
        if pool is not None:
            found[str(series)] = SeedNoise(pool.variance, pool.df, HISTORY)
    return found
