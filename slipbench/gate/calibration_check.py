"""A calibration's numbers checked before a comparison takes them: a detector's noise is used
only where it agrees with what BASE's own seeds show.

A calibration (:mod:`slipbench.stats.calibration`) is keyed on the bench's settings and each
detector's code, which says *whether* it was measured for this code, not whether its numbers
are the ones measured: a hand-edited or damaged file could hold 25 times the noise, or none.
Two checks, per detector, each a ratio of variances read against a stated factor:

- **Against BASE's seeds.** Per protocol and gated figure, BASE's seed variance over its cells,
  pooled (each cell's variance across its seeds, weighted by its degrees of freedom), over the
  calibration's ``seed_var`` of the same cells pooled alike: ``R = sum((n - 1) s2) / sum((n -
  1) v)``. Under a true calibration ``R`` is near 1. Its spread is not an F distribution over
  the cells' summed degrees of freedom: a seed's split moves every cell of a protocol at once
  (the shipped calibration's per-cell and mean variances put the effective number of
  independent cells at 6 to 11 of 41), so the factor is set from measured null spreads instead.
  The detector's ratio is the geometric mean of ``R`` over its protocols and figures, and it is
  refused outside ``[1 / SEED_FACTOR, SEED_FACTOR]``. A figure whose variance is 0 where BASE's
  seeds vary gives ``R`` = infinity: refused.
- **The twin within the run.** ``paired_var`` (one seed's change when only training
  randomness separates two sides) cannot exceed twice ``seed_var`` (training randomness is part
  of a seed's whole variance) beyond chance: the ratio ``paired_var / (2 seed_var)`` of a
  protocol's mean, with ``paired_df`` and ``seed_df``, is refused above its F quantile at
  ``TWIN_LEVEL``.

``SEED_FACTOR`` (5): measured on the shipped bench (cross-instance, ``holweg`` and ``bandpass``,
three seeds a side as the workflow runs them) against its committed calibration, over six
disjoint triples of seeds (0-2, ..., 15-17; ``benchmarks/calibration_check_null.py``, its output
in ``docs/studies/calibration-check.txt``): the detector's ratio spanned 0.33 to 3.3, none
refused; the calibration scaled by 25 was refused in 12 of 12 (a factor of 10 let one through,
holweg at seeds 6-8: 3.3 / 25 = 0.13) and scaled by 0 in 12 of 12. A normal fit to the 12 log
ratios (SD 0.6, holweg's alone 0.84) puts a true calibration's refusal near 1 % (holweg's
several %): the cheap error, since a refused calibration is said and the sides' own seeds then
carry the noise, where one taken at 25 times or none misjudges every comparison.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pandas as pd
import scipy  # scipy.stats loads on first use (see slipbench.stats)

from slipbench.gate.calibration import Calibration, DetectorCalibration
from slipbench.stats.factors import latest_runs

#: the most a detector's calibrated seed variance may differ from BASE's seeds' (either way)
SEED_FACTOR = 5.0
#: the level at which a twin's variance beyond twice the seed variance is refused
TWIN_LEVEL = 0.001


def refused(cal: Calibration, rows: pd.DataFrame, figures: Sequence[str]) -> dict[str, str]:
    """Per detector of ``cal`` whose numbers fail a check against BASE's result ``rows``, why
    (empty where every detector passes or BASE's seeds cannot tell: one seed a cell)."""
    rows = latest_runs(rows)[0]  # a cell run again with other code counts once, as compare's
    out = {}
    for name, det in cal.detectors.items():
        why = _twin_excess(det, figures) or _against_seeds(name, det, rows, figures)
        if why:
            out[name] = why
    return out


def _twin_excess(det: DetectorCalibration, figures: Sequence[str]) -> str:
    for protocol, part in det.protocols.items():
        for f in figures:
            n = part.figures.get(f)
            if n is None or not (n.seed_df > 0 and n.paired_df > 0) or n.paired_var == 0:
                continue
            limit = 2 * n.seed_var * scipy.stats.f.ppf(1 - TWIN_LEVEL, n.paired_df, n.seed_df)
            if not n.paired_var <= limit:
                return (
                    f"its retrained twin's variance of {f} on {protocol} ({n.paired_var:.3g}) "
                    f"exceeds twice its seed variance ({n.seed_var:.3g}) beyond chance "
                    f"(F({n.paired_df:g}, {n.seed_df:g}) at {TWIN_LEVEL:g})"
                )
    return ""


def _against_seeds(
    name: str, det: DetectorCalibration, rows: pd.DataFrame, figures: Sequence[str]
) -> str:
    ok = rows[(rows["detector"] == name) & (rows["status"] == "ok")]
    ratios, seeds = [], 0
    for protocol, part in det.protocols.items():
        mine = ok[ok["protocol"] == protocol]
        for f in figures:
            if f not in mine:
                continue
            num = den = 0.0
            for cell, group in mine.groupby("cell", sort=False):
                noise = part.cells.get(str(cell), {}).get(f)
                x = pd.to_numeric(group[f], errors="coerce").to_numpy(float)
                if noise is None or len(x) < 2 or not np.isfinite([*x, noise.seed_var]).all():
                    continue  # a variance not measured (null) says nothing either way
                # equal values: 0 exactly (their mean's rounding would leave ~1e-32)
                num += (len(x) - 1) * float(x.var(ddof=1)) if np.ptp(x) > 0 else 0.0
                den += (len(x) - 1) * noise.seed_var
                seeds = max(seeds, len(x))
            if num > 0 or den > 0:
                ratios.append(math.inf if den == 0 else num / den)
    if not ratios:
        return ""
    with np.errstate(divide="ignore"):  # a ratio of 0 (BASE's seeds do not vary): mean 0
        ratio = math.inf if math.inf in ratios else float(np.exp(np.mean(np.log(ratios))))
    if 1 / SEED_FACTOR <= ratio <= SEED_FACTOR:
        return ""
    if math.isinf(ratio) or ratio == 0:
        said = (
            "is 0 where BASE's seeds vary"
            if math.isinf(ratio)
            else "varies where BASE's seeds do not"
        )
    else:
        said = f"is {1 / ratio:.3g} times what BASE's {seeds} seeds a cell show"
    return f"its seed variance {said} (allowed: within a factor of {SEED_FACTOR:g})"
