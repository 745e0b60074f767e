"""The one contrast: its states against a margin, its intervals from parts, and its noise input
(a seed variance from elsewhere deciding what one seed cannot)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from resultgen import fake_rows
from scipy.stats import t as student_t

from slipbench.stats.contrast import (
    CONTRADICTED,
    ONE_SEED,
    SHOWN,
    UNDECIDED,
    Contrast,
    from_parts,
    from_rows,
    margin_of,
    pair_seeds,
    paired_change,
    state_of,
)
from slipbench.stats.factors import named_entrants
from slipbench.stats.leaderboard import leaderboard
from slipbench.stats.noise import OWN_SEEDS, PROTOCOL_POOL, SeedNoise, own_seeds


@pytest.mark.parametrize(
    "lo, hi, state",
    [
        (0.02, 0.05, SHOWN),  # beyond +margin
        (-0.05, -0.02, SHOWN),
        (-0.005, 0.008, CONTRADICTED),  # inside: the only "no"
        (-0.005, 0.03, UNDECIDED),  # within and beyond
        (0.005, 0.03, UNDECIDED),  # excludes 0, not the margin
        (np.nan, np.nan, UNDECIDED),
    ],
)
def test_a_state_reads_its_interval_against_the_margin(lo, hi, state):
    assert state_of(lo, hi, 0.01) == state
    c = Contrast((lo + hi) / 2, lo, hi, margin=0.01)
    assert c.state == state and (c.why == "") == (state != UNDECIDED)
    assert c.direction == (0 if state != SHOWN else (1 if lo > 0 else -1))


def test_a_missing_noise_leaves_any_interval_undecided():
    c = Contrast(0.2, 0.15, 0.25, margin=0.01, missing=ONE_SEED)
    assert c.state == UNDECIDED and c.why == ONE_SEED and c.direction == 0


def test_an_interval_from_parts_is_given_back_by_its_se_and_df():
    """Banerjee's half-width over a normal and a 2-df part; ``estimate +- t(df) se`` gives it
    back, which is what the pooling across datasets reads."""
    parts = [(0.01**2, np.inf), (0.02**2, 2.0)]
    c = from_parts(0.05, parts, 0.95, 0.01)
    half = np.sqrt(1.959964**2 * 0.01**2 + student_t.ppf(0.975, 2) ** 2 * 0.02**2)
    assert (c.lo, c.hi) == pytest.approx((0.05 - half, 0.05 + half))
    assert c.se == pytest.approx(np.hypot(0.01, 0.02))
    assert student_t.ppf(0.975, c.df) * c.se == pytest.approx(half, rel=1e-6)
    assert 2 < c.df < 30
    # a part of no degrees of freedom (one block) leaves it without an interval
    assert not from_parts(0.05, [(0.01, 0.0)]).judged


def _terms(seeds: int, shift: float = 0.05) -> pd.DataFrame:
    rng = np.random.default_rng(seeds)
    lines = []
    for s in range(seeds):
        luck = rng.normal(0, 0.002)
        for unit in ("a", "b"):
            for sign, level in ((1.0, 0.8 + shift + luck), (-1.0, 0.8)):
                lines.append(
                    {"unit": unit, "seed": s, "weight": sign / 2, "mean": level, "se": 0.01}
                )
    return pd.DataFrame(lines)


def test_from_rows_takes_its_own_seeds_and_says_one_seed_is_not_enough():
    three = from_rows(_terms(3), margin=0.01)
    assert three.missing == "" and OWN_SEEDS in three.noise and three.seeds == (0, 1, 2)
    assert three.state == SHOWN and three.direction == 1
    one = from_rows(_terms(1), margin=0.01)
    assert one.missing == ONE_SEED and one.state == UNDECIDED and one.judged


def test_a_seed_variance_from_elsewhere_decides_one_seed():
    """The noise input: a calibration's seed variance with its own degrees of freedom stands for
    the seed term one seed cannot measure, said as its source; it widens the interval."""
    calibration = SeedNoise(0.01**2, 40.0, "the bench's calibration")
    one = from_rows(_terms(1), margin=0.01)
    fed = from_rows(_terms(1), margin=0.01, noise=calibration)
    assert fed.missing == "" and fed.noise[-1] == "the bench's calibration"
    assert fed.state == SHOWN and (fed.hi - fed.lo) > (one.hi - one.lo)
    # where the rows hold several seeds, their own spread is the seed term
    assert from_rows(_terms(3), noise=calibration) == from_rows(_terms(3))


def test_seed_noise_is_checked_and_its_sources_named():
    with pytest.raises(ValueError, match="finite and >= 0"):
        SeedNoise(-1.0, 3.0)
    with pytest.raises(ValueError, match="degrees of freedom"):
        SeedNoise(0.1, 0.0)
    assert own_seeds([0.1]) is None
    own = own_seeds([0.1, 0.2, 0.3])
    assert own is not None and own.variance == pytest.approx(0.01)
    assert (own.df, own.source) == (2.0, OWN_SEEDS)
    assert SeedNoise(0.1, 3.0).source == PROTOCOL_POOL
    assert SeedNoise(0.3, 3.0).of_mean(3) == pytest.approx(0.1)


def test_one_seed_pairs_decide_on_a_seed_variance_from_elsewhere():
    """The leaderboard and "vs baseline" take the same input: with it, a one-seed board's pairs
    are decided; without, undecided."""
    base = fake_rows("window-size", "features")
    noise = np.random.default_rng(0).normal(0, 0.005, len(base))
    holweg = base.assign(detector="holweg", key=base["key"] + "h")
    holweg["accuracy"] = base["accuracy"] + 0.05 + noise
    rows = named_entrants(pd.concat([base, holweg], ignore_index=True))
    calibration = SeedNoise(0.005**2, 30.0, "the history of main")
    assert not leaderboard(rows).pairs["decided"].any()
    (pair,) = leaderboard(rows, noise=calibration).pairs.itertuples()
    assert pair.decided and pair.state == SHOWN
    both = pair_seeds(*(rows[rows["detector"] == d] for d in ("features", "holweg")))
    alone, fed = paired_change(both), paired_change(both, noise=calibration)
    assert alone.missing == ONE_SEED and alone.state == UNDECIDED
    assert fed.missing == "" and fed.state == SHOWN and fed.lo < alone.lo
    assert fed.noise[-1] == "the history of main"


def test_the_margin_is_the_figures_tolerance():
    assert margin_of("accuracy") == pytest.approx(0.01)
    assert margin_of("median_delay_ms") == pytest.approx(10.0)
    assert margin_of("auroc") == pytest.approx(0.01)  # not gated: one point of a fraction
