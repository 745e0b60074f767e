"""Results rows resolved once: what every reader of them would otherwise derive again.

A report, a leaderboard, a contrast, a compare and a history each need the same things of the
rows they read: who competes (each entrant's name: ``holweg (band=[39, 100])``), each
identity column's value as text (one spelling per meaning, a missing value its default), which
settings differ, which test sets hold one class, what pairs a cell across detectors, each
cell's label. :func:`resolve` computes them once and keeps them in the rows as hidden columns
(:data:`TEXT`, :data:`ENTRANT_NAME`, :data:`ONE_CLASS`, :data:`CELL_KEY`), so that any part
of the rows a step hands on still carries them: :func:`factor_values`, :func:`entrant_names`,
:func:`one_class` and :func:`cell_keys` read them where they are and derive them only from
rows that were never resolved.

Resolved rows are read, not rewritten: a step that changes an identity column of them does it
through :func:`rewritten`, which makes anew what the column's new values change; rows joined to
rows never resolved are joined as :func:`plain_rows` and resolved again.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
import pandas as pd

from slipbench.store.columns import CELL_ROLE, ENTRANT, READING, SETTING, identity
from slipbench.vocabulary import cell_label

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
#: the two inputs a detector reads (``input``): the paper's signal, or the raw channels
UNIVARIATE, CHANNELS = "univariate", "channels"
#: what two detectors' rows of one cell share (where the rows hold the column): the key's
#: columns but the detector's own, and but those another of them fixes already
CELL_COLUMNS = identity(READING, SETTING, CELL_ROLE, keyed=True, follows=False)
#: the hidden column of an identity column's text (:func:`factor_values`): ``TEXT + column``
TEXT = "_text:"
#: the hidden columns of each row's one-class flag (:func:`one_class`) and what it shares with
#: another detector's row of its cell (:func:`cell_keys`)
ONE_CLASS, CELL_KEY = "_one_class", "_cell_key"
#: the hidden column of each row's entrant (:func:`entrant_names`), its detector column kept
ENTRANT_NAME = "_entrant"
HIDDEN = (ONE_CLASS, CELL_KEY, ENTRANT_NAME)


def _text(column: str, v: Any) -> str:
    if v is None or (isinstance(v, float) and v != v):
        return DEFAULTS.get(column, "")
    if isinstance(v, float) and v.is_integer():
        return str(int(v))
    return str(v)


def factor_values(rows: pd.DataFrame, column: str) -> pd.Series:
    """A factor's values as text, one spelling per meaning: a missing value is its default
    where :data:`DEFAULTS` has one, else ""; whole floats as ints (a column another protocol's
    rows left empty reads as float). Resolved rows hold it already."""
    if TEXT + column in rows:
        return rows[TEXT + column]
    if column not in rows:
        return pd.Series(DEFAULTS.get(column, ""), index=rows.index, dtype=object)
    known: dict[tuple[type, Any], str] = {}  # each distinct value spelled once
    texts = [
        known[k] if (k := (type(v), v)) in known else known.setdefault(k, _text(column, v))
        for v in rows[column]
    ]
    return pd.Series(texts, index=rows.index, dtype=object)


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
    if ENTRANT_NAME in rows:
        return rows[ENTRANT_NAME]
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
    names = entrant_names(rows)
    text = {TEXT + "detector": names} if TEXT + "detector" in rows else {}
    return rows.assign(**{ENTRANT_ID: rows["detector"], "detector": names, **text})


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
    ranked nowhere (the report gives them a table of their own). Resolved rows hold it."""
    if ONE_CLASS in rows:
        return rows[ONE_CLASS]
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


def cell_labels(rows: pd.DataFrame) -> pd.Series:
    """(n_rows,) each row's cell as a short label (:func:`slipbench.vocabulary.cell_label`),
    each distinct cell key read once; "" where a row has none."""
    if "cell" not in rows:
        return pd.Series("", index=rows.index, dtype=object)
    keys = rows["cell"].fillna("").astype(str)
    return keys.map({k: cell_text(k) for k in keys.unique()}).astype(object)


def cell_text(cell: str) -> str:
    """A cell key (JSON) as its short label; a key that is not a JSON object as it is."""
    try:
        return cell_label(cell) if cell.startswith("{") else cell
    except (ValueError, TypeError, AttributeError):  # not JSON: shown as recorded
        return cell


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


def cell_of(row: dict) -> str:
    """What a row shares with another detector's row of the same cell, as one text (its input
    as :func:`inputs` reads it)."""
    return json.dumps(
        {c: plain(row[c]) for c in CELL_COLUMNS if c in row}, sort_keys=True, default=str
    )


def cell_keys(rows: pd.DataFrame) -> pd.Series:
    """(n_rows,) each row's :func:`cell_of`. Resolved rows hold it."""
    if CELL_KEY in rows:
        return rows[CELL_KEY]
    columns = [c for c in CELL_COLUMNS if c in rows]
    shared = rows[columns].assign(input=inputs(rows))  # as a contrast reads it
    return pd.Series(
        [cell_of(r) for r in shared.to_dict("records")], index=rows.index, dtype=object
    )


def rewritten(rows: pd.DataFrame, values: dict[str, pd.Series]) -> pd.DataFrame:
    """``rows`` with the columns of ``values`` replaced, and what :func:`resolve` derived from
    them made anew (their texts) or left to be (a cell key that read them)."""
    out = rows.assign(**values)
    texts = {TEXT + c: factor_values(plain_rows(out), c) for c in values if TEXT + c in rows}
    stale = [CELL_KEY] if CELL_KEY in rows and set(values) & set(CELL_COLUMNS) else []
    return out.assign(**texts).drop(columns=stale)


def is_resolved(rows: pd.DataFrame) -> bool:
    """Whether ``rows`` (or a part of them) carry what :func:`resolve` computed."""
    return ONE_CLASS in rows


def plain_rows(rows: pd.DataFrame) -> pd.DataFrame:
    """``rows`` without the hidden columns of :func:`resolve`: as they were read, for a step
    that hands them on as records or joins them to rows never resolved."""
    hidden = [c for c in rows if c.startswith(TEXT) or c in HIDDEN]
    return rows.drop(columns=hidden) if hidden else rows


@dataclass(frozen=True)
class Resolved:
    """Results rows and what every reader of them needs, computed once (:func:`resolve`).

    Attributes
    ----------
    rows : the rows as given, with each identity column's text (:data:`TEXT`), each row's
        entrant (:data:`ENTRANT_NAME`), one-class flag (:data:`ONE_CLASS`) and cell key
        (:data:`CELL_KEY`) beside them.

    The protocols, the entrants' names (as the rows first name them) and the settings that
    differ between the rows (:func:`differing_settings`) are computed when first asked for.
    """

    rows: pd.DataFrame

    @cached_property
    def protocols(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(self.rows["protocol"].astype(str)))

    @cached_property
    def entrants(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(entrant_names(self.rows)))

    @cached_property
    def settings(self) -> tuple[str, ...]:
        return tuple(differing_settings(self.rows))

    @property
    def one_class(self) -> pd.Series:
        return self.rows[ONE_CLASS]

    @cached_property
    def cell_labels(self) -> pd.Series:
        """(n_rows,) each row's cell label (:func:`cell_labels`), made when first asked for:
        a report names few cells by label, a history every one."""
        return cell_labels(self.rows)

    def text(self, column: str) -> pd.Series:
        """(n_rows,) ``column``'s values as text (:func:`factor_values`)."""
        return factor_values(self.rows, column)

    def setting_labels(self) -> pd.Series:
        """(n_rows,) the settings that differ, each row's as text ("" where none differs)."""
        return setting_labels(self.rows)


def resolve(rows: pd.DataFrame | Resolved) -> Resolved:
    """``rows`` resolved (:class:`Resolved`); rows resolved already are taken as they are, with
    nothing computed again."""
    if isinstance(rows, Resolved):
        return rows
    return Resolved(rows if is_resolved(rows) else rows.assign(**_derived(rows)))


def _derived(rows: pd.DataFrame) -> dict[str, pd.Series]:
    """The hidden columns of :func:`resolve`, each computed once over all of ``rows``."""
    present = [c for c in dict.fromkeys((*ENTRANTS, *SETTINGS, *CELLS)) if c in rows]
    return {
        **{TEXT + c: factor_values(rows, c) for c in present},
        ENTRANT_NAME: entrant_names(rows),
        ONE_CLASS: one_class(rows),
        CELL_KEY: cell_keys(rows),
    }
