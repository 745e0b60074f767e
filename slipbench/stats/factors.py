"""What makes two result rows different results: the fields of a cell's key, as rows record them.

A figure may pool rows that differ in their seed alone (its mean over seeds); rows that differ
in anything else in their cell's key are different results, and no figure averages them. Every
field :func:`slipbench.engine.plan.keys` hashes is listed in :data:`KEY_FIELDS` with the row
columns that record it and its role (a test fails on a key field missing here). The roles are
the results schema's (:attr:`slipbench.store.columns.Column.role`), and every list of columns
here is a query of it (:func:`slipbench.store.columns.identity`):

- ``SEED``: the repeat (``--repeats``); the one thing a figure averages over;
- ``ENTRANT`` and ``READING``: what the detector is and reads (its id, parameters, input,
  normalization): two values are two entrants, named apart (:func:`entrant_names`) in every table and leaderboard;
- ``SETTING``: the conditions of the run (data, split, labels, protocol options, ...): two values
  are two tables (:func:`setting_parts`), two blocks of a leaderboard, two cells of a compare;
- ``CELL_ROLE``: which cell of a protocol it is (its key, window, rate, training and test parts):
  what a protocol's table lays out;
- ``UNRECORDED``: fields rows do not hold (the code's identity, the random-stream scheme): a
  row's slipbench version stands for them where it differs.

The interval method and the slipbench version are not key fields but settings too: they change
what a row's figures or intervals are (the schema gives them the setting role and no key).
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from typing import Any

import numpy as np
import pandas as pd

from slipbench.store.columns import (
    CELL_ROLE,
    ENTRANT,
    READING,
    SEED,
    SETTING,
    identity,
    key_columns,
)

UNRECORDED = "unrecorded"
#: each field of a cell's key -> (its role, the row columns that record it): the results
#: schema's (:func:`slipbench.store.columns.key_columns`) and those rows do not record
KEY_FIELDS: dict[str, tuple[str, tuple[str, ...]]] = {
    **key_columns(),
    "code": (UNRECORDED, ()),
    "protocol_code": (UNRECORDED, ()),
    "streams": (UNRECORDED, ()),
    "delays": (UNRECORDED, ()),
    "model": (UNRECORDED, ()),  # a hash of the fields above, the seed among them
}
#: the two inputs a detector reads (``input``): the paper's signal, or the raw channels
UNIVARIATE, CHANNELS = "univariate", "channels"
#: the column :func:`named_entrants` keeps a detector's plugin id in
ENTRANT_ID = "detector_id"
#: what a row lacking a column meant when it was written (runs without the option)
DEFAULTS = {"normalize": "none", "input": "univariate", "balance": "within"}
#: a setting's name in captions
SETTING_NAMES = {
    "dataset_fingerprint": "dataset",
    "train_dataset_fingerprint": "trained on dataset",
    "test_dataset_fingerprint": "tested on dataset",
    "sensor_map": "sensor map",
    "protocol_params": "protocol options",
    "interval_method": "interval method",
    "slipbench_version": "slipbench",
    "detector_params": "parameters",
}


ENTRANTS = identity(ENTRANT, READING)
SETTINGS = identity(SETTING)
CELLS = identity(CELL_ROLE)


def factor_values(rows: pd.DataFrame, column: str) -> pd.Series:
    """A factor's values as text, one spelling per meaning: a missing value is its default
    where :data:`DEFAULTS` has one, else ""; whole floats as ints (a column another protocol's
    rows left empty reads as float)."""
    if column not in rows:
        return pd.Series(DEFAULTS.get(column, ""), index=rows.index, dtype=object)
    col = rows[column]

    def text(v: Any) -> str:
        if v is None or (isinstance(v, float) and v != v):
            return DEFAULTS.get(column, "")
        if isinstance(v, float) and v.is_integer():
            return str(int(v))
        return str(v)

    return col.map(text).astype(object)


def latest_runs(rows: pd.DataFrame) -> tuple[pd.DataFrame, int]:
    """The rows without those of a cell and seed that was run again later (by ``finished_at``),
    and how many were left out. Rows alike in every recorded key field and setting differ in
    what rows do not record, the code: a folder that kept an older run beside its rerun must not
    count both, or average them, as two results."""
    if "finished_at" not in rows or "seed" not in rows:
        return rows, 0
    recorded = identity(SEED, ENTRANT, READING, SETTING, CELL_ROLE)
    same = pd.DataFrame({c: factor_values(rows, c).to_numpy() for c in recorded if c in rows})
    order = np.argsort(rows["finished_at"].fillna("").astype(str).to_numpy(), kind="stable")
    earlier = np.zeros(len(rows), bool)
    earlier[order] = same.iloc[order].duplicated(keep="last").to_numpy()
    return rows[~earlier], int(earlier.sum())


def _differ(rows: pd.DataFrame, column: str, within: list[pd.Series]) -> bool:
    """Whether two rows of one group of ``within`` hold two values of ``column``."""
    if column not in rows or rows.empty:
        return False
    found = factor_values(rows, column)
    return bool(found.groupby(within).nunique().gt(1).any()) if within else found.nunique() > 1


def differing_settings(rows: pd.DataFrame) -> list[str]:
    """The settings two rows of one protocol differ in (options of two protocols differ as
    they are), and the cell columns two rows of one cell differ in (rows of one protocol and
    cell key described otherwise: another code wrote them)."""
    protocol = [factor_values(rows, "protocol")] if "protocol" in rows else []
    out = [c for c in SETTINGS if _differ(rows, c, protocol)]
    if "cell" not in rows:
        return out
    cell = [factor_values(rows, c) for c in ("protocol", "cell", *ENTRANTS)]
    return out + [c for c in CELLS if c not in ("protocol", "cell") and _differ(rows, c, cell)]


def setting_name(column: str) -> str:
    """How a setting is named in text: ``protocol options`` for ``protocol_params``."""
    return SETTING_NAMES.get(column, column.replace("_", " "))


def setting_text(column: str, value: Any) -> str:
    """``labels majority``, ``dataset aac611fa5f8a``: a setting and its value, short."""
    name = setting_name(column)
    text = str(value)
    if column.endswith("fingerprint"):
        text = text[:12]
    elif text.startswith("{"):
        try:
            params = json.loads(text)
            text = ", ".join(f"{k}={json.dumps(v)}" for k, v in params.items()) or "none"
        except json.JSONDecodeError:
            pass
    return f"{name} {text or 'not recorded'}"


def setting_parts(rows: pd.DataFrame) -> list[tuple[dict[str, str], pd.DataFrame]]:
    """The rows split by every setting that differs between them (:func:`differing_settings`):
    (setting -> value, rows) per combination, in first-seen order; the rows whole, with no
    setting named, where none differs."""
    columns = differing_settings(rows)
    if not columns:
        return [({}, rows)]
    keys = pd.DataFrame({c: factor_values(rows, c) for c in columns}, index=rows.index)
    return [
        (dict(zip(columns, k if isinstance(k, tuple) else (k,))), rows.loc[part.index])
        for k, part in keys.groupby(columns, sort=False)
    ]


def setting_labels(rows: pd.DataFrame, exclude: Iterable[str] = ()) -> pd.Series:
    """(n_rows,) the settings that differ between ``rows`` (but ``exclude``), each row's as
    text (``labels majority, dataset aac611fa5f8a``); "" where none differs."""
    columns = [c for c in differing_settings(rows) if c not in set(exclude)]
    texts = [factor_values(rows, c) for c in columns]
    return pd.Series(
        [", ".join(setting_text(c, v) for c, v in zip(columns, k)) for k in zip(*texts)]
        if columns
        else "",
        index=rows.index,
        dtype=object,
    )


def entrant_names(rows: pd.DataFrame) -> pd.Series:
    """(n_rows,) who competes: the detector's id, named apart by what makes two of its rows two
    entrants: the input and normalization where they are not the paper's (``tcn (channels)``,
    ``holweg (normalize=unit)``), and the parameters that differ where one detector ran with
    several sets (``holweg (band=[39, 100])``). Rows named already (:func:`named_entrants`)
    keep their names."""
    if ENTRANT_ID in rows:
        return rows["detector"].astype(str)
    suffix: dict[Any, list[str]] = {i: [] for i in rows.index}
    for i in rows.index[factor_values(rows, "input").eq("channels")]:
        suffix[i].append("channels")
    for i, v in factor_values(rows, "normalize").items():
        if v != DEFAULTS["normalize"]:
            suffix[i].append(f"normalize={v}")
    if "detector_params" in rows:
        for _, part in rows.groupby("detector", sort=False):
            for i, text in _params_apart(part).items():
                suffix[i].append(text)
    return pd.Series(
        [
            f"{n} ({', '.join(suffix[i])})" if suffix[i] else n
            for i, n in rows["detector"].astype(str).items()
        ],
        index=rows.index,
        dtype=object,
    )


def named_entrants(rows: pd.DataFrame) -> pd.DataFrame:
    """``rows`` with each detector named as its entrant (:func:`entrant_names`), its plugin id
    kept in ``ENTRANT_ID``: every table, figure and ranking then keeps entrants apart."""
    if ENTRANT_ID in rows:
        return rows
    return rows.assign(**{ENTRANT_ID: rows["detector"], "detector": entrant_names(rows)})


def _params_apart(part: pd.DataFrame) -> dict[Any, str]:
    """Per row of one detector's rows, the parameters that differ between them (``band=[39,
    100]``); none where they ran with one parameter set."""
    texts = part["detector_params"].fillna("{}")
    if texts.nunique() < 2:
        return {}
    params = {t: _parsed(t) for t in texts.unique()}
    apart = sorted(
        {
            k
            for p in params.values()
            for k in p
            if len({json.dumps(q.get(k)) for q in params.values()}) > 1
        }
    )
    named = {t: ", ".join(f"{k}={json.dumps(p.get(k))}" for k in apart) for t, p in params.items()}
    return {i: named[t] for i, t in texts.items()}


def _parsed(text: str) -> dict[str, Any]:
    """Parameters as their JSON says (a text that is not a JSON object: whole, as ``params``)."""
    try:
        found = json.loads(text)
    except (TypeError, json.JSONDecodeError):
        found = None
    return found if isinstance(found, dict) else {"params": text}


def one_class(rows: pd.DataFrame) -> pd.Series:
    """(n_rows,) bool: finished cells whose test set holds one class only (a slip-only transfer
    target): their accuracy is one class's rate, which a constant detector wins; they are
    ranked nowhere (the report gives them a table of their own)."""
    out = pd.Series(False, index=rows.index)
    if "constant_slip_accuracy" in rows:
        out |= pd.to_numeric(rows["constant_slip_accuracy"], errors="coerce").notna()
    if {"test_slip_windows", "test_nonslip_windows"} <= set(rows.columns):
        slip = pd.to_numeric(rows["test_slip_windows"], errors="coerce")
        nonslip = pd.to_numeric(rows["test_nonslip_windows"], errors="coerce")
        out |= (slip.eq(0) & nonslip.gt(0)) | (nonslip.eq(0) & slip.gt(0))
    if "status" in rows:
        out &= rows["status"].eq("ok")
    return out


def inputs(rows: pd.DataFrame) -> pd.Series:
    """Each row's input: its ``input`` column, "univariate" where the rows lack it (older
    results) or leave it empty."""
    if "input" not in rows:
        return pd.Series(UNIVARIATE, index=rows.index)
    return rows["input"].where(rows["input"].notna() & (rows["input"] != ""), UNIVARIATE)


def plain(value: Any) -> Any:
    """A row's value as Python: None for a missing one, a NumPy scalar as its item."""
    if value is None or (np.ndim(value) == 0 and pd.isna(value)):
        return None
    return value.item() if isinstance(value, np.generic) else value
