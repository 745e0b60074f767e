"""False alarms of the leaderboard's pairwise "A - B [interval]" when detectors run under several
seeds (issue 20), and coverage of its mean figures: the study behind :mod:`slipbench.stats.leaderboard`'s
seeded intervals and the section of ``docs/studies/coverage.md`` that gives its table.

A simulated board holds ``B`` blocks and two equal detectors, each run under ``S`` seeds. An
entrant's figure in block ``b`` under seed ``s`` is

    x_k[b, s] = mu_b + c_s + u_k,s + e_k,b,s

``mu_b ~ N(0.80, 0.05^2)``: the block's difficulty, shared by both detectors; ``c_s ~ N(0,
0.02^2)``: the seed's split of the trials, shared by both; ``u_k,s ~ N(0, SD_U^2)``: the
detector's luck under a seed that reaches every block (one initialisation and one split for
every cell of a run); ``e_k,b,s ~ N(0, SD_E^2)``: its luck in one block. Scenarios:

- ``per-block``: seed luck that differs from block to block only (SD_E 0.03, SD_U 0).
- ``shared``: seed luck shared by the blocks (SD_E 0.01, SD_U 0.01).
- ``both``: SD_E 0.03, SD_U 0.01.
- ``unpaired``: as ``both``, but the two detectors ran different seeds (no ``c_s`` in common).

The truth: A - B = 0, and each detector's mean is 0.80 (the expectation over blocks and seeds).
Counted per setting: the share of boards whose 95 % pairwise interval excludes 0 (false alarms;
target <= 5 %), and the coverage of A's mean interval of 0.80, for the seeded intervals
(:func:`slipbench.stats.leaderboard.pairwise` with ``seeds``) and for the t-interval over
blocks of the seeds' means (what the leaderboard shows without ``seeds``, the pair undecided;
before issue 45, a percentile bootstrap over blocks); and the median
width of the seeded pairwise interval over that of a 95 % normal interval that knew the true
standard deviation of A - B (:func:`true_sd`).

    nice python benchmarks/bench_leaderboard_seeds.py --reps 1000 --out leaderboard-seeds.md
"""

from __future__ import annotations

import argparse
import itertools
import multiprocessing
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from slipbench.stats.leaderboard import _mean_interval, pairwise

SCENARIOS = {  # SD_E, SD_U, paired
    "per-block": (0.03, 0.0, True),
    "shared": (0.01, 0.01, True),
    "both": (0.03, 0.01, True),
    "unpaired": (0.03, 0.01, False),
}
BLOCKS = (30, 300)
SEEDS = (2, 3, 5)
MEAN, SD_BLOCK, SD_SPLIT = 0.80, 0.05, 0.02
CHUNK = 50  # boards per task of a worker


def board(rng: np.random.Generator, scenario: str, n_blocks: int, n_seeds: int) -> dict:
    """One simulated board: per entrant its (n_blocks, seed levels) figures, NaN for a seed it
    did not run (unpaired: A ran the first ``n_seeds`` levels, B the next)."""
    sd_e, sd_u, paired = SCENARIOS[scenario]
    levels = n_seeds if paired else 2 * n_seeds
    mu = rng.normal(MEAN, SD_BLOCK, (n_blocks, 1))
    split = rng.normal(0, SD_SPLIT, (1, levels))
    out = {}
    for k, name in enumerate("ab"):
        x = mu + split + rng.normal(0, sd_u, (1, levels)) + rng.normal(0, sd_e, (n_blocks, levels))
        if not paired:
            own = np.zeros(levels, bool)
            own[k * n_seeds : (k + 1) * n_seeds] = True
            x[:, ~own] = np.nan
        out[name] = x
    return out


def true_sd(scenario: str, n_blocks: int, n_seeds: int) -> float:
    """The standard deviation of A - B over boards: each detector's seed luck (shared and per
    block), and the seeds' splits where the two ran different seeds."""
    sd_e, sd_u, paired = SCENARIOS[scenario]
    var = 2 * (sd_u**2 / n_seeds + sd_e**2 / (n_blocks * n_seeds))
    return float(np.sqrt(var + (0 if paired else 2 * SD_SPLIT**2 / n_seeds)))


def one(scenario: str, n_blocks: int, n_seeds: int, rep: int, seed: int) -> dict[str, float]:
    rng = np.random.default_rng([seed, rep, n_blocks, n_seeds, list(SCENARIOS).index(scenario)])
    x = board(rng, scenario, n_blocks, n_seeds)
    blocks = pd.DataFrame({e: np.nanmean(v, axis=1) for e, v in x.items()})
    seeded = pairwise(blocks, ["a", "b"], seeds=x, margin=0.0).iloc[0]
    plain = pairwise(blocks, ["a", "b"], margin=0.0).iloc[0]
    _, lo_s, hi_s = _mean_interval(blocks["a"].to_numpy(), x["a"], seed=rep)
    _, lo_p, hi_p = _mean_interval(blocks["a"].to_numpy(), seed=rep)
    return {
        "alarm seeded": float(not seeded.lo <= 0 <= seeded.hi),
        "alarm blocks": float(not plain.lo <= 0 <= plain.hi),
        "mean seeded": float(lo_s <= MEAN <= hi_s),
        "mean blocks": float(lo_p <= MEAN <= hi_p),
        "width seeded": (seeded.hi - seeded.lo) / (2 * 1.96 * true_sd(scenario, n_blocks, n_seeds)),
    }


def _chunk(task: tuple) -> list[dict[str, float]]:
    scenario, n_blocks, n_seeds, reps, seed = task
    return [one(scenario, n_blocks, n_seeds, r, seed) for r in reps]


def study(
    reps: int,
    scenarios: Sequence[str],
    blocks: Sequence[int],
    seeds: Sequence[int],
    seed: int,
    jobs: int = 1,
) -> pd.DataFrame:
    settings = list(itertools.product(scenarios, blocks, seeds))
    tasks = [
        (*setting, range(start, min(start + CHUNK, reps)), seed)
        for setting in settings
        for start in range(0, reps, CHUNK)
    ]
    if jobs > 1:
        with multiprocessing.Pool(jobs) as pool:
            done = pool.map(_chunk, tasks)
    else:
        done = [_chunk(t) for t in tasks]
    lines = []
    for scenario, n_blocks, n_seeds in settings:
        got = pd.DataFrame(
            [r for t, rs in zip(tasks, done) if t[:3] == (scenario, n_blocks, n_seeds) for r in rs]
        )
        lines.append(
            {
                "scenario": scenario,
                "blocks": n_blocks,
                "seeds": n_seeds,
                "reps": reps,
                **got.drop(columns="width seeded").mean().round(3).to_dict(),
                "width seeded / known-SD width": round(float(got["width seeded"].median()), 2),
            }
        )
    return pd.DataFrame(lines)


def main(argv: Sequence[str] | None = None) -> pd.DataFrame:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reps", type=int, default=1000, help="boards per setting")
    ap.add_argument("--scenario", action="append", choices=list(SCENARIOS), help="repeatable")
    ap.add_argument("--blocks", default=",".join(map(str, BLOCKS)), help="comma list")
    ap.add_argument(
        "--seeds", default=",".join(map(str, SEEDS)), help="seeds per entrant, comma list"
    )
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=1, help="processes")
    ap.add_argument("--out", type=Path, help="write the Markdown table here too")
    a = ap.parse_args(argv)
    start = time.perf_counter()
    table = study(
        a.reps,
        a.scenario or list(SCENARIOS),
        [int(b) for b in a.blocks.split(",")],
        [int(s) for s in a.seeds.split(",")],
        a.seed,
        a.jobs,
    )
    text = (
        f"{a.reps} boards per row, seed {a.seed}, {time.perf_counter() - start:.0f} s\n\n"
        f"{table.to_markdown(index=False)}\n"
    )
    print(text, flush=True)
    if a.out:
        a.out.write_text(text)
    return table


if __name__ == "__main__":
    main()
