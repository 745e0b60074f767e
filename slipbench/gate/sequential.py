"""Group-sequential seeds: looks at a growing number of seeds per side, with the chance of a
false "regressed" over every look held at a stated level.

A comparison that cannot decide at its first seeds adds seeds on both sides and looks again, up
to a budget. Looking repeatedly at a test of level ``alpha`` raises its false-alarm rate (three
looks at 2.5 % each: 5.4 %), so each look gets its own critical value from an
**error-spending function**: the Lan-DeMets approximation of O'Brien and Fleming's boundaries
(Lan & DeMets, Biometrika 70:659-663, 1983), which spends almost nothing early and keeps the
last look's critical value close to the fixed design's:

    alpha(t) = 2 - 2 * Phi(z(1 - alpha / 2) / sqrt(t)),   0 < t <= 1,

with ``t`` the information fraction of a look (here the seeds per side at that look over the
budget's) and ``alpha(1) = alpha``. The one-sided critical values ``c_1 .. c_K`` of the
cumulative z-statistics make the chance of first crossing at look ``k``, under no change,
``alpha(t_k) - alpha(t_{k-1})``; they are found by the recursive numerical integration of
Armitage, McPherson and Rowe (1969), as Jennison and Turnbull (2000, ch. 19) give it, on the
score scale ``B_k = sqrt(t_k) Z_k``: a Brownian motion, so its increments are independent normal.
Stopping early to say "no regression" (a look whose power already suffices) never raises the
false-alarm rate: only crossing a boundary flags. ``tests/stats/test_sequential.py`` checks the
boundaries against published values and by simulation.

Statistics with few degrees of freedom are t-distributed, not normal: a look compares its
one-sided p-value (from its own t distribution) with the look's **nominal level**
``1 - Phi(c_k)``, the usual way of carrying z-boundaries to t-tests.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy  # its submodules load on first use: reading stored rows pays none

#: grid points per standard deviation of the narrowest increment in the recursive integration
#: (8 gives the boundaries to 1e-5: 16 and 32 agree, and so does the exact second look)
GRID_PER_SD = 8
#: how many standard deviations below its mean the continuation region's density is followed
TAIL_SD = 9.0


def spending(fractions: Sequence[float] | np.ndarray, alpha: float) -> np.ndarray:
    """The Lan-DeMets O'Brien-Fleming error spent by each information fraction in (0, 1]:
    ``2 - 2 Phi(z(1 - alpha / 2) / sqrt(t))`` (cumulative; ``alpha`` at ``t = 1``)."""
    t = np.asarray(fractions, float)
    if not (np.all(t > 0) and np.all(t <= 1)):
        raise ValueError(f"information fractions must lie in (0, 1], got {t.tolist()}")
    if not 0 < alpha < 1:
        raise ValueError(f"alpha must lie in (0, 1), got {alpha}")
    return 2 * scipy.stats.norm.sf(scipy.stats.norm.isf(alpha / 2) / np.sqrt(t))


@dataclass(frozen=True)
class Boundaries:
    """One-sided group-sequential boundaries at ``fractions`` (increasing, the last 1 where the
    budget is reached) holding ``alpha`` over every look.

    Attributes
    ----------
    fractions : information fraction of each look.
    alpha : the level held over all looks.
    z : critical value of each look's cumulative z-statistic.
    spent : error spent up to and including each look (cumulative).
    """

    fractions: tuple[float, ...]
    alpha: float
    z: tuple[float, ...]
    spent: tuple[float, ...]

    @property
    def nominal(self) -> tuple[float, ...]:
        """Each look's nominal one-sided level ``1 - Phi(c_k)``: a look flags where its
        one-sided p-value is at most this."""
        return tuple(float(scipy.stats.norm.sf(c)) for c in self.z)

    @property
    def looks(self) -> int:
        return len(self.fractions)


def boundaries(fractions: Sequence[float], alpha: float) -> Boundaries:
    """The Lan-DeMets O'Brien-Fleming boundaries at ``fractions`` (increasing, in (0, 1]).

    The last fraction need not be 1: a comparison stopped before its budget has spent only
    ``alpha(t_K)``, less than ``alpha`` (the rest is never spent, which errs safe).
    """
    t = _checked(fractions)
    spent = spending(t, alpha)
    targets = np.diff(spent, prepend=0.0)
    walk = _Walk(t, 0.0)
    z = [float(scipy.stats.norm.isf(targets[0]))]
    for k in range(1, len(t)):
        first_cross = walk.step_to(k, z[-1] * np.sqrt(t[k - 1]))
        z.append(_critical(first_cross, float(np.sqrt(t[k])), float(targets[k])))
    return Boundaries(tuple(map(float, t)), float(alpha), tuple(z), tuple(map(float, spent)))


def _critical(first_cross: Callable[[float], float], root_t: float, target: float) -> float:
    """The critical z whose first-crossing chance (``first_cross`` of the score ``z *
    sqrt(t)``) is ``target``."""
    return float(scipy.optimize.brentq(lambda c: first_cross(c * root_t) - target, -10.0, 40.0))


def crossing(bounds: Boundaries, drift: float = 0.0) -> np.ndarray:
    """The chance of first crossing each look's boundary where the cumulative z-statistic at
    information fraction 1 has mean ``drift`` (0: no change; the score ``B(t) = sqrt(t) Z(t)``
    drifts by ``drift * t``)."""
    t = np.asarray(bounds.fractions)
    b = np.asarray(bounds.z) * np.sqrt(t)
    walk = _Walk(t, drift)
    out = [float(scipy.stats.norm.sf((b[0] - drift * t[0]) / np.sqrt(t[0])))]
    for k in range(1, len(t)):
        out.append(walk.step_to(k, b[k - 1])(b[k]))
    return np.array(out)


def power(bounds: Boundaries, drift: float) -> float:
    """The chance that some look flags (crosses its boundary) at ``drift``."""
    return float(crossing(bounds, drift).sum())


def detectable_drift(bounds: Boundaries, chance: float = 0.8) -> float:
    """The drift (the mean of the z-statistic at information fraction 1) that some look flags
    with probability ``chance``: a change of that many standard errors at the budget."""
    if not bounds.alpha < chance < 1:
        raise ValueError(f"power must lie in ({bounds.alpha}, 1), got {chance}")
    return float(scipy.optimize.brentq(lambda d: power(bounds, d) - chance, 0.0, 40.0, xtol=1e-9))


def fractions_of(seeds: Sequence[int], budget: int) -> list[float]:
    """The information fractions of looks at ``seeds`` per side (increasing) of ``budget``:
    each look's seeds over the budget's (the seed term of a mean's variance falls as one over
    the seeds)."""
    if budget < 1 or not seeds or any(not 0 < s <= budget for s in seeds):
        raise ValueError(f"looks at {list(seeds)} seeds need a budget >= each, got {budget}")
    return [s / budget for s in seeds]


def _checked(fractions: Sequence[float]) -> np.ndarray:
    t = np.asarray(fractions, float)
    if t.ndim != 1 or len(t) == 0 or np.any(np.diff(t) <= 0):
        raise ValueError(f"information fractions must increase, got {list(fractions)}")
    return t


class _Walk:
    """The score ``B(t)`` (drift ``drift``) from look to look, over the paths that crossed no
    boundary yet: its sub-density at the current look, evaluated where asked by integrating the
    previous look's (Simpson's rule on a grid that ends at that look's boundary) against the
    normal increment: Armitage, McPherson and Rowe's recursion."""

    def __init__(self, t: np.ndarray, drift: float) -> None:
        self.t, self.drift = t, drift
        # the grid step: the narrowest increment's sd over GRID_PER_SD
        self.h = float(np.sqrt(np.diff(t, prepend=0.0)).min()) / GRID_PER_SD
        self.density = lambda y: scipy.stats.norm.pdf(
            y, drift * t[0], np.sqrt(t[0])
        )  # the first look's

    def step_to(self, k: int, b_prev: float) -> Callable[[float], float]:
        """Cut the density of look ``k - 1`` at ``b_prev`` (paths at or above it stopped), move
        it on to look ``k`` and return the chance of first crossing there as a function of that
        look's boundary on the score scale."""
        lo = self.drift * self.t[k - 1] - TAIL_SD * np.sqrt(self.t[k - 1])
        x, w = _simpson(lo, max(b_prev, lo + self.h), self.h)
        g = self.density(x) * w
        dt = self.t[k] - self.t[k - 1]
        sd, shift = np.sqrt(dt), self.drift * dt
        scaled = g / (sd * np.sqrt(2 * np.pi))
        self.density = lambda y: np.exp(-0.5 * ((y[:, None] - x - shift) / sd) ** 2) @ scaled
        return lambda b: float(g @ scipy.special.ndtr((x + shift - b) / sd))


def _simpson(lo: float, hi: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Points and Simpson weights on [lo, hi] at a step of at most ``h``."""
    n = 2 * max(1, int(np.ceil((hi - lo) / (2 * h)))) + 1
    x = np.linspace(lo, hi, n)
    w = np.full(n, 2.0)
    w[1::2] = 4.0
    w[0] = w[-1] = 1.0
    return x, w * (x[1] - x[0]) / 3
