"""Coverage of slipbench's 95 % intervals in six scenarios, by simulation against a closed-form
truth: the study behind ``docs/studies/coverage.md`` and the docstring of :mod:`slipbench.stats.bootstrap`.

A simulated test set holds ``m`` slip and ``m`` non-slip trials with window counts 10-200 (slip)
and 5-100 (non-slip), uniform. A window's latent score is ``mu_class + u_trial + a_trial + e``:
``u ~ N(0, TAU^2)`` is the trial's effect shared by every detector (intra-trial correlation of
hits about 0.3), ``a ~ N(0, 0.5^2)`` the detector's own per-trial effect, ``e ~ N(0, 1)`` window
noise of which half is shared by two detectors on the same window. A window is called slip when
its score exceeds 0 (the candidate: ``SHIFT``, fewer slip calls). Population TP rate 0.80, TN
rate 0.92.

- ``normal``: as above.
- ``heavy``: a share ``FAIL_SHARE`` (10 %) of trials fails wholesale: its class mean moves
  ``FAIL_SHIFT`` latent SDs to the wrong side, so nearly every window of it is wrong, for both
  detectors (a bad trial).
- ``seeds``: each side is trained under ``SEEDS`` (3) seeds; a seed shifts the model's
  performance by ``b ~ N(0, SEED_SD^2)`` latent units (towards the right class for both
  classes) and draws its own per-trial effects and window noise. The target is the figure's
  expectation over seeds and trials; the interval is :func:`slipbench.stats.metrics.over_seeds`.
- ``paired``: as ``seeds``, but a seed's effect is shared by both sides (the luck of the split a
  seed makes, which both sides train and test on), and the change pairs the sides seed by seed
  (``over_seeds(..., paired=True)``, what ``compare`` does where both sides ran the same seeds).
- ``half-shared``: as ``paired``, but half a seed's effect (in variance) is shared by both sides
  and half is each side's own: a seed-by-side interaction, as where a change of code trains
  differently under the same split. Its paired changes carry a seed variance that ``paired``'s
  lack, so the two bracket what the seed terms of a paired change must cover.
- ``ranks``: as ``normal``, but the candidate also pulls each class's mean ``RANK_SHIFT`` (0.5)
  latent units further from the other's, so it ranks better: every change, the AUROC's
  included (+0.036), is away from 0. Elsewhere the two detectors rank alike and the change in
  AUROC is exactly 0, where a t-interval overcovers (its estimate and standard error rise
  together).

Every target has a closed form (normal integrals), so coverage is counted against the truth.
``d_<figure>``: the change candidate - base (paired on the same trials). Replications are
split into chunks run by ``--jobs`` processes; results depend on ``--seed`` only.

    nice python benchmarks/bench_coverage.py --reps 1000 --jobs 2 --out coverage.md
    nice python benchmarks/bench_coverage.py --reps 200 --scenario heavy --sizes 10
"""

from __future__ import annotations

import argparse
import itertools
import multiprocessing
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.stats import norm
from studies.intervals import method as study_method

from slipbench.stats.bootstrap import DEFAULT_METHOD
from slipbench.stats.metrics import FIGURES, Predictions, over_seeds

# appended, never reordered: a scenario's index seeds its draws
SCENARIOS = ("normal", "heavy", "seeds", "ranks", "paired", "half-shared")
SEEDED = ("seeds", "paired", "half-shared")
PAIRED = ("paired", "half-shared")  # the change pairs the sides seed by seed
SIZES = (5, 10, 20, 40)
TAU, TAU_DETECTOR, SHARED_NOISE = 1.0, 0.5, 0.5
TP, TN = 0.80, 0.92
SLIP_WINDOWS, NONSLIP_WINDOWS = (10, 200), (5, 100)
SHIFT = 0.3  # the candidate's threshold, latent units
FAIL_SHARE, FAIL_SHIFT = 0.10, 4.0  # heavy: failing trials, their shift in latent SDs
SEEDS, SEED_SD = 3, 0.3  # seeds: per side, and the SD of a seed's effect (latent units)
RANK_SHIFT = 0.5  # ranks: the candidate pulls each class mean this far apart (latent units)
CHUNK = 50
NAMES = (*FIGURES, *(f"d_{f}" for f in FIGURES))
SHORT = {
    "accuracy": "acc",
    "tp_rate": "TP",
    "tn_rate": "TN",
    "balanced_accuracy": "BA",
    "auroc": "AUROC",
}


def _sd() -> float:
    return float(np.sqrt(1 + TAU**2 + TAU_DETECTOR**2))


def _mixture(scenario: str) -> tuple[list[tuple[float, float]], list[tuple[float, float]]]:
    """Per class, (latent mean, probability) of a trial's component."""
    sd = _sd()
    mu1, mu0 = norm.ppf(TP) * sd, -norm.ppf(TN) * sd
    if scenario != "heavy":
        return [(mu1, 1.0)], [(mu0, 1.0)]
    ok = 1 - FAIL_SHARE
    return (
        [(mu1, ok), (mu1 - FAIL_SHIFT * sd, FAIL_SHARE)],
        [(mu0, ok), (mu0 + FAIL_SHIFT * sd, FAIL_SHARE)],
    )


def truth(scenario: str) -> dict[str, float]:
    """Population figures of the base detector and the changes (candidate - base), averaged
    over seeds where seeds are a factor."""
    sd = _sd()
    b = SEED_SD if scenario in SEEDED else 0.0
    slip, nonslip = _mixture(scenario)
    n1, n0 = np.mean(SLIP_WINDOWS), np.mean(NONSLIP_WINDOWS)

    def figures(threshold: float, sep: float) -> dict[str, float]:
        rate_sd = np.sqrt(sd**2 + b**2)
        tp = sum(p * norm.cdf((mu + sep - threshold) / rate_sd) for mu, p in slip)
        tn = sum(p * norm.cdf((threshold - mu + sep) / rate_sd) for mu, p in nonslip)
        pair_sd = np.sqrt(2 * sd**2 + 4 * b**2)
        auroc = sum(
            p * q * norm.cdf((a - c + 2 * sep) / pair_sd)
            for (a, p), (c, q) in itertools.product(slip, nonslip)
        )
        return {
            "accuracy": (n1 * tp + n0 * tn) / (n1 + n0),
            "tp_rate": tp,
            "tn_rate": tn,
            "balanced_accuracy": (tp + tn) / 2,
            "auroc": auroc,
        }

    base, cand = figures(0.0, 0.0), figures(SHIFT, RANK_SHIFT if scenario == "ranks" else 0.0)
    return base | {f"d_{k}": cand[k] - base[k] for k in base}


def dataset(
    rng: np.random.Generator, m: int, scenario: str
) -> tuple[list[Predictions], list[Predictions]]:
    """One simulated test set: the base and candidate sides, one Predictions per seed."""
    sd = _sd()
    sizes = np.concatenate(
        [
            rng.integers(SLIP_WINDOWS[0], SLIP_WINDOWS[1] + 1, m),
            rng.integers(NONSLIP_WINDOWS[0], NONSLIP_WINDOWS[1] + 1, m),
        ]
    )
    groups = np.repeat(np.arange(2 * m), sizes)
    y = groups < m
    sign = np.where(y, 1.0, -1.0)
    mean = np.where(y, norm.ppf(TP), -norm.ppf(TN)) * sd
    if scenario == "heavy":
        fails = (rng.random(2 * m) < FAIL_SHARE)[groups]
        mean = mean - fails * sign * FAIL_SHIFT * sd
    trial = mean + rng.normal(0, TAU, 2 * m)[groups]
    n_seeds = SEEDS if scenario in SEEDED else 1
    sides: list[list[Predictions]] = [[], []]
    for _ in range(n_seeds):
        effect = np.zeros(2)
        if scenario == "seeds":
            effect = rng.normal(0, SEED_SD, 2)
        elif scenario == "paired":
            effect = np.full(2, rng.normal(0, SEED_SD))
        elif scenario == "half-shared":  # half the variance shared, half each side's own
            effect = np.sqrt(0.5) * (rng.normal(0, SEED_SD) + rng.normal(0, SEED_SD, 2))
        shared = rng.normal(0, np.sqrt(SHARED_NOISE), len(y))
        for k, threshold in enumerate((0.0, SHIFT)):
            sep = RANK_SHIFT if scenario == "ranks" and k == 1 else 0.0
            score = (
                trial
                + sign * (effect[k] + sep)
                + rng.normal(0, TAU_DETECTOR, 2 * m)[groups]
                + shared
                + rng.normal(0, np.sqrt(1 - SHARED_NOISE), len(y))
            )
            sides[k].append(Predictions(y, score > threshold, groups, score))
    return sides[0], sides[1]


def _chunk(task: tuple[str, int, int, int, int, str]) -> dict[str, float]:
    """Hits of every interval over ``n`` replications of one (scenario, m), chunk ``c``, and
    their summed widths (``w_<name>``)."""
    scenario, m, c, n, seed, method = task
    rng = np.random.default_rng([seed, SCENARIOS.index(scenario), m, c])
    true = truth(scenario)
    hits: dict[str, float] = dict.fromkeys([*true, *(f"w_{k}" for k in true)], 0.0)
    for r in range(n):
        base, cand = dataset(rng, m, scenario)
        f = over_seeds(base, seed=r, method=study_method(method))
        d = over_seeds(base, cand, seed=r, method=study_method(method), paired=scenario in PAIRED)
        for name, value in true.items():
            src = d if name.startswith("d_") else f
            hits[name] += bool(src[f"{name}_lo"] <= value <= src[f"{name}_hi"])
            hits[f"w_{name}"] += src[f"{name}_hi"] - src[f"{name}_lo"]
    return hits


def run_tasks(work: Callable[[Any], Any], tasks: list, jobs: int) -> list:
    """``work`` over ``tasks`` in order, by ``jobs`` processes (one task at a time each)."""
    if jobs > 1:
        with multiprocessing.Pool(jobs) as pool:
            return pool.map(work, tasks, chunksize=1)
    return [work(t) for t in tasks]


def study(
    reps: int,
    scenarios: Sequence[str] = SCENARIOS,
    sizes: Sequence[int] = SIZES,
    jobs: int = 1,
    seed: int = 0,
    method: str = DEFAULT_METHOD,
) -> pd.DataFrame:
    """Coverage of every figure's interval and of every change, and (``w_<name>``) the mean
    width of each: one row per (scenario, m)."""
    tasks = [
        (s, m, c, min(CHUNK, reps - c * CHUNK), seed, method)
        for s in scenarios
        for m in sizes
        for c in range(-(-reps // CHUNK))
    ]
    results = run_tasks(_chunk, tasks, jobs)
    rows = []
    for s in scenarios:
        for m in sizes:
            mine = [h for t, h in zip(tasks, results) if t[:2] == (s, m)]
            total = {k: sum(h[k] for h in mine) for k in (*NAMES, *(f"w_{n}" for n in NAMES))}
            rows.append(
                {"scenario": s, "m": m, "reps": reps, **{k: v / reps for k, v in total.items()}}
            )
    return pd.DataFrame(rows)


def markdown(table: pd.DataFrame, widths: bool = False) -> str:
    """The coverage table in Markdown, figures abbreviated; with ``widths``, the mean widths
    too (columns ``w ...``)."""
    keep = ["scenario", "m", "reps", *NAMES, *((f"w_{n}" for n in NAMES) if widths else ())]
    short = {**SHORT, **{f"d_{k}": f"d {v}" for k, v in SHORT.items()}}
    shown = table[keep].rename(columns={f"w_{k}": f"w {v}" for k, v in short.items()})
    shown = shown.rename(
        columns={**SHORT, **{f"d_{k}": f"d {v}" for k, v in SHORT.items()}, "m": "trials/class"}
    )
    return str(shown.to_markdown(index=False, floatfmt=".3f"))


def main(argv: Sequence[str] | None = None) -> pd.DataFrame:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reps", type=int, default=1000, help="replications per scenario and size")
    ap.add_argument(
        "--scenario", action="append", choices=SCENARIOS, help="repeatable; all by default"
    )
    ap.add_argument(
        "--sizes", default=",".join(map(str, SIZES)), help="trials per class, comma list"
    )
    ap.add_argument("--jobs", type=int, default=2, help="processes")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--method",
        default=DEFAULT_METHOD,
        help="interval method (bootstrap.METHODS or studies.intervals.STUDIES)",
    )
    ap.add_argument("--out", type=Path, help="write the Markdown table here too")
    ap.add_argument("--widths", action="store_true", help="show the mean widths too")
    a = ap.parse_args(argv)
    start = time.perf_counter()
    table = study(
        a.reps,
        a.scenario or SCENARIOS,
        [int(s) for s in a.sizes.split(",")],
        a.jobs,
        a.seed,
        a.method,
    )
    text = (
        f"{a.reps} replications per row, method {a.method}, seed {a.seed}, "
        f"{time.perf_counter() - start:.0f} s\n\n{markdown(table, a.widths)}\n"
    )
    print(text, flush=True)
    if a.out:
        a.out.write_text(text)
    return table


if __name__ == "__main__":
    main()
