"""The retraining noise a contrast's interval holds: :class:`SeedNoise`.

A detector trained again under another seed (another split, another initialisation) scores
otherwise; a change between two detectors, or two versions of one, moves with it. A contrast
(:mod:`slipbench.stats.contrast`) takes that noise as one small object: the variance one seed
adds, its degrees of freedom and where it was measured. Today's sources:

- :data:`OWN_SEEDS`: the spread of the contrast's own seeds (``S - 1`` degrees of freedom);
- :data:`PROTOCOL_POOL`: the spreads of a protocol's cells pooled (:func:`pool_seed_spreads`),
  their degrees of freedom summed.

A calibration of the bench, or the history of main, passes its own ``SeedNoise`` with its own
degrees of freedom; a contrast whose own seeds are one per side then decides on it, where its
own seeds could not.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

#: the contrast's own seeds, their spread about their mean
OWN_SEEDS = "the sides' own seeds"
#: the protocol's cells, their seed spreads pooled
PROTOCOL_POOL = "the protocol's pooled seed variance"


@dataclass(frozen=True)
class SeedNoise:
    """The variance one seed adds to what a contrast draws its seeds of, with its degrees of
    freedom and its source.

    Attributes
    ----------
    variance : float
        The variance of one seed's value about the mean over seeds, in the figure's stored unit
        squared (fractions: 0.0004 is a 2-point seed SD): of the seeds' paired differences
        where both sides ran the same seeds, else of each side's figure. ``S`` seeds of a side
        add ``variance / S`` to the contrast's variance.
    df : float
        Its degrees of freedom (> 0): the t quantile of the seed term is taken at them.
    source : str
        Where it was measured, said beside every verdict that used it (:data:`OWN_SEEDS`,
        :data:`PROTOCOL_POOL`, or a calibration's own words).
    """

    variance: float
    df: float
    source: str = PROTOCOL_POOL

    def __post_init__(self) -> None:
        if not (self.variance >= 0 and np.isfinite(self.variance)):
            raise ValueError(f"a seed variance is finite and >= 0, got {self.variance}")
        if not self.df > 0:
            raise ValueError(f"a seed variance needs degrees of freedom > 0, got {self.df}")

    def of_mean(self, n_seeds: int) -> float:
        """The variance it adds to a mean over ``n_seeds`` seeds."""
        return self.variance / max(1, n_seeds)


def own_seeds(values: Iterable[float]) -> SeedNoise | None:
    """The spread of a contrast's own per-seed values (ddof 1, ``S - 1`` degrees of freedom);
    None with fewer than two finite values."""
    v = np.asarray([x for x in values if np.isfinite(x)], float)
    if len(v) < 2:
        return None
    return SeedNoise(float(v.var(ddof=1)), float(len(v) - 1), OWN_SEEDS)


def pool_seed_spreads(spreads: Iterable[tuple[float, int]]) -> SeedNoise | None:
    """The pooled seed variance of ``(variance over a side's seeds (ddof 1), seeds)`` pairs,
    one per cell side, weighted by and carrying their degrees of freedom; sides of one seed
    and NaN spreads carry nothing. None where none is left."""
    kept = [(float(v), n - 1) for v, n in spreads if n >= 2 and np.isfinite(v)]
    df = sum(d for _, d in kept)
    if df == 0:
        return None
    return SeedNoise(sum(v * d for v, d in kept) / df, float(df), PROTOCOL_POOL)


class NoiseSource(Protocol):
    """Seed noise measured outside a comparison (a bench's calibration; the history of main):
    per detector, protocol and figure (of the protocol's mean where ``cell`` is None, else of
    that cell), for sides run under the same seeds (``paired``) or apart; None where it has
    none."""

    def seed_noise(
        self, detector: str, protocol: str, figure: str, cell: str | None, paired: bool
    ) -> SeedNoise | None: ...


def combined(found: Iterable[SeedNoise]) -> SeedNoise | None:
    """Seed variances of one figure from several sources as one: weighted by and carrying
    their degrees of freedom (each an estimate of the same variance), their sources named
    together. None where none is given."""
    kept = list(found)
    if not kept:
        return None
    df = sum(n.df for n in kept)
    variance = sum(n.variance * n.df for n in kept) / df
    return SeedNoise(variance, df, " and ".join(dict.fromkeys(n.source for n in kept)))
