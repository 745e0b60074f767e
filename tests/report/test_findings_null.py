"""A detector that flips a coin per window shows none of the paper's findings: over 20 seeds,
every finding reads "shown" in at most 1 (the criteria judge contrasts by their intervals)."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pandas as pd
import pytest
from resultgen import fake_rows

from slipbench.report.document import layouts
from slipbench.report.findings import paper_findings_table
from slipbench.stats.metrics import wilson_ci

PROTOCOLS = ("window-size", "sampling-rate", "material-holdout", "speed-holdout", "cross-instance")
WINDOWS = 120  # test windows per class in a cell


def coin_rows(seed: int) -> pd.DataFrame:
    """Result rows of coin flips: each cell's TP and TN rates are a binomial draw at 0.5, its
    intervals Wilson's (windows are independent under a coin flip)."""
    rng = np.random.default_rng(seed)
    parts = [fake_rows(p, "lstm") for p in PROTOCOLS] + [fake_rows("window-size", "holweg")]
    rows = pd.concat(parts, ignore_index=True)
    tp, tn = rng.binomial(WINDOWS, 0.5, (2, len(rows)))
    for name, hits, n in (
        ("tp_rate", tp, WINDOWS),
        ("tn_rate", tn, WINDOWS),
        ("accuracy", tp + tn, 2 * WINDOWS),
    ):
        rows[name] = hits / n
        bounds = np.array([wilson_ci(h, n) for h in hits])
        rows[f"{name}_lo"], rows[f"{name}_hi"] = bounds[:, 0], bounds[:, 1]
    return rows


@pytest.mark.slow  # 20 reports of 6 protocols: about 20 s of CPU
def test_a_coin_flip_shows_no_finding():
    yes: Counter[str] = Counter()
    judged: Counter[str] = Counter()
    for seed in range(20):
        rows = coin_rows(seed)
        table = paper_findings_table(rows, layouts(rows))
        assert table is not None and len(table.rows) == 9
        for (finding,), (_, _, shown, _) in zip(table.rows, table.cells):
            judged[finding] += shown != "—"
            yes[finding] += shown == "shown"
    assert all(n == 20 for n in judged.values()), judged  # every finding is judged each time
    assert all(n <= 1 for n in yes.values()), yes
