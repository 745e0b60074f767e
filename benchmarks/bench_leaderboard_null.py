"""How often does the leaderboard call equal detectors different, and does it ever contradict
itself? The study behind the one family of tests of :mod:`slipbench.stats.leaderboard` and its
section of ``docs/explanation/statistics.md``.

A simulated board holds three entrants that are the same detector run under seeds drawn apart,
over two protocols of ``BLOCKS`` blocks each. Entrant ``k``'s figure in block ``b`` under its
seed ``s`` is ``mu_b + c_k,s + e_k,b,s``: ``mu_b ~ N(0.80, 0.05^2)`` the block's difficulty,
``c_k,s ~ N(0, SD_RUN^2)`` the run's luck (its split and initialisation, in every block),
``e ~ N(0, SD_BLOCK^2)`` its luck in one block. Per board, every scope (all blocks, each
protocol) is ranked by :func:`slipbench.stats.leaderboard.rank_scope` with the seeds, one
Bonferroni level over every scope's decided pairs, read against the 1-point margin
(:func:`slipbench.stats.leaderboard.one_family`); counted: boards where some pair of some scope
"differs" (target <= 5 %), boards where the groups split the entrants (one seed: no pair is
decided, so there are no groups to split), and boards where a scope's groups contradict its
pairs (a differing or undecided pair sharing a group, or neighbours in rank decided and not
differing kept apart). "Before": the Wilcoxon-Holm groups
the leaderboard drew until issue 35 (scope "all"), on the same boards.

    nice python benchmarks/bench_leaderboard_null.py --boards 100 --out benchmarks/results/leaderboard_null.md
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.stats import wilcoxon
from statsmodels.stats.multitest import multipletests

from slipbench.seeding import rng_for
from slipbench.stats.leaderboard import ALPHA, Scope, one_family, rank_scope

ENTRANTS = ("a", "b", "c")
BLOCKS = 24  # per protocol
SD_DIFFICULTY, SD_RUN, SD_BLOCK = 0.05, 0.02, 0.03


def board(rep: int, n_seeds: int) -> tuple[pd.DataFrame, dict[str, np.ndarray]]:
    """The blocks' figures (mean over seeds) and each entrant's (blocks, seeds) figures."""
    rng = rng_for(rep, "bench-leaderboard-null", n_seeds)
    n = 2 * BLOCKS
    mu = rng.normal(0.80, SD_DIFFICULTY, (n, 1))
    seeds = {
        e: mu + rng.normal(0, SD_RUN, (1, n_seeds)) + rng.normal(0, SD_BLOCK, (n, n_seeds))
        for e in ENTRANTS
    }
    index = pd.Index([f"p{b // BLOCKS}-{b}" for b in range(n)])
    blocks = pd.DataFrame({e: v.mean(axis=1) for e, v in seeds.items()}, index=index)
    return blocks, seeds


def contradicts(scope: Scope) -> bool:
    """A differing pair, or an undecided one, sharing a group; or neighbours in rank decided
    and not differing kept apart."""
    order = list(scope.ranks.index)
    together = {(x, y) for g in scope.groups for x in g for y in g}
    for r in scope.pairs.itertuples():
        if (r.differ or not r.decided) and (r.a, r.b) in together:
            return True
        if r.decided and not r.differ and abs(order.index(r.a) - order.index(r.b)) == 1:
            if (r.a, r.b) not in together:
                return True
    return False


def wilcoxon_split(blocks: pd.DataFrame) -> bool:
    """The former groups: some pair differs by Wilcoxon signed-rank over blocks, Holm."""
    cols = list(blocks.columns)
    p = [
        wilcoxon(blocks[a] - blocks[b], zero_method="zsplit").pvalue
        for i, a in enumerate(cols)
        for b in cols[i + 1 :]
    ]
    return bool((multipletests(p, method="holm")[1] < ALPHA).any())


def one(rep: int, n_seeds: int) -> dict:
    blocks, seeds = board(rep, n_seeds)
    scopes = [rank_scope(blocks, "all", seeds)]
    for p in ("p0", "p1"):
        at = blocks.index.str.startswith(p + "-")
        part = {e: v[at] for e, v in seeds.items()}
        scopes.append(rank_scope(blocks[at], p, part))
    one_family(scopes)
    return {
        "differ": any(s.pairs["differ"].any() for s in scopes),
        # split: the groups keep apart entrants that no decided pair shows to differ
        "split": any(s.groups and s.groups != [list(s.ranks.index)] for s in scopes),
        "contradicts": any(contradicts(s) for s in scopes),
        "before": wilcoxon_split(blocks),
    }


def study(boards: int) -> pd.DataFrame:
    out = []
    for n_seeds in (1, 3):
        runs = pd.DataFrame([one(rep, n_seeds) for rep in range(boards)])
        out.append(
            {
                "seeds per entrant": n_seeds,
                "boards": boards,
                "a pair differs": f"{runs['differ'].mean():.3f}",
                "groups split": f"{runs['split'].mean():.3f}",
                "groups contradict pairs": int(runs["contradicts"].sum()),
                "before: Wilcoxon-Holm split": f"{runs['before'].mean():.3f}",
            }
        )
    return pd.DataFrame(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--boards", type=int, default=400, help="simulated boards per setting")
    ap.add_argument("--out", type=Path, help="write the table (Markdown) here")
    args = ap.parse_args()
    text = (
        f"3 equal entrants, seeds drawn apart, 2 protocols of {BLOCKS} blocks; run SD {SD_RUN}, "
        f"block SD {SD_BLOCK}; shares of boards\n\n"
        + study(args.boards).to_markdown(index=False)
        + "\n"
    )
    print(text)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)


if __name__ == "__main__":
    main()
