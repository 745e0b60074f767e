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

What names and tells rows apart (each factor's text, the entrants' names, the settings that
differ, the one-class cells) is computed once by the resolved reader,
:mod:`slipbench.store.resolved`, and named here as before; this module keeps the key's fields
and what splits rows by them.
"""

from __future__ import annotations

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
from slipbench.store.resolved import (  # noqa: F401  (this module's names since it began)
    CELLS,
    CHANNELS,
    DEFAULTS,
    ENTRANT_ID,
    ENTRANTS,
    SETTING_NAMES,
    SETTINGS,
    UNIVARIATE,
    differing_settings,
    entrant_names,
    factor_values,
    inputs,
    named_entrants,
    one_class,
    plain,
    setting_labels,
    setting_name,
    setting_parts,
    setting_text,
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
