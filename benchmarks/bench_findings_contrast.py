"""Coverage of the findings' contrast intervals (:mod:`slipbench.stats.contrast`, as
:mod:`slipbench.report.findings` builds them from result rows), by simulation against a
closed-form truth: the study behind the figures quoted in that module's docstring and in
``docs/studies/coverage.md``.

A simulated sensor has ``FINGERS`` (3) fingers recorded in the same trials: ``m`` slip and ``m``
non-slip trials, each finger's recording of a trial 10-60 (slip) or 5-30 (non-slip) windows. A
window of cell (finger, window size, detector) is right with probability
``Phi(beta + t + f + g + b)``: ``beta`` the cell's level (per class: TP side ``+ 0.3``, TN side
``- 0.3``), ``t ~ N(0, 0.8^2)`` the trial's difficulty, shared by every finger, window size and
detector; ``f ~ N(0, 0.5^2)`` the finger's own in that trial; ``g ~ N(0, 0.4^2)`` the
detector's own per trial (the Holweg baseline's differs from the LSTM's); ``b ~ N(0,
SEED_SD^2)`` the retraining noise, drawn per cell and seed. Levels (probit): the LSTM at windows
5, 50, 200: 0.5, 1.1, 1.2; the baseline at 50: 0.6. Rows are the cells' figures with their
cluster-bootstrap intervals (:func:`slipbench.stats.metrics.classification_figures`, clusters:
trials); over several seeds, :func:`slipbench.report.tables.summarize` (the rows' interval over
seeds). Scenarios:

- ``test``: no retraining noise, one seed: the intervals' own ground.
- ``seeds-1``: retraining noise ``SEED_SD`` 0.3, one seed per cell: what a run without
  ``--repeats`` holds; the truth is the expectation over retraining too.
- ``seeds-3``: the same noise, three seeds per cell (``--repeats 3``).
- ``strong-1``, ``strong-3``: retraining noise 0.6 (about 10 points of accuracy per cell and
  seed), one and three seeds.

Contrasts (points, means over the fingers, as the findings take them): ``rise`` (accuracy at
window 200 minus at 5), ``levels`` (200 minus 50), ``gap`` (TP minus TN rate at 50) and
``lead`` (the LSTM minus the baseline at 50); and ``cell``, one cell's accuracy (index finger,
window 50) with the interval the tables give it (over several seeds,
:func:`slipbench.stats.metrics.seeds_from_rows`). Every truth has a closed form (normal
integrals).
Counted: the share of replications whose contrast interval holds the truth (``<contrast>``),
its mean width in points (``w``), and that width over the width a normal 95 % interval would
have at the estimate's standard deviation over the replications (``w/ideal``: above 1, wider
than it needs to be).

    nice python benchmarks/bench_findings_contrast.py --reps 1000 --jobs 2 --out findings.md
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
from scipy.stats import norm

from slipbench.report.findings import UNIT, _cells, _unit_contrast
from slipbench.report.tables import summarize
from slipbench.stats.contrast import Contrast
from slipbench.stats.metrics import classification_figures

SCENARIOS = {  # SEED_SD, seeds per cell
    "test": (0.0, 1),
    "seeds-1": (0.3, 1),
    "seeds-3": (0.3, 3),
    "strong-1": (0.6, 1),
    "strong-3": (0.6, 3),
}
SIZES = (10, 20, 40)
FINGERS = ("index", "middle", "little")
TAU, FINGER_SD, DETECTOR_SD, CLASS_SHIFT = 0.8, 0.5, 0.4, 0.3
SLIP_WINDOWS, NONSLIP_WINDOWS = (10, 60), (5, 30)
LEVELS = {("lstm", 5): 0.5, ("lstm", 50): 1.1, ("lstm", 200): 1.2, ("holweg", 50): 0.6}
CONTRASTS = ("rise", "levels", "gap", "lead", "cell")
CHUNK = 25


def _rate(beta: float, detector: str, seed_sd: float) -> float:
    """The expected rate of a class whose level is ``beta``: Phi(beta / sqrt(1 + var))."""
    var = TAU**2 + FINGER_SD**2 + seed_sd**2 + (DETECTOR_SD**2 if detector == "holweg" else 0.0)
    return float(norm.cdf(beta / np.sqrt(1 + var)))


def truth(scenario: str) -> dict[str, float]:
    """Each contrast's population value (points): expectations over trials, fingers and seeds."""
    seed_sd = SCENARIOS[scenario][0]
    n1, n0 = np.mean(SLIP_WINDOWS), np.mean(NONSLIP_WINDOWS)

    def rates(cell: tuple[str, int]) -> tuple[float, float]:
        beta = LEVELS[cell]
        return (
            _rate(beta + CLASS_SHIFT, cell[0], seed_sd),
            _rate(beta - CLASS_SHIFT, cell[0], seed_sd),
        )

    def accuracy(cell: tuple[str, int]) -> float:
        tp, tn = rates(cell)
        return (n1 * tp + n0 * tn) / (n1 + n0)

    tp50, tn50 = rates(("lstm", 50))
    return {
        "rise": 100 * (accuracy(("lstm", 200)) - accuracy(("lstm", 5))),
        "levels": 100 * (accuracy(("lstm", 200)) - accuracy(("lstm", 50))),
        "gap": 100 * (tp50 - tn50),
        "lead": 100 * (accuracy(("lstm", 50)) - accuracy(("holweg", 50))),
        "cell": 100 * accuracy(("lstm", 50)),
    }


def rows(rng: np.random.Generator, m: int, scenario: str, rep: int) -> pd.DataFrame:
    """One simulated sensor's result rows: every cell of ``LEVELS`` for every finger and seed."""
    seed_sd, n_seeds = SCENARIOS[scenario]
    trial = rng.normal(0, TAU, 2 * m)
    detector = {"lstm": rng.normal(0, 0, 2 * m), "holweg": rng.normal(0, DETECTOR_SD, 2 * m)}
    out = []
    for finger in FINGERS:
        sizes = np.concatenate(
            [
                rng.integers(SLIP_WINDOWS[0], SLIP_WINDOWS[1] + 1, m),
                rng.integers(NONSLIP_WINDOWS[0], NONSLIP_WINDOWS[1] + 1, m),
            ]
        )
        groups = np.repeat(np.arange(2 * m), sizes)
        y = groups < m
        own = (trial + rng.normal(0, FINGER_SD, 2 * m))[groups]
        for (who, window), beta in LEVELS.items():
            level = np.where(y, beta + CLASS_SHIFT, beta - CLASS_SHIFT) + own
            level += detector[who][groups]
            for seed in range(n_seeds):
                right = rng.random(len(y)) < norm.cdf(level + rng.normal(0, seed_sd))
                figures = classification_figures(y, np.where(right, y, ~y), groups, seed=rep)
                out.append(
                    {
                        "sensor_type": "Nano17",
                        "sensor_instance": finger,
                        "window": window,
                        "_who": who,
                        "seed": seed,
                        "status": "ok",
                        **figures,
                    }
                )
    return pd.DataFrame(out)


def contrasts(table: pd.DataFrame) -> dict[str, Contrast]:
    """The four contrasts as :mod:`slipbench.report.findings` builds them from rows, and one
    cell's accuracy (the index finger's at window 50) with its row interval, over seeds as the
    tables give it (:func:`slipbench.report.tables.summarize`)."""
    lstm = table[table["_who"] == "lstm"]
    cells = _cells(lstm, [*UNIT, "window"])
    at50 = lstm[lstm["window"] == 50]
    rates = pd.concat(
        [
            _cells(at50, UNIT, "tp_rate").assign(_r="tp"),
            _cells(at50, UNIT, "tn_rate").assign(_r="tn"),
        ],
        ignore_index=True,
    )
    both = _cells(table[table["window"] == 50], [*UNIT, "_who"])
    index50 = lstm[(lstm["sensor_instance"] == "index") & (lstm["window"] == 50)]
    one = summarize(index50, [*UNIT, "window"])
    return {
        "rise": _unit_contrast(cells, "window", [200], [5]),
        "levels": _unit_contrast(cells, "window", [200], [50]),
        "gap": _unit_contrast(rates, "_r", ["tp"], ["tn"]),
        "lead": _unit_contrast(both, "_who", ["lstm"], ["holweg"]),
        "cell": Contrast(*one[["mean", "lo", "hi"]].iloc[0]).scaled(100),
    }


def _chunk(task: tuple[str, int, int, int, int]) -> dict[str, float]:
    """Hits and summed widths of every contrast over ``n`` replications (chunk ``c``)."""
    scenario, m, c, n, seed = task
    rng = np.random.default_rng([seed, list(SCENARIOS).index(scenario), m, c])
    true = truth(scenario)
    out = {f"{k} {name}": 0.0 for name in CONTRASTS for k in ("hit", "w", "sum", "sq")}
    for r in range(n):
        for name, e in contrasts(rows(rng, m, scenario, c * CHUNK + r)).items():
            out[f"hit {name}"] += bool(e.lo <= true[name] <= e.hi)
            out[f"w {name}"] += e.hi - e.lo
            out[f"sum {name}"] += e.estimate
            out[f"sq {name}"] += e.estimate**2
    return out


def study(
    reps: int, scenarios: Sequence[str], sizes: Sequence[int], jobs: int = 1, seed: int = 0
) -> pd.DataFrame:
    tasks = [
        (s, m, c, min(CHUNK, reps - c * CHUNK), seed)
        for s, m in itertools.product(scenarios, sizes)
        for c in range(-(-reps // CHUNK))
    ]
    if jobs > 1:
        with multiprocessing.Pool(jobs) as pool:
            done = pool.map(_chunk, tasks, chunksize=1)
    else:
        done = [_chunk(t) for t in tasks]
    lines = []
    for s, m in itertools.product(scenarios, sizes):
        mine = [h for t, h in zip(tasks, done) if t[:2] == (s, m)]
        total = {k: sum(h[k] for h in mine) / reps for k in mine[0]}
        line: dict = {"scenario": s, "trials/class": m, "reps": reps}
        for name in CONTRASTS:
            spread = max(total[f"sq {name}"] - total[f"sum {name}"] ** 2, 0.0)
            sd = np.sqrt(spread * reps / (reps - 1)) if reps > 1 else np.nan
            line[name] = total[f"hit {name}"]
            line[f"w {name}"] = total[f"w {name}"]
            line[f"w/ideal {name}"] = total[f"w {name}"] / (2 * 1.96 * sd) if sd > 0 else np.nan
        lines.append(line)
    return pd.DataFrame(lines)


def main(argv: Sequence[str] | None = None) -> pd.DataFrame:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reps", type=int, default=1000, help="replications per setting")
    ap.add_argument("--scenario", action="append", choices=list(SCENARIOS), help="repeatable")
    ap.add_argument("--sizes", default=",".join(map(str, SIZES)), help="trials per class")
    ap.add_argument("--jobs", type=int, default=1, help="processes")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, help="write the Markdown table here too")
    a = ap.parse_args(argv)
    start = time.perf_counter()
    table = study(
        a.reps,
        a.scenario or list(SCENARIOS),
        [int(s) for s in a.sizes.split(",")],
        a.jobs,
        a.seed,
    )
    text = (
        f"{a.reps} replications per row, seed {a.seed}, {time.perf_counter() - start:.0f} s\n\n"
        f"{table.round(3).to_markdown(index=False)}\n"
    )
    print(text, flush=True)
    if a.out:
        a.out.write_text(text)
    return table


if __name__ == "__main__":
    main()
