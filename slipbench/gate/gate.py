"""The CI gate's family of figures: which figures it reads, the tolerance of each, and the power
of every "no regression".

Windowed cells are judged on accuracy, TN rate (false alarms) and TP rate (misses); streaming
cells on false alarms per minute, detection rate and median delay. A figure *regressed* where
its change is worse than its tolerance (in its own units: points of a rate, false alarms per
minute, ms): its interval, at the family's Bonferroni level, lies beyond the tolerance on the
worse side (:mod:`slipbench.stats.contrast`); higher is worse for false alarms per minute and
delays.

Power. A pooled test that flags nothing says how large a drop it would have flagged with
``POWER`` (80 %): with ``se`` its standard error, ``df`` its degrees of freedom and ``N`` the
pooled tests in the family, the resolution is ``X = se * (t(1 - alpha / (2 N), df) + t(POWER,
df))`` (the family's Bonferroni level), and a drop of ``tolerance + X`` is
flagged with 80 % power. Where ``X`` exceeds the tolerance, the noise is larger than what the
gate is asked to hold: the test is *undecided*, and ``n * (X / tolerance) ** 2`` seeds (or test
trials) would decide it, the standard error scaling as ``sqrt(n / n')``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy  # scipy.stats loads on first use (see slipbench.stats)

from slipbench.errors import UsageError
from slipbench.store.columns import FIGURES, STREAMED, WINDOWED, figures, names

#: the figures the gate reads, each with its default tolerance (the results schema's)
DEFAULT_TOLERANCE: dict[str, float] = {
    f.name: float(f.tolerance) for f in figures(gated=True) if f.tolerance is not None
}
POWER = 0.8
#: the most seeds or trials :func:`needed` counts to
MAX_NEEDED = 100_000


def unit(figure: str) -> str:
    """The unit of a change of ``figure`` and of its tolerance."""
    return FIGURES[figure].change_unit


@dataclass(frozen=True)
class Gate:
    """The figures the gate reads and the tolerance of each, in the figure's units; a cell or
    pooled change whose interval is wider than ``max_width`` points decides nothing.

    ``seeds`` and ``budget`` (a bench's ``repeats`` and ``[gate] budget``): the gate looks at
    ``seeds`` per side, then ``seeds`` more at a time up to ``budget``
    (:func:`slipbench.stats.power.looks`), each look at its share of the error
    (:mod:`slipbench.stats.sequential`); 0: one look, at whatever seeds the sides hold."""

    tolerances: Mapping[str, float] = field(default_factory=lambda: dict(DEFAULT_TOLERANCE))
    max_width: float = 40.0
    seeds: int = 0
    budget: int = 0

    def __post_init__(self) -> None:
        unknown = set(self.tolerances) - set(DEFAULT_TOLERANCE)
        if unknown:
            raise UsageError(
                f"the gate reads {', '.join(DEFAULT_TOLERANCE)}; unknown figure "
                f"{', '.join(sorted(unknown))}"
            )
        bad = {k: v for k, v in self.tolerances.items() if not (v > 0 and math.isfinite(v))}
        if bad:
            raise UsageError(
                f"a tolerance must be > 0 (a gate that must see any drop never decides "
                f"'no regression'): {', '.join(f'{k} = {v}' for k, v in bad.items())}"
            )
        if not self.max_width > 0:
            raise UsageError(f"--max-width must be > 0 points, got {self.max_width}")
        if self.seeds and not 1 <= self.seeds <= self.budget:
            raise UsageError(
                f"the gate's looks need 1 <= seeds <= budget, got {self.seeds}, {self.budget}"
            )

    @property
    def sequential(self) -> bool:
        """Looks at more seeds follow where a look is undecided."""
        return 0 < self.seeds < self.budget

    @classmethod
    def of(cls, figures: Iterable[str] | None = None, **tolerance: float) -> Gate:
        """The gate on ``figures`` (every figure where None), default tolerances overridden by
        ``tolerance``; a tolerance names its figure into the family."""
        names = list(DEFAULT_TOLERANCE if figures is None else figures) + list(tolerance)
        return cls({n: float(tolerance.get(n, DEFAULT_TOLERANCE.get(n, 1.0))) for n in names})

    def figures(self, stream: bool) -> tuple[str, ...]:
        """The figures of a streaming or windowed cell the gate reads, in the family's order."""
        kind = STREAMED if stream else WINDOWED
        return tuple(f for f in names(kind, gated=True) if f in self.tolerances)


def parse_tolerances(items: Iterable[str]) -> dict[str, float]:
    """``figure=points`` options as a mapping; a clear UsageError otherwise."""
    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            sep = ""
        if not sep:
            raise UsageError(f"--tolerance takes FIGURE=POINTS (e.g. tn_rate=2), got {item!r}")
    return out


def two_sided_p(worse: np.ndarray, se: np.ndarray, df: np.ndarray, tol: Any) -> tuple:
    """p-values of "worse than the tolerance" and "better than the tolerance" from changes
    ``worse`` signed so that positive is worse, in the figure's units (NaN -> 1)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        p_reg = np.minimum(1.0, 2 * scipy.stats.t.sf((worse - tol) / se, df))
        p_imp = np.minimum(1.0, 2 * scipy.stats.t.sf((-worse - tol) / se, df))
    return np.nan_to_num(p_reg, nan=1.0), np.nan_to_num(p_imp, nan=1.0)


def resolution(se: float, df: float, n_tests: int, alpha: float) -> float:
    """The smallest change beyond the tolerance flagged with ``POWER``: ``se * (t(1 - alpha /
    (2 n_tests), df) + t(POWER, df))`` (NaN without a finite standard error)."""
    if not (np.isfinite(se) and df > 0):
        return float("nan")
    q = scipy.stats.t.ppf(1 - alpha / (2 * max(1, n_tests)), df) + scipy.stats.t.ppf(POWER, df)
    return float(se * q)


def needed(n: float, tol: float, resolution_at: Callable[[float], float]) -> int:
    """The fewest seeds (or trials) at which ``resolution_at`` (the resolution with that many,
    :func:`scaled_resolution`) is at most ``tol``, of which ``n`` ran; 0 where nothing finite
    measures it, and ``MAX_NEEDED`` where even that many would not do."""
    if not (n > 0 and np.isfinite(resolution_at(n))):
        return 0
    lo, hi = 0.0, float(n)
    while resolution_at(hi) > tol:  # doubling, then bisection: more runs never see less
        if hi >= MAX_NEEDED:
            return MAX_NEEDED
        lo, hi = hi, min(2 * hi, MAX_NEEDED)
    while hi - lo > 1:
        mid = math.floor((lo + hi) / 2)
        lo, hi = (lo, mid) if resolution_at(mid) <= tol else (mid, hi)
    return int(math.ceil(hi))


def scaled_resolution(
    n: float, se: float, df: float, seeds: bool, resolve: Callable[[float, float], float]
) -> Callable[[float], float]:
    """``resolve`` (the resolution of a standard error and its degrees of freedom,
    :func:`resolution`) with ``m`` instead of the ``n`` seeds (``seeds``) or test trials that
    ran: the standard error falls as ``sqrt(n / m)`` and the degrees of freedom grow in
    proportion, ``(m - 1) / (n - 1)`` of seeds, ``m / n`` of trials. Counting the degrees of
    freedom matters where few seeds carry the noise: three seeds leave two, and holding them
    fixed asked for hundreds of seeds where tens decide."""

    def at(m: float) -> float:
        grow = (m - 1) / (n - 1) if seeds and n > 1 else m / n
        return resolve(se * math.sqrt(n / m), df * grow)

    return at
