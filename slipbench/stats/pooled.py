"""The mean change of a rate over many compared cells, with ONE joint cluster bootstrap.

A change spread thinly over a protocol (every window of a tenth of the trials flipped in all
window-size cells: -4.6 points on average) hides inside each cell's simultaneous interval, but
not inside the interval of the mean over the cells. The cells of a protocol test the same
trials (fingers recorded at once, windows cut from the same recordings), so their changes move
together: the mean is bootstrapped once, every resample drawing each trial for all cells and
both sides at once (clusters shared by test sets are one cluster, as in
:func:`slipbench.stats.metrics.mean_over_test_sets`).

Seeds (``--repeats``): a cell's change is the mean over the candidate's seeds minus the mean
over the base's. The interval is the two-level bootstrap of
:func:`slipbench.stats.bootstrap.seeded_interval`, trials drawn once for every test set. Where
every cell ran the same seeds on each side (one ``evaluate --repeats`` per side), a seed is one
split and one set of draws for every cell, so its luck moves all cells at once: the seeds are
crossed with the cells and a seed's figure is the mean over the cells. Where both sides ran the
same seeds (a branch against main), seed k of each side made the same split, so the pooled test
pairs them seed by seed, as the cells do, and the split's luck cancels (null study of
``benchmarks/bench_compare_null.py --same-seeds``: 0 of 20 exit 1; power: the pooled test flags
10 of 10 and 10 of 10, where drawn apart it flagged 1 and 0). Where a cell lacks a seed the
others ran (skipped under that split), the pooled test keeps to the seeds every cell ran, if two
or more: :func:`on_common_seeds`. Where the cells ran different seeds, each cell's seeds are
drawn on their own, and the method says so.

Where some cell has no stored predictions, :func:`pooled_from_rows` gives the mean from the
cells' rows, taking their errors as moving together (the widest case).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import scipy  # its submodules load on first use: reading stored rows pays none

from slipbench.errors import DataError
from slipbench.stats.bootstrap import (
    N_RESAMPLES,
    Clusters,
    IntervalSpec,
    SeededFigure,
    make_design,
    seeded_interval,
)
from slipbench.stats.metrics import (
    FIGURES,
    RATES,
    Predictions,
    class_masks,
    classes_low_n,
    cluster_counts,
    seed_spreads,
)
from slipbench.stats.noise import SeedNoise, pool_seed_spreads
from slipbench.store.columns import FIGURES as FIGURES_DECLARED
from slipbench.store.results import read_predictions

#: the interval of a pooled change: the t-interval the null and power studies measured (a
#: change, where ``satterthwaite`` and the figures' ``replicate-logit`` agree); the default's
#: choice of scale was screened on cells, not on means over many cells
POOLED_METHOD = "satterthwaite"


@dataclass(frozen=True)
class CellSides:
    """One compared cell: one Predictions per seed on each side, and the seeds they ran
    (``base_seeds``, ``cand_seeds``, in the same order; empty where unknown)."""

    base: Sequence[Predictions]
    cand: Sequence[Predictions]
    base_seeds: Sequence[int] = ()
    cand_seeds: Sequence[int] = ()


def crossed(cells: Sequence[CellSides]) -> bool:
    """Every cell ran the same seeds on each side: a seed's luck (its split, its models' draws)
    reaches every cell at once, so the seeds are crossed with the cells."""
    first = cells[0]
    return len(first.base_seeds) > 0 and all(
        list(c.base_seeds) == list(first.base_seeds)
        and list(c.cand_seeds) == list(first.cand_seeds)
        for c in cells
    )


def paired(cells: Sequence[CellSides]) -> bool:
    """Crossed, and both sides ran the same seeds, several: seed k of each side made the same
    split. (One seed per side gives the same interval either way.)"""
    seeds = list(cells[0].base_seeds)
    return len(seeds) > 1 and crossed(cells) and list(cells[0].cand_seeds) == seeds


def on_common_seeds(cells: Sequence[CellSides]) -> Sequence[CellSides]:
    """``cells`` kept to the seeds every cell ran, per side, where that leaves each side 2 seeds
    or more (1 where some cell ran one): a cell skipped under one seed would otherwise leave the
    pooled test drawing each cell's seeds on its own, though a seed's split moves every cell
    (``benchmarks/bench_seed_by_cell.py``). Else ``cells`` as they are."""
    if crossed(cells) or not all(c.base_seeds and c.cand_seeds for c in cells):
        return cells
    kept = []
    for side in ("base_seeds", "cand_seeds"):
        common = [s for s in getattr(cells[0], side) if all(s in getattr(c, side) for c in cells)]
        ran = min(len(getattr(c, side)) for c in cells)
        if len(common) < min(ran, 2):
            return cells
        kept.append(common)

    def keep(preds: Sequence[Predictions], seeds: Sequence[int], common: list) -> list:
        return [preds[list(seeds).index(s)] for s in common]

    return [
        CellSides(keep(c.base, c.base_seeds, kept[0]), keep(c.cand, c.cand_seeds, kept[1]), *kept)
        for c in cells
    ]


def protocol_seed_pool(
    cells: Sequence[CellSides], figures: Sequence[str] = FIGURES, paired: bool = False
) -> dict[str, SeedNoise]:
    """Per figure, the seed variance ``cells`` (a protocol's compared cells) share: each cell
    side's spread over its seeds, pooled with its degrees of freedom (``docs/explanation/statistics.md``);
    figures no cell side of two seeds measures are left out. Give it to
    :func:`slipbench.stats.metrics.over_seeds` (``seed_pool``, the same ``paired``) so that a
    cell's seed term rests on the protocol's degrees of freedom, and more seeds narrow it."""
    spreads: dict[str, list[tuple[float, int]]] = {name: [] for name in figures}
    for c in cells:
        for name, found in seed_spreads(c.base, c.cand, figures, paired).items():
            spreads[name] += found
    pools = {name: pool_seed_spreads(found) for name, found in spreads.items()}
    return {name: pool for name, pool in pools.items() if pool is not None}


def _mask(p: Predictions, figure: str) -> np.ndarray:
    return class_masks(p.y_true)[FIGURES_DECLARED[figure].rate]


def pooled_change(
    cells: Sequence[CellSides],
    seed: int,
    level: float,
    figure: str = "accuracy",
    noise: Callable[[bool], SeedNoise | None] | None = None,
) -> dict:
    """The mean over ``cells`` of (candidate - base) of ``figure`` (a rate, as a fraction),
    with an interval at ``level`` from one joint stratified cluster bootstrap over the trials
    and, where a side holds several, its seeds. ``noise``: the seed variance of the mean
    measured elsewhere, for sides of the same seeds (True) or apart (False); it takes the
    place of the sides' own spread where the cells' seeds are crossed (its noise is of the
    mean over the cells, one seed at a time).

    Returns
    -------
    dict
        ``d``, ``lo``, ``hi``, ``se``, ``df``; ``seeds`` (a side held several seeds) and
        ``seed_design`` (how they were drawn, in words); ``noise``: the source of the seed
        variance measured elsewhere that it took ("" where none);
        ``n_cells``; ``n_test_clusters_slip``/``_nonslip`` over the union of the
        test sets and ``low_n``; ``estimable``.
    """
    if figure not in RATES:
        raise ValueError(f"pooled changes are of rates ({', '.join(RATES)}), not {figure}")
    if not cells:
        raise ValueError("pooled_change needs at least one cell")
    ran = cells
    cells = on_common_seeds(cells)
    parts = [p for c in cells for p in (*c.base, *c.cand)]
    design, codes = make_design([p.y_true for p in parts], [p.groups for p in parts])
    hits, size = [], []
    for p, c in zip(parts, codes):
        m = _mask(p, figure)
        correct = (np.asarray(p.y_true, bool) == np.asarray(p.y_pred, bool)).astype(float)
        hits.append(np.bincount(c[m], weights=correct[m], minlength=design.n_clusters))
        size.append(np.bincount(c[m], minlength=design.n_clusters).astype(float))
    # the columns of each cell's seeds in the parts, per side: (cells, seeds) where crossed
    index, k = [], 0
    for cell in cells:
        nb, nc = len(cell.base), len(cell.cand)
        index.append((np.arange(k, k + nb), np.arange(k + nb, k + nb + nc)))
        k += nb + nc
    # the sides of the two-level bootstrap, each (sign, columns added, columns taken away),
    # summed over the cells per seed. Crossed seeds: a seed's figure is the mean over the cells
    # (one seed's luck moves every cell at once); where both sides ran the same seeds, one side
    # of the seeds' paired differences (seed k of each side made the same split), else one side
    # per run side. Otherwise one side per cell and run side (each cell's seeds drawn on their
    # own). Each side's figures come scaled by 1 / cells and the signs stay +-1, so every
    # variance term seeded_interval forms is on the scale of the mean
    sides: list[tuple[float, np.ndarray, np.ndarray | None]] = []
    if paired(cells):
        sides = [(1.0, np.stack([c for _, c in index]), np.stack([b for b, _ in index]))]
    elif crossed(cells):
        sides = [
            (-1.0, np.stack([b for b, _ in index]), None),
            (1.0, np.stack([c for _, c in index]), None),
        ]
    else:
        for b, c in index:
            sides += [(-1.0, b[None], None), (1.0, c[None], None)]
    signs = [sign for sign, _, _ in sides]
    H, S = np.array(hits), np.array(size)
    share = 1.0 / len(cells)

    def gather(x: np.ndarray) -> list[np.ndarray]:
        # x (n, parts, ...) -> per side (n, seeds, ...): added minus taken away, over the cells
        return [
            x[:, add].sum(axis=1) - (0 if away is None else x[:, away].sum(axis=1))
            for _, add, away in sides
        ]

    def per_seed(w: np.ndarray) -> list[np.ndarray]:
        return gather(share * (w @ H.T) / (w @ S.T))

    def per_seed_influence(w: np.ndarray) -> list[np.ndarray]:
        denom = w @ S.T
        r = (w @ H.T) / denom
        return gather(share * (H[None] - r[:, :, None] * S[None]) / denom[:, :, None])

    measured = noise(paired(cells)) if noise is not None and crossed(cells) else None
    iv = seeded_interval(
        SeededFigure(per_seed, per_seed_influence, signs, (-1.0, 1.0)),
        Clusters(design, S.sum(axis=0) > 0, S.sum(axis=0)),
        IntervalSpec(seed, level, N_RESAMPLES, POOLED_METHOD),
        measured,
    )
    out = {
        "n_cells": len(cells),
        "estimable": bool(iv.estimable),
        "d": float(iv.estimate),
        "lo": iv.lo,
        "hi": iv.hi,
        "se": iv.se,
        "df": iv.df,
        "seeds": any(len(c.base) > 1 or len(c.cand) > 1 for c in cells),
        "seed_design": _seed_design(ran, cells),
        "noise": "" if measured is None else measured.source,
    }
    y = np.concatenate([np.asarray(p.y_true, bool) for p in parts])
    g = np.concatenate([np.asarray(p.groups) for p in parts])
    n_slip, n_nonslip = cluster_counts(y, g)
    out |= {
        "n_test_clusters_slip": n_slip,
        "n_test_clusters_nonslip": n_nonslip,
        "low_n": classes_low_n(n_slip, n_nonslip),
    }
    return out


def _seed_design(ran: Sequence[CellSides], cells: Sequence[CellSides]) -> str:
    """How ``pooled_change`` drew the seeds of ``cells`` (``ran``: before they were kept to the
    seeds every cell ran), in words."""
    if not crossed(cells):
        return "each cell's seeds, drawn on their own (the cells ran different seeds)"
    how = "crossed with the cells" + (" and paired seed by seed" if paired(cells) else "")
    if cells is ran:
        return f"the seeds, {how}"
    seeds = sorted({*cells[0].base_seeds, *cells[0].cand_seeds})
    return f"the seeds every cell ran ({', '.join(map(str, seeds))}), {how}"


def pooled_from_rows(
    d: Sequence[float], se: Sequence[float], df: Sequence[float], level: float
) -> dict:
    """The mean of cells' changes where no predictions are at hand to pool: the interval takes
    the cells' errors as moving together (the mean of their standard errors, the widest case),
    with the fewest degrees of freedom among them.

    Returns
    -------
    dict
        ``d``, ``lo``, ``hi``, ``se``, ``df``.
    """
    out = {
        "d": float(np.mean(d)),
        "se": float(np.mean(se)),
        "df": float(np.nanmin(np.asarray(df, float))),
    }
    q = scipy.stats.t.ppf(1 - (1 - level) / 2, out["df"])
    return out | {"lo": out["d"] - q * out["se"], "hi": out["d"] + q * out["se"]}


def _as_predictions(frame: pd.DataFrame, by_trial: bool) -> Predictions:
    score = frame["score"].to_numpy()
    groups = frame["trial" if by_trial else "recording_id"].astype(str).to_numpy()
    return Predictions(frame["y_true"].to_numpy().astype(bool), score >= 0.5, groups, score)


def seed_sides(base: list[pd.DataFrame], cand: list[pd.DataFrame]) -> tuple[list, list]:
    """Each seed's predictions as Predictions, clustered by trial where every file holds one."""
    by_trial = all("trial" in f for f in (*base, *cand))
    return [_as_predictions(f, by_trial) for f in base], [
        _as_predictions(f, by_trial) for f in cand
    ]


def cell_sides(
    base: list[pd.DataFrame], cand: list[pd.DataFrame], base_rows: list, cand_rows: list
) -> CellSides:
    """A compared cell as the pooled tests take it: each seed's predictions per side and the
    seeds their rows ran, in the same order."""
    return CellSides(
        *seed_sides(base, cand),
        [r.get("seed") for r in base_rows],
        [r.get("seed") for r in cand_rows],
    )


def find_predictions(folders: Sequence[Path], key: str) -> pd.DataFrame | None:
    """A cell's stored predictions from the first folder that holds them; a damaged file costs
    the cell its window-by-window pairing, not the report."""
    for folder in folders:
        try:
            found = read_predictions(folder, key)
        except DataError as exc:
            warnings.warn(f"{exc}; the cell is compared from its rows", stacklevel=3)
            return None
        if found is not None:
            return found
    return None
