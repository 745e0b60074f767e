"""Every proposal judged in one batch reads what the scalar path reads, number for number."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from slipbench.history.judging import Side, judge
from slipbench.history.steps import SERIES_ALPHA, _runs_needed, _verdict, step_change
from slipbench.stats.contrast import family_level


def _scalar(sides, figure, margin, proposals, low_n) -> dict:
    """The per-proposal path: step_change, _verdict and _runs_needed."""
    b, a = ([{figure: v, f"{figure}_se": s, "df": d} for v, s, d in zip(*x)] for x in sides)
    change = step_change((b, a), figure, family_level(proposals, SERIES_ALPHA), margin)
    seeds = min(len(b), len(a))
    return {
        **_verdict(change, figure, low_n, proposals),
        "runs_needed": _runs_needed(change, proposals, seeds),
    }


def _proposals(rng: np.random.Generator, count: int) -> list:
    """Sides of 1-6 seeds whose changes fall beyond, inside and across the tolerance."""
    out = []
    for i in range(count):
        shift = rng.choice([0.0, 0.005, 0.02, 0.05, -0.03])
        spread = rng.choice([0.0005, 0.005, 0.02])
        sides = []
        for j in range(2):
            n = 1 if i % 7 == 0 else int(rng.integers(1, 7))
            value = 0.8 + j * shift + spread * rng.standard_normal(n)
            se = rng.uniform(0.002, 0.02, n)
            df = rng.choice([5.0, 30.0, np.inf], n)
            sides.append(Side(value, se, df))
        out.append((sides[0], sides[1]))
    return out


@pytest.mark.parametrize("figure, margin", [("tp_rate", 0.01), ("accuracy", 0.005)])
def test_a_batch_judges_as_each_proposal_alone(figure, margin):
    rng = np.random.default_rng(7)
    sides = _proposals(rng, 300)
    proposals = rng.integers(1, 5, len(sides))
    low_n = rng.random(len(sides)) < 0.1
    got = pd.DataFrame(judge(sides, figure, margin, (proposals, low_n)))
    want = pd.DataFrame(
        [
            _scalar(((s.value, s.se, s.df) for s in pair), figure, margin, int(k), bool(low))
            for pair, k, low in zip(sides, proposals, low_n)
        ]
    )
    pd.testing.assert_frame_equal(got[want.columns], want, check_exact=True, check_dtype=False)
    verdicts = set(want["verdict"])
    assert verdicts >= {"inconclusive", "not confirmed", "regressed", "improved"}
    assert (want["runs_needed"] > 0).sum() > 10  # the bisection ran for many
