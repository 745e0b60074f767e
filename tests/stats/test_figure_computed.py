"""A windowed figure is computed by its own code: a rate by the share of its windows, any other
by its entry in ``slipbench.stats.metrics.COMPUTED``. A figure declared in the results schema
without either is refused when the module is imported, never computed as another figure (before,
every non-rate figure but the balanced accuracy fell through to the AUROC)."""

from __future__ import annotations

import importlib.util
import sys

import pytest

from slipbench.stats import metrics
from slipbench.store import columns
from slipbench.store.columns import NONSLIP_WINDOWS, WINDOWED, Figure, figures

#: a new windowed figure that is no share of windows, declared and never computed
PLANTED = Figure("spread_of_scores", "fraction", "a figure without a computation")


def test_every_shipped_windowed_figure_has_its_computation():
    assert metrics.uncomputed(figures(WINDOWED), metrics.COMPUTED) == []
    own = {f.name for f in figures(WINDOWED) if not f.rate}
    assert set(metrics.COMPUTED) == own  # no computation of a figure the schema lacks


def test_a_figure_without_a_computation_is_named():
    rate = Figure(
        "tn_rate_again", "fraction", "a rate: its windows compute it", rate=NONSLIP_WINDOWS
    )
    declared = (*figures(WINDOWED), PLANTED, rate)
    assert metrics.uncomputed(declared, metrics.COMPUTED) == [PLANTED.name]
    with pytest.raises(NotImplementedError, match=f"{PLANTED.name} without a computation"):
        metrics.check_computed(declared, metrics.COMPUTED)


def test_the_module_refuses_it_at_import(monkeypatch):
    """The schema gains the figure; a fresh copy of the metrics module (under another name, not
    the one every other module holds) fails on import, naming it."""
    monkeypatch.setitem(columns.FIGURES, PLANTED.name, PLANTED)
    spec = importlib.util.spec_from_file_location("metrics_with_planted", metrics.__file__)
    fresh = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, fresh)  # its dataclasses look it up there
    with pytest.raises(NotImplementedError, match=PLANTED.name):
        spec.loader.exec_module(fresh)
