"""The seed variance pooled over a protocol's cells (``seed_pool``)."""

from __future__ import annotations

import numpy as np
import pytest

from slipbench.stats.metrics import Predictions, over_seeds
from slipbench.stats.noise import PROTOCOL_POOL, SeedNoise, pool_seed_spreads
from slipbench.stats.pooled import CellSides, protocol_seed_pool


def _seed(rng: np.random.Generator, luck: float) -> Predictions:
    """One seed's test set: 10 + 10 trials of 10-40 windows, right with a trial's own odds."""
    windows = rng.integers(10, 41, 20)
    p = 1 / (1 + np.exp(-(rng.normal(1.4, 0.5, 20) + luck)))
    y = np.repeat(np.arange(20) < 10, windows)
    hit = rng.random(windows.sum()) < np.repeat(p, windows)
    return Predictions(y, np.where(hit, y, ~y), np.repeat(np.arange(20), windows).astype(str))


def _cells(n_cells: int, n_seeds: int, seed: int = 0) -> list[CellSides]:
    rng = np.random.default_rng(seed)
    luck = rng.normal(0, 0.2, (2, n_seeds))  # a seed's luck, shared by the cells
    return [
        CellSides(
            [_seed(rng, luck[0, s]) for s in range(n_seeds)],
            [_seed(rng, luck[1, s]) for s in range(n_seeds)],
            list(range(n_seeds)),
            list(range(n_seeds, 2 * n_seeds)),
        )
        for _ in range(n_cells)
    ]


def test_pool_weighs_each_side_by_its_degrees_of_freedom():
    pool = pool_seed_spreads([(0.01, 3), (0.04, 2), (0.5, 1), (np.nan, 3)])
    assert pool is not None and pool.variance == pytest.approx((0.01 * 2 + 0.04 * 1) / 3)
    assert (pool.df, pool.source) == (3.0, PROTOCOL_POOL)
    assert pool_seed_spreads([(0.5, 1), (np.nan, 4)]) is None


def test_protocol_pool_sums_the_cells_degrees_of_freedom():
    pools = protocol_seed_pool(_cells(4, 3), ("accuracy", "tn_rate"))
    assert set(pools) == {"accuracy", "tn_rate"}
    assert pools["accuracy"].df == 4 * 2 * (3 - 1)  # cells x sides x (seeds - 1)
    assert pools["accuracy"].variance > 0
    assert protocol_seed_pool(_cells(2, 1), ("accuracy",)) == {}  # one seed: nothing to pool


def test_a_pool_gives_the_cell_the_protocols_degrees_of_freedom_and_narrows_it():
    cells = _cells(6, 3)
    pool = protocol_seed_pool(cells, ("accuracy",))
    own = over_seeds(cells[0].base, cells[0].cand, 0, figures=("accuracy",), n_resamples=199)
    pooled = over_seeds(
        cells[0].base, cells[0].cand, 0, figures=("accuracy",), n_resamples=199, seed_pool=pool
    )
    assert own["df"] < 5 < pooled["df"]

    def width(r: dict) -> float:
        return r["d_accuracy_hi"] - r["d_accuracy_lo"]

    assert width(pooled) < width(own)


def test_more_seeds_never_widen_a_cell_under_one_pool():
    """The seed term is the pool's variance over the side's seeds on the pool's degrees of
    freedom: 3 seeds per side give a narrower interval than the first of them alone."""
    cells = _cells(6, 3)
    pool = protocol_seed_pool(cells, ("accuracy",))
    c = cells[0]
    kw = {"figures": ("accuracy",), "n_resamples": 199, "seed_pool": pool}
    three = over_seeds(c.base, c.cand, 0, **kw)
    one = over_seeds(c.base[:1], c.cand[:1], 0, **kw)
    assert three["d_accuracy_se"] < one["d_accuracy_se"]
    assert (
        three["d_accuracy_hi"] - three["d_accuracy_lo"]
        < one["d_accuracy_hi"] - one["d_accuracy_lo"]
    )


def test_a_pool_of_no_seed_variance_leaves_one_seed_per_side_as_it_was():
    c = _cells(1, 1)[0]
    kw = {"figures": ("accuracy",), "n_resamples": 199}
    plain = over_seeds(c.base, c.cand, 0, **kw)
    pooled = over_seeds(c.base, c.cand, 0, seed_pool={"accuracy": SeedNoise(0.0, 10.0)}, **kw)
    assert pooled == plain


def test_a_cell_retraining_moves_more_than_the_pool_keeps_its_own_spread():
    """A transfer cell whose seeds scatter by tens of points is not judged on the calm cells'
    pooled spread: its side's own spread, on its own degrees of freedom, stands."""
    cells = _cells(6, 3)
    rng = np.random.default_rng(7)
    noisy = CellSides(
        [_seed(rng, luck) for luck in (-2.0, 0.0, 2.0)],
        [_seed(rng, luck) for luck in (2.0, -2.0, 0.0)],
        [0, 1, 2],
        [3, 4, 5],
    )
    pool = protocol_seed_pool(cells, ("accuracy",))
    kw = {"figures": ("accuracy",), "n_resamples": 199}
    own = over_seeds(noisy.base, noisy.cand, 0, **kw)
    pooled = over_seeds(noisy.base, noisy.cand, 0, seed_pool=pool, **kw)
    assert pooled["df"] < 10 < pool["accuracy"].df
    assert pooled["d_accuracy_se"] == pytest.approx(own["d_accuracy_se"], rel=0.05)
    calm = over_seeds(cells[0].base, cells[0].cand, 0, seed_pool=pool, **kw)
    assert calm["df"] > 10  # the calm cells keep the pool
