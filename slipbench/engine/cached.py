"""Which stored cells a run may reuse, and a fully cached run answered from the store alone.

A cell's key holds the data's fingerprint, the code, the parameters and the seed, never the
samples themselves (:func:`slipbench.engine.plan.keys`): a run whose every cell is stored can
be answered from the recordings table and the fingerprint the dataset's writer stored, without
reading the samples, computing the signal or the windows, or starting a worker. Where any cell
must be computed, :func:`cached_rows` says so and the run goes the whole way
(:func:`slipbench.engine.runner.evaluate`), which verifies the samples against that fingerprint.
"""

from __future__ import annotations

import warnings

import pandas as pd

from slipbench.engine.plan import Run, keys
from slipbench.store.keys import changed_reads
from slipbench.store.results import ResultsStore


def refits(stored: dict[str, dict], warn: bool = True) -> set[str]:
    """Model keys of stored cells whose fit read a file outside its code identity that has
    changed since: they are fitted again (with ``warn``, a warning names the file)."""
    refit: set[str] = set()
    for row in stored.values():
        changed = changed_reads(row) if row.get("unkeyed_reads") else []
        if changed and str(row.get("model_key")) not in refit:
            refit.add(str(row.get("model_key")))
            if warn:
                warnings.warn(
                    f"detector {row.get('detector')!r}: {', '.join(changed)} changed since its "
                    "cells were computed (a file its fit read, not part of its code identity): "
                    "refitting",
                    stacklevel=2,
                )
    return refit


def reusable(stored: dict[str, dict], refit: set[str]) -> set[str]:
    """Keys of the stored cells a run takes as they are: finished (ok or skipped), and not of a
    model in ``refit``."""
    return {
        k
        for k, r in stored.items()
        if r.get("status") in ("ok", "skipped") and r.get("model_key") not in refit
    }


def cached_rows(
    recordings: pd.DataFrame, fingerprint: str, runs: list[Run], store: ResultsStore
) -> pd.DataFrame | None:
    """The rows of ``runs`` on the dataset of ``recordings`` (canonical, with ``n_samples``) and
    ``fingerprint``, in protocol order, where ``store`` holds every one of their cells
    reusable; None where any cell must be computed. Reads nothing but the store."""
    stored = store.finished()
    if not stored:
        return None
    done = reusable(stored, refits(stored, warn=False))  # the whole run warns, if it comes to it
    rows = []
    for run in runs:
        run.validate()
        for cell in run.cells_or_stand_in(recordings):
            key, _ = keys(run, cell, fingerprint)
            if key not in done:
                return None
            rows.append(stored[key])
    store.consolidate()  # only reads, where results.parquet already holds every cell
    return pd.DataFrame(rows)
