"""What a gate can see before it runs: for one pooled test (a protocol's mean of a figure, one
detector), the smallest drop beyond its tolerance it flags with 80 % power, from a calibrated
seed noise, at the bench's seeds and with sequential looks up to its budget.

A comparison of ``n`` seeds per side has the standard error ``sd / sqrt(n)``, with ``sd`` the
calibrated standard deviation of one seed's change between two equal sides
(:meth:`slipbench.stats.calibration.Noise.per_seed`) and ``df`` its degrees of freedom. As in
:func:`slipbench.gate.gate.resolution`, a test at one-sided level ``a`` flags a drop of
``tolerance + X`` with power 80 %, where

    X = se * (t(1 - a, df) + t(0.80, df)).

Each test is held at ``a = alpha / (2 N)``: Bonferroni over the ``N`` pooled tests of the
family, two-sided. With a budget above the bench's seeds, the looks run at ``seeds, 2 seeds,
..`` up to the budget (:func:`looks`) and each flags at its Lan-DeMets O'Brien-Fleming nominal
level (:mod:`slipbench.stats.sequential`), which spends ``a`` over them. **At the bench's
seeds** ``X`` is the first look's, at its own nominal level (a budget makes it stricter than a
single look's ``a``); **at the budget** it is the last look's: the drop the last look alone
flags with 80 % power (earlier looks only add power, so this errs safe). A test **decides** its tolerance where ``X`` at the budget is at most the tolerance: a
harmless change then reads "no regression" and a drop of twice the tolerance is flagged. Where
it does not, :class:`Sight` says what would: a budget of more seeds, a larger tolerance, or
more data (the scale, assuming the variance falls in proportion to the data: stated wherever
it is used, since retraining noise need not).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import scipy  # its submodules load on first use: reading stored rows pays none

from slipbench.gate.gate import POWER
from slipbench.gate.sequential import boundaries, fractions_of

#: the most looks :func:`sight` allows a budget it suggests (a workflow that runs the bench
#: ten times is as far as one would go; a budget beyond it asks for a larger tolerance)
MAX_LOOKS = 10


@dataclass(frozen=True)
class Design:
    """How a gate looks: ``seeds`` per side at its first look, up to ``budget`` per side in
    steps of ``seeds``; ``tests`` pooled tests in its family, held at ``alpha`` together
    (two-sided)."""

    seeds: int
    budget: int
    tests: int
    alpha: float

    def __post_init__(self) -> None:
        if not 1 <= self.seeds <= self.budget:
            raise ValueError(
                f"a design needs 1 <= seeds <= budget, got {self.seeds}, {self.budget}"
            )
        if self.tests < 1 or not 0 < self.alpha < 1:
            raise ValueError(f"a design needs tests >= 1 and alpha in (0, 1), got {self}")

    @property
    def level(self) -> float:
        """Each test's one-sided level: ``alpha / (2 tests)``."""
        return self.alpha / (2 * self.tests)


def looks(seeds: int, budget: int) -> list[int]:
    """Seeds per side at each look: ``seeds``, then ``seeds`` more at a time, the last at
    ``budget``."""
    return [*range(seeds, budget, seeds), budget]


def nominal_levels(design: Design) -> list[float]:
    """Each look's one-sided nominal level (:func:`looks`), the test's level spent over them."""
    return list(_nominal(design.seeds, design.budget, design.level))


@cache
def _nominal(seeds: int, budget: int, level: float) -> tuple[float, ...]:
    at = looks(seeds, budget)
    if len(at) == 1:
        return (level,)
    return boundaries(fractions_of(at, budget), level).nominal


def resolution(sd: float, df: float, seeds: int, level: float) -> float:
    """``X``: the drop beyond the tolerance flagged with ``POWER`` by a one-sided test at
    ``level`` of a mean over ``seeds`` seeds whose one seed varies by ``sd`` on ``df`` degrees
    of freedom (infinite ``df``: normal quantiles). 0 where the noise is 0; NaN where unknown."""
    if not (math.isfinite(sd) and df > 0):
        return math.nan
    if sd == 0:
        return 0.0
    q = scipy.stats.t.isf(level, df) + scipy.stats.t.ppf(POWER, df)
    return float(sd / math.sqrt(seeds) * q)


@dataclass(frozen=True)
class Sight:
    """What one pooled test of a design sees, in the figure's units (points of a rate).

    ``at_seeds``: ``X`` at the first look (the bench's seeds, at that look's level);
    ``at_budget``: ``X`` at the last look (the budget); ``budget_needed``: the fewest seeds per side whose looks decide
    the tolerance (0: none in ``MAX_LOOKS`` looks); ``data_needed``: how many times the data the
    budget needs to decide, if the variance falls in proportion to the data (1 or less: it
    decides)."""

    tolerance: float
    sd: float
    df: float
    at_seeds: float
    at_budget: float
    budget_needed: int
    data_needed: float

    @property
    def decides(self) -> bool:
        return self.at_budget <= self.tolerance

    @property
    def decides_at_seeds(self) -> bool:
        return self.at_seeds <= self.tolerance

    @property
    def detectable(self) -> float:
        """The drop flagged with 80 % power at the budget: tolerance + ``at_budget``."""
        return self.tolerance + self.at_budget


def sight(sd: float, df: float, tolerance: float, design: Design) -> Sight:
    """What a pooled test whose one seed varies by ``sd`` (on ``df`` degrees of freedom) sees
    under ``design`` against ``tolerance``."""
    levels = nominal_levels(design)
    at_seeds = resolution(sd, df, design.seeds, levels[0])
    at_budget = resolution(sd, df, design.budget, levels[-1])
    return Sight(
        tolerance=tolerance,
        sd=sd,
        df=df,
        at_seeds=at_seeds,
        at_budget=at_budget,
        budget_needed=_budget_needed(sd, df, tolerance, design),
        data_needed=(at_budget / tolerance) ** 2 if math.isfinite(at_budget) else math.nan,
    )


def _budget_needed(sd: float, df: float, tolerance: float, design: Design) -> int:
    """The fewest seeds per side (a multiple of the first look's, up to ``MAX_LOOKS`` looks)
    whose looks decide ``tolerance``; 0 where none does or the noise is unknown."""
    if not math.isfinite(resolution(sd, df, 1, design.level)):
        return 0
    for steps in range(1, MAX_LOOKS + 1):
        budget = steps * design.seeds
        level = _nominal(design.seeds, budget, design.level)[-1]
        if resolution(sd, df, budget, level) <= tolerance:
            return budget
    return 0
