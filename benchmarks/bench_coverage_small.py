"""Coverage of slipbench's 95 % intervals on the small test sets labs have: 3-20 test trials a
class, trials holding windows of both classes (per-sample labels), pure trials, a lone pure
trial among mixed ones, and 1:4 imbalance. The study behind the table "Small test sets" of
``docs/studies/coverage.md``, which this script writes (``--doc``).

A window's latent score is ``mu_class + u + e``: ``u ~ N(0, TAU^2)`` a trial's effect, drawn for
each class the trial holds (a trial that is hard for slip need not be hard for holding), ``e``
window noise, an AR(1) series along the trial's windows (``RHO``; windows overlap, so neighbours
move together) of unit variance. A window is called slip when its score exceeds 0. Population
TP rate ``TP``, TN rate ``TN`` (closed form: normal integrals); the accuracy's target is the
ratio of the expected hits to the expected windows, as the figure is a ratio of sums. A trial
holds ``WINDOWS`` windows (uniform); a mixed trial's share of slip windows is uniform in
``SLIP_SHARE``, in bursts: its labels switch between hold and slip ``BURSTS`` times, as
per-sample labels of intermittent slip do.

Scenarios, ``m`` test trials a class (mixed trials counting for both):

- ``pure``: ``m`` slip trials and ``m`` non-slip trials.
- ``mixed``: ``m`` trials, each holding windows of both classes.
- ``lone``: ``m - 1`` mixed trials and one pure slip trial (a hold-slip protocol where one
  trial slipped from the start); the design resamples the pure trial with the mixed ones.
- ``imbalanced``: ``m`` slip trials and ``4 m`` non-slip trials (1:4).
- ``half-mixed``: ``m // 2`` mixed trials, and ``m - m // 2`` pure trials of each class.

Every replication's interval is checked against the truth; the Monte Carlo standard error of a
coverage of 0.95 over ``R`` replications is ``sqrt(0.95 x 0.05 / R)`` (0.007 at 1,000, 0.010 at
500). Methods (:data:`METHODS`), each on the same test sets: the product's default
(``scale-choice``: below ``LOW_N`` trials a class, a figure of one seed takes the CR2 interval
on Bell-McCaffrey's degrees of freedom; from ``LOW_N`` up, the bootstrap's), the figures as the
default took them before at every size (``replicate-logit``: the bootstrap on the plug-in
Satterthwaite degrees of freedom), and ``cr2-bm`` (the CR2 interval at every size,
``benchmarks/studies/intervals.py``). Every method's figures hold the binomial floor
(:func:`slipbench.stats.metrics.binomial_floor`).

    nice python benchmarks/bench_coverage_small.py --reps 500 --jobs 2 --doc docs/studies/coverage.md
"""

from __future__ import annotations

import argparse
import re
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from bench_coverage import run_tasks
from scipy.stats import norm
from studies.intervals import method as study_method

from slipbench.stats.bootstrap import DEFAULT_METHOD
from slipbench.stats.metrics import Predictions, mean_over_test_sets

# appended, never reordered: a scenario's index seeds its draws
SCENARIOS = ("pure", "mixed", "lone", "imbalanced", "half-mixed")
SIZES = (3, 5, 10, 20)
#: the default; its figures as they were before (the plug-in degrees of freedom); the candidate
METHODS = (DEFAULT_METHOD, "replicate-logit", "cr2-bm")
FIGURES = ("accuracy", "tp_rate", "tn_rate", "balanced_accuracy")
SHORT = {"accuracy": "acc", "tp_rate": "TP", "tn_rate": "TN", "balanced_accuracy": "BA"}
TAU, RHO = 1.0, 0.6
TP, TN = 0.80, 0.90
WINDOWS = (6, 40)
SLIP_SHARE = (0.2, 0.6)
BURSTS = 3
CHUNK = 50
#: the table's place in the study page, between these two lines
BEGIN, END = "<!-- bench_coverage_small: begin -->", "<!-- bench_coverage_small: end -->"


def _means() -> tuple[float, float]:
    """Latent class means giving the population rates ``TP`` and ``TN``."""
    sd = float(np.sqrt(1 + TAU**2))
    return float(norm.ppf(TP) * sd), float(-norm.ppf(TN) * sd)


def _trials(scenario: str, m: int) -> list[str]:
    """Each test trial's kind: ``slip``, ``hold`` or ``mixed``."""
    if scenario == "pure":
        return ["slip"] * m + ["hold"] * m
    if scenario == "mixed":
        return ["mixed"] * m
    if scenario == "lone":
        return ["mixed"] * (m - 1) + ["slip"]
    if scenario == "imbalanced":
        return ["slip"] * m + ["hold"] * (4 * m)
    half = m // 2
    return ["mixed"] * half + ["slip"] * (m - half) + ["hold"] * (m - half)


def truth(scenario: str, m: int) -> dict[str, float]:
    """The population figures: the rates, their mean, and the accuracy as the ratio of expected
    hits to expected windows over the scenario's trials."""
    n = np.mean(WINDOWS)
    share = np.mean(SLIP_SHARE)
    slip = hold = 0.0
    for kind in _trials(scenario, m):
        slip += n if kind == "slip" else n * share if kind == "mixed" else 0.0
        hold += n if kind == "hold" else n * (1 - share) if kind == "mixed" else 0.0
    return {
        "accuracy": (slip * TP + hold * TN) / (slip + hold),
        "tp_rate": TP,
        "tn_rate": TN,
        "balanced_accuracy": (TP + TN) / 2,
    }


def _labels(rng: np.random.Generator, kind: str, n: int) -> np.ndarray:
    """A trial's window labels: all one class, or bursts of slip among hold."""
    if kind != "mixed":
        return np.full(n, kind == "slip")
    n_slip = int(np.clip(round(rng.uniform(*SLIP_SHARE) * n), 1, n - 1))
    y = np.zeros(n, bool)
    cuts = np.sort(rng.choice(np.arange(1, n_slip), min(BURSTS, n_slip) - 1, replace=False))
    lengths = np.diff(np.r_[0, cuts, n_slip])  # slip bursts, placed among the hold windows
    gaps = rng.multinomial(n - n_slip, np.full(len(lengths) + 1, 1 / (len(lengths) + 1)))
    at = 0
    for gap, length in zip(gaps, lengths):
        at += gap
        y[at : at + length] = True
        at += length
    return y


def _ar1(rng: np.random.Generator, n: int) -> np.ndarray:
    """Unit-variance AR(1) noise of ``n`` windows."""
    e = rng.normal(0, 1, n)
    out = np.empty(n)
    out[0] = e[0]
    for i in range(1, n):
        out[i] = RHO * out[i - 1] + np.sqrt(1 - RHO**2) * e[i]
    return out


def dataset(rng: np.random.Generator, scenario: str, m: int) -> Predictions:
    """One simulated test set of the scenario."""
    mu1, mu0 = _means()
    ys, groups, scores = [], [], []
    for t, kind in enumerate(_trials(scenario, m)):
        n = int(rng.integers(WINDOWS[0], WINDOWS[1] + 1))
        y = _labels(rng, kind, n)
        effect = rng.normal(0, TAU, 2)  # the trial's effect on each class
        score = np.where(y, mu1 + effect[1], mu0 + effect[0]) + _ar1(rng, n)
        ys.append(y)
        groups.append(np.full(n, t))
        scores.append(score)
    score = np.concatenate(scores)
    return Predictions(np.concatenate(ys), score > 0, np.concatenate(groups), score)


def _chunk(task: tuple[str, int, int, int, int, tuple[str, ...]]) -> dict[str, float]:
    """Hits and summed widths of every method's interval over ``n`` replications of one
    (scenario, m), chunk ``c``; and how often each was not estimable (``na_``)."""
    scenario, m, c, n, seed, methods = task
    rng = np.random.default_rng([seed, SCENARIOS.index(scenario), m, c])
    true = truth(scenario, m)
    out: dict[str, float] = {}
    for r in range(n):
        part = dataset(rng, scenario, m)
        for meth in methods:
            f = mean_over_test_sets([part], seed=r, method=study_method(meth))
            for name, value in true.items():
                lo, hi = f[f"{name}_lo"], f[f"{name}_hi"]
                for key, v in (
                    (f"{meth}|{name}", bool(lo <= value <= hi)),
                    (f"{meth}|w_{name}", hi - lo),
                    # the whole range as a table prints it, at one decimal of a percent
                    (f"{meth}|na_{name}", bool(lo < 0.0005 and hi >= 0.9995)),
                ):
                    out[key] = out.get(key, 0.0) + v
    return out


def study(
    reps: int,
    scenarios: Sequence[str] = SCENARIOS,
    sizes: Sequence[int] = SIZES,
    methods: Sequence[str] = METHODS,
    jobs: int = 1,
    seed: int = 0,
) -> pd.DataFrame:
    """Per (scenario, m, method): coverage of each figure, its mean width (``w_``) and the share
    of intervals that were the whole range [0, 1] (``na_``)."""
    tasks = [
        (s, m, c, min(CHUNK, reps - c * CHUNK), seed, tuple(methods))
        for s in scenarios
        for m in sizes
        for c in range(-(-reps // CHUNK))
    ]
    results = run_tasks(_chunk, tasks, jobs)
    rows = []
    for s in scenarios:
        for m in sizes:
            mine = [h for t, h in zip(tasks, results) if t[:2] == (s, m)]
            for meth in methods:
                row: dict = {"scenario": s, "trials/class": m, "method": meth, "reps": reps}
                for kind in ("", "w_", "na_"):
                    for name in FIGURES:
                        key = f"{meth}|{kind}{name}"
                        row[f"{kind}{name}"] = sum(h[key] for h in mine) / reps
                rows.append(row)
    return pd.DataFrame(rows)


def markdown(table: pd.DataFrame) -> str:
    """Coverage, mean width (``w``) and share of whole-range intervals (``[0, 1]``, any
    figure), figures abbreviated."""
    shown = table[["scenario", "trials/class", "method", "reps"]].copy()
    for name in FIGURES:
        shown[SHORT[name]] = table[name]
    for name in FIGURES:
        shown[f"w {SHORT[name]}"] = table[f"w_{name}"]
    shown["[0, 1]"] = table[[f"na_{n}" for n in FIGURES]].max(axis=1)
    return str(shown.to_markdown(index=False, floatfmt=".3f"))


def misses(table: pd.DataFrame, band: tuple[float, float] = (0.93, 0.97)) -> list[str]:
    """Each (scenario, size, method, figure) whose coverage lies outside ``band``."""
    out = []
    for _, row in table.iterrows():
        for name in FIGURES:
            if not band[0] <= row[name] <= band[1]:
                out.append(
                    f"{row['scenario']} {row['trials/class']} {row['method']} "
                    f"{SHORT[name]} {row[name]:.3f}"
                )
    return out


def write_doc(path: Path, text: str) -> None:
    """Put ``text`` between :data:`BEGIN` and :data:`END` in ``path`` (refused without them)."""
    page = path.read_text()
    pattern = re.compile(re.escape(BEGIN) + r".*?" + re.escape(END), re.S)
    if not pattern.search(page):
        raise SystemExit(f"{path}: no '{BEGIN}' ... '{END}' block to write the table into")
    path.write_text(pattern.sub(lambda _: f"{BEGIN}\n{text}\n{END}", page))


def main(argv: Sequence[str] | None = None) -> pd.DataFrame:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reps", type=int, default=500, help="replications per scenario and size")
    ap.add_argument(
        "--scenario", action="append", choices=SCENARIOS, help="repeatable; all by default"
    )
    ap.add_argument(
        "--sizes", default=",".join(map(str, SIZES)), help="trials per class, comma list"
    )
    ap.add_argument(
        "--method",
        action="append",
        help="interval method (repeatable; bootstrap.METHODS or studies.intervals.STUDIES); "
        f"default: {', '.join(METHODS)}",
    )
    ap.add_argument("--jobs", type=int, default=2, help="processes")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--doc", type=Path, help="write the table into this page's marked block")
    a = ap.parse_args(argv)
    start = time.perf_counter()
    table = study(
        a.reps,
        a.scenario or SCENARIOS,
        [int(s) for s in a.sizes.split(",")],
        a.method or METHODS,
        a.jobs,
        a.seed,
    )
    mc = float(np.sqrt(0.95 * 0.05 / a.reps))
    outside = misses(table)
    text = (
        f"{a.reps} replications per row (Monte Carlo standard error {mc:.3f} at 0.95), seed "
        f"{a.seed}, {time.perf_counter() - start:.0f} s:\n\n"
        f"    nice python benchmarks/bench_coverage_small.py --reps {a.reps} --jobs {a.jobs}"
        f" --doc docs/studies/coverage.md\n\n{markdown(table)}\n\n"
        f"Outside [0.93, 0.97]: {len(outside)} of {len(table) * len(FIGURES)}"
        + (": " + "; ".join(outside) if outside else "")
        + "."
    )
    print(text, flush=True)
    if a.doc:
        write_doc(a.doc, text)
    return table


if __name__ == "__main__":
    main()
