"""The gate's study (issue 46): does the shipped bench say "no regression" to harmless changes
and "regressed" to harmful ones, learned detectors included? Run at the shipped bench's
settings (its protocols, scale, split, seeds a side, budget and tolerances, read from the bench
file) against a gate (``--gate``; ``today``: ``compare`` one look at the bench's seeds, each side's
noise from its own seeds, as before issue 46; ``sequential``: the shipped workflow's gate, the
noise from the calibrations that hold and looks at more seeds up to the budget).

The detector is a retrained plugin like the independent audit's: ``HalfLogistic``, a logistic
regression on log band energies fitted on a random half of the training windows, drawn from
its fit's seed, so every seed retrains it. Candidates (each one retrained, damage done in
``predict``):

- null, same seeds: ``HalfLogisticSalted``, its half drawn from another stream of each seed;
- null, seeds apart: ``HalfLogistic`` under seeds 1000 further on (other splits);
- null, a retrained rewrite: ``HalfLogisticRewrite``, the same model written another way (its
  own feature code and solver) with its half from a third stream;
- a 2-point uniform accuracy drop: ``HalfLogisticDrop`` (salted) inverts a random share
  ``DROP`` of the windows' scores, ``DROP = 0.02 / (2a - 1)`` with ``a`` the base's mean
  accuracy, so the mean accuracy falls by 2 points;
- 7 more points of false alarms at equal accuracy: ``HalfLogisticShift`` (salted) raises every
  logit by ``SHIFT``, solved on the base's stored scores so that the mean TN rate falls by 7
  points (at a threshold near the balanced optimum, accuracy moves little: the output says how
  much it did);
- issue 35's check: ``HalfLogisticShiftHalf`` (salted), every logit raised by 0.5 (its
  reproduction at filing: TN rate 66 -> 44 %), which must be flagged in TN at the bench's seeds;
- the bench's own detectors with holweg's ``keep`` 0.80 -> 0.79 (a harmless tweak of a
  detector that draws nothing) and 0.80 -> 0.6 (a harmful one), at the bench's seeds.

Cells are computed once: each detector runs over a pool of seeds and a comparison takes its
seeds from the pools (comparison k: seeds ``k * R`` onwards, ``R`` the bench's repeats; a gate
that adds seeds takes the next ones, wrapping around the pool, so later looks of neighbouring
comparisons share seeds: their first looks are independent). Printed: per design, the exit
codes, the pooled tests that flagged, the mean changes the candidate made, the seeds a side ran
(the CI cost) and compare's time.

With ``--alternatives`` it prints instead the plans of benches the shipped one was chosen
against (:data:`ALTERNATIVES`: the study bench with other protocols), each calibrated alike.

    nice python benchmarks/gate_study.py --work DIR [--bench bench.toml] > benchmarks/results/gate_study_today.md
    nice python benchmarks/gate_study.py --work DIR --gate sequential > benchmarks/results/gate_study_sequential.md
    nice python benchmarks/gate_study.py --work DIR --alternatives > benchmarks/results/gate_plans_not_shipped.md
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import textwrap
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).parent))
import compare_study as cs  # noqa: E402

PLUGIN = textwrap.dedent(
    '''
    import numpy as np
    from sklearn.linear_model import LogisticRegression

    from slipbench.base import BaseDetector


    def features(x):
        """Log mean absolute value, standard deviation and five log-spaced band amplitudes."""
        amp = np.abs(np.fft.rfft(x - x.mean(axis=1, keepdims=True), axis=1))
        edges = np.unique(np.geomspace(1, amp.shape[1], 6).astype(int))
        bands = [amp[:, a:b].mean(axis=1) for a, b in zip(edges[:-1], edges[1:])]
        return np.log(np.column_stack([np.abs(x).mean(axis=1), x.std(axis=1), *bands]) + 1e-9)


    class HalfLogistic(BaseDetector):
        """Logistic regression on log band energies, fitted on a random half of the windows."""

        stream = ()
        solver = "lbfgs"

        def _fit(self, x, y, seed):
            pick = np.random.default_rng([seed, *self.stream]).random(len(x)) < 0.5
            f = self._features(x)
            self.mu_, self.sd_ = f.mean(axis=0), f.std(axis=0) + 1e-9
            model = LogisticRegression(solver=self.solver, max_iter=1000)
            self.model_ = model.fit((f[pick] - self.mu_) / self.sd_, y[pick])

        def _features(self, x):
            return features(x)

        def _predict_proba(self, x):
            return self.model_.predict_proba((self._features(x) - self.mu_) / self.sd_)[:, 1]
    '''
)
SALTED = '''
from half_logistic import HalfLogistic


class HalfLogisticSalted(HalfLogistic):
    """HalfLogistic with its half drawn from another stream of the same seed."""

    stream = (1,)
'''
REWRITE = '''
import numpy as np
from half_logistic import HalfLogistic


class HalfLogisticRewrite(HalfLogistic):
    """The same model written another way: its features by a real FFT of the centred windows
    through numpy's hfft-free path and a Newton solver; its half from a third stream."""

    stream = (2,)
    solver = "newton-cg"

    def _features(self, x):
        centred = x - x.mean(axis=1)[:, None]
        amp = np.abs(np.fft.fft(centred, axis=1))[:, : x.shape[1] // 2 + 1]
        edges = np.unique(np.geomspace(1, amp.shape[1], 6).astype(int))
        bands = np.stack([amp[:, a:b].mean(axis=1) for a, b in zip(edges[:-1], edges[1:])], 1)
        level = np.stack([np.mean(np.abs(x), axis=1), np.std(x, axis=1)], 1)
        return np.log(np.concatenate([level, bands], axis=1) + 1e-9)
'''
DAMAGED = {
    "drop": '''
import numpy as np
from half_logistic_salted import HalfLogisticSalted


class HalfLogisticDrop(HalfLogisticSalted):
    """HalfLogisticSalted with a random {drop:.4f} of its windows' scores inverted."""

    def _predict_proba(self, x):
        p = super()._predict_proba(x)
        rng = np.random.default_rng([len(x), int(abs(self.model_.coef_.sum()) * 1e9) % 2**32])
        return np.where(rng.random(len(x)) < {drop!r}, 1 - p, p)
''',
    "shift": '''
import numpy as np
from half_logistic_salted import HalfLogisticSalted


class HalfLogisticShift(HalfLogisticSalted):
    """HalfLogisticSalted with every logit raised by {shift:.4f}: more windows called slip."""

    def _predict_proba(self, x):
        p = np.clip(np.asarray(super()._predict_proba(x), float), 1e-12, 1 - 1e-12)
        return 1 / (1 + np.exp(-(np.log(p / (1 - p)) + {shift!r})))
''',
    "shifthalf": '''
import numpy as np
from half_logistic_salted import HalfLogisticSalted


class HalfLogisticShiftHalf(HalfLogisticSalted):
    """HalfLogisticSalted with every logit raised by {issue35:.4f} (issue 35's check)."""

    def _predict_proba(self, x):
        p = np.clip(np.asarray(super()._predict_proba(x), float), 1e-12, 1 - 1e-12)
        return 1 / (1 + np.exp(-(np.log(p / (1 - p)) + {issue35!r})))
''',
}
FILES = {
    "half_logistic.py": PLUGIN,
    "half_logistic_salted.py": SALTED,
    "half_logistic_rewrite.py": REWRITE,
}
APART = 1000  # the seeds-apart candidate's seeds begin this far from the base's
TARGET_DROP, TARGET_TN = 0.02, 0.07
ISSUE35_SHIFT = 0.5  # issue 35's check: this logit shift, 3 seeds a side, must flag TN
DAMAGE_SEEDS = 10  # comparisons' first looks the damage is solved on


@dataclass(frozen=True)
class Design:
    """A design: the candidate's pool and detector, its seeds' offset from the base's, and
    whether it is a null (``--nulls`` comparisons) or a damage (``--powers``)."""

    pool: str
    detector: str
    offset: int
    kind: str


DESIGNS = {
    "null, same seeds": Design("salted", "half-logistic-salted", 0, "null"),
    "null, seeds apart": Design("apart", "half-logistic", APART, "null"),
    "null, a retrained rewrite": Design("rewrite", "half-logistic-rewrite", 0, "null"),
    "2-point accuracy drop": Design("drop", "half-logistic-drop", 0, "power"),
    "7 more points of false alarms": Design("shift", "half-logistic-shift", 0, "power"),
    "issue 35's check: logits +0.5": Design("shifthalf", "half-logistic-shifthalf", 0, "power"),
}


class Study:
    """The bench's settings, the dataset and the plugins, and pools of evaluated seeds."""

    def __init__(self, root: Path, bench_file: Path) -> None:
        from slipbench.app.benchfile import plan_runs
        from slipbench.app.benchside import bench_dataset
        from slipbench.app.benchspec import load_benchmark
        from slipbench.engine import registry

        self.root = root
        self.bench = load_benchmark(bench_file)
        self.plugins = root / "plugins"
        (self.plugins / "detectors").mkdir(parents=True, exist_ok=True)
        for name, text in FILES.items():
            (self.plugins / "detectors" / name).write_text(text)
        registry.add_plugin_folder(self.plugins)
        # the bench's own runs (its protocols with their options), before anything is simulated
        self.bench_runs = plan_runs(self.bench, echo=lambda _: None, check_gate=False)
        self.protocols = {r.protocol_name: r.protocol for r in self.bench_runs}
        self.data = bench_dataset(self.bench, echo=lambda _: None)
        # the calibrations a gate takes its noise from: the bench's own (its detectors) and
        # the study bench's, once calibrated (HalfLogistic), each kept to what it holds for
        self.sources = _held(self.bench, self.bench_runs)

    @property
    def repeats(self) -> int:
        return self.bench.repeats

    def damage(self, label: str, **constants: float) -> None:
        """Write a damaged candidate's plugin with its constants."""
        from slipbench.engine import registry

        text = DAMAGED[label].format(**constants)
        (self.plugins / "detectors" / f"half_logistic_{label}.py").write_text(text)
        registry.add_plugin_folder(self.plugins)  # the new file registered (the rest again)

    def pool(self, label: str, seeds: list[int], detector) -> Path:
        """The results of ``detector`` at ``seeds`` in the pool ``label``; seeds it lacks are
        evaluated (a pool grows as a gate asks for more seeds)."""
        from slipbench.engine.runner import Run, evaluate
        from slipbench.store.results import ResultsStore

        out = self.root / f"pool-{label}"
        missing = sorted(set(seeds) - self._finished_seeds(out))
        if not missing:
            return out
        b = self.bench
        runs = [
            Run(detector, p, b.split, s, b.labels) for s in missing for p in self.protocols.values()
        ]
        t0 = time.perf_counter()
        rows = evaluate(self.data, runs, ResultsStore(out), jobs=b.jobs, progress=False)
        bad = rows[~rows["status"].isin(["ok", "skipped"])]
        if len(bad):
            raise SystemExit(f"pool {label}: {len(bad)} cells {sorted(set(bad['status']))}")
        print(
            f"# pool {label}: {len(missing)} seeds in {time.perf_counter() - t0:.0f} s "
            f"(load {os.getloadavg()[0]:.1f})",
            file=sys.stderr,
        )
        return out

    def _finished_seeds(self, out: Path) -> set[int]:
        if not (out / "results.parquet").exists():
            return set()
        rows = pd.read_parquet(out / "results.parquet", columns=["seed", "protocol"])
        per_seed = rows.groupby("seed")["protocol"].nunique()
        return set(per_seed[per_seed == len(self.protocols)].index)


#: benches the plan was asked about and not shipped: the study bench with these protocols
ALTERNATIVES = {
    "window-size at 50 and 100 beside cross-instance": {
        "window-size": {"windows": [50, 100]},
        "cross-instance": {},
    },
}


def study_bench(study: Study, protocols: dict | None = None, name: str = "study") -> Path:
    """The bench file with the study's detector in place of the bench's (and ``protocols`` in
    place of its protocols): what a calibration and plan are made of (simulated data only)."""
    import json

    b = study.bench
    assert b.dataset is None, "the study runs on the simulated dataset"
    lines = [
        f"# {b.path.name} with HalfLogistic in place of its detectors (benchmarks/gate_study.py)",
        "[benchmark]",
        'out = "results"',
        "[dataset]",
        f"scale = {b.scale!r}",
        f"seed = {b.seed if b.data_seed is None else b.data_seed}",
        "[run]",
        f'split = "{b.split}"',
        f"seed = {b.seed}",
        f"repeats = {b.repeats}",
        f"jobs = {b.jobs}",
        'plugins = ["plugins"]',
        "[gate]",
        *(f"{figure} = {tol!r}" for figure, tol in b.gate.items()),
        f"budget = {b.seeds_budget}",
        "[detectors.half-logistic]",
    ]
    for protocol, params in (b.protocols if protocols is None else protocols).items():
        lines += [f"[protocols.{protocol}]", *(f"{k} = {json.dumps(v)}" for k, v in params.items())]
    path = study.root / f"{name}.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


def calibrated_plan(study: Study, seeds: int, bench_file: Path | None = None) -> list[str]:
    """Calibrate the study's bench (or ``bench_file``) on ``seeds`` seeds, kept in the work
    folder (a second run, or a bench sharing cells, reads them), and return its gate's plan."""
    from slipbench.app.benchfile import plan_runs
    from slipbench.app.benchspec import load_benchmark
    from slipbench.app.calibrate import calibrate, status
    from slipbench.app.gateplan import plan_gate

    bench = load_benchmark(bench_file or study_bench(study))
    runs = plan_runs(bench, echo=lambda _: None, check_gate=False)
    t0 = time.perf_counter()
    calibrate(
        bench,
        runs,
        study.data,
        seeds,
        study.root / "calibration",
        progress=False,
        echo=lambda _: None,
    )
    print(f"# calibration of {bench.path.name}: {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    if bench_file is None:  # the study bench's noise joins the gate's sources
        study.sources = [*study.sources, *status(bench, runs).sources()]
    return plan_gate(bench, runs, status(bench, runs)).lines()


def _held(bench, runs) -> list:
    """The calibration of ``bench`` kept to the detectors it holds for (none without one)."""
    from slipbench.app.calibrate import status

    return status(bench, runs).sources()


def alternative_plans(study: Study, seeds: int) -> None:
    """The plans of :data:`ALTERNATIVES`, each calibrated as the study's bench is."""
    for k, (label, protocols) in enumerate(ALTERNATIVES.items()):
        bench = study_bench(study, protocols, name=f"alternative-{k}")
        print(f"The study bench with {label} (not shipped):\n\n```text")
        print("\n".join(calibrated_plan(study, seeds, bench)) + "\n```\n", flush=True)


def damage_constants(base: Path, seeds: list[int]) -> dict[str, float]:
    """``drop``: the share of windows to invert for a 2-point mean accuracy drop; ``shift``:
    the logit shift that lowers the mean TN rate by 7 points, both from the base's rows and
    stored scores at ``seeds``."""
    from slipbench.store.results import read_predictions

    rows = pd.read_parquet(base / "results.parquet")
    rows = rows[rows["seed"].isin(seeds) & (rows["status"] == "ok")]
    a = float(rows["accuracy"].mean())
    logits = []
    for key in rows["key"]:
        p = read_predictions(base, key)
        s = np.clip(p["score"].to_numpy(float), 1e-12, 1 - 1e-12)
        logits.append(np.log(s / (1 - s))[~p["y_true"].to_numpy(bool)])

    def tn_drop(shift: float) -> float:
        return float(np.mean([(z < 0).mean() - (z + shift < 0).mean() for z in logits]))

    lo, hi = 0.0, 5.0
    for _ in range(60):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if tn_drop(mid) < TARGET_TN else (lo, mid)
    return {"drop": TARGET_DROP / (2 * a - 1), "shift": (lo + hi) / 2}


# ----------------------------------------------------------------------------- gates
Sides = Callable[[int], tuple[Path, Path]]


def judge_today(sides: Sides, study: Study) -> tuple[int, int, list[str], pd.DataFrame]:
    """compare as it stands, at the bench's seeds and [gate] tolerances: (exit code, seeds a
    side, pooled figures flagged, pooled tests)."""
    from slipbench.gate.compare import compare
    from slipbench.gate.gate import Gate

    base, cand = sides(study.repeats)
    cmp = compare(base, cand, Gate(dict(study.bench.gate)) if study.bench.gate else Gate())
    pooled = cmp.pooled
    flagged = [] if pooled.empty else list(pooled.loc[pooled["verdict"] == "regressed", "figure"])
    return cmp.exit_code, study.repeats, flagged, pooled


def judge_sequential(sides: Sides, study: Study) -> tuple[int, int, list[str], pd.DataFrame]:
    """The gate as the shipped workflow runs it: ``compare`` at the bench's seeds, its noise from
    the calibrations that hold (:attr:`Study.sources`), and while undecided the bench's seeds
    more on both sides, up to its budget; each look decides at its own level."""
    from slipbench.gate.compare import compare
    from slipbench.gate.gate import Gate

    b = study.bench
    gate = Gate(
        dict(b.gate) if b.gate else Gate().tolerances, seeds=b.repeats, budget=b.seeds_budget
    )
    n = b.repeats
    while True:
        base, cand = sides(n)
        cmp = compare(base, cand, gate, sources=study.sources)
        if cmp.state != "undecided" or n >= b.seeds_budget:
            break
        n = min(n + b.repeats, b.seeds_budget)
    pooled = cmp.pooled
    flagged = [] if pooled.empty else list(pooled.loc[pooled["verdict"] == "regressed", "figure"])
    return cmp.exit_code, n, flagged, pooled


GATES = {"today": judge_today, "sequential": judge_sequential}


# ----------------------------------------------------------------------------- designs
def comparison_sides(study: Study, design: Design, k: int, size: int) -> Sides:
    """Comparison ``k``'s sides at ``n`` seeds: seeds ``k * R ..`` (wrapping around ``size``
    seeds) of the base pool and of the design's candidate, evaluated where missing."""

    def sides(n: int) -> tuple[Path, Path]:
        offsets = [(k * study.repeats + j) % size for j in range(n)]
        first = study.bench.seed
        base = study.pool("base", [first + o for o in offsets], "half-logistic")
        cand_seeds = [first + design.offset + o for o in offsets]
        cand = study.pool(design.pool, cand_seeds, design.detector)
        work = study.root / "sides" / f"{design.pool}-{k}-{n}"
        if not (work / "cand" / "results.parquet").exists():
            cs.side(base, work / "base", [first + o for o in offsets])
            cs.side(cand, work / "cand", cand_seeds)
        return work / "base", work / "cand"

    return sides


def summary(name: str, outcomes: list[tuple]) -> str:
    """One design's line of the table."""
    codes = Counter(o[0] for o in outcomes)
    seeds = np.array([o[1] for o in outcomes])
    flagged = Counter(f for o in outcomes for f in o[2])
    tests = [o[3] for o in outcomes if len(o[3])]  # none where every cell is identical
    changes = pd.concat(tests, ignore_index=True) if tests else pd.DataFrame()
    mean = changes.groupby("figure")["change"].mean() if len(changes) else pd.Series(dtype=float)
    seconds = np.array([o[4] for o in outcomes])
    n = len(outcomes)
    return (
        f"| {name} | {n} | {codes[0]} | {codes[1]} | {codes[6]} | "
        f"{', '.join(f'{f} {c}' for f, c in sorted(flagged.items())) or 'none'} | "
        + " / ".join(f"{mean.get(f, np.nan):+.1f}" for f in ("accuracy", "tn_rate", "tp_rate"))
        + f" | {np.median(seeds):.0f} / {np.percentile(seeds, 95):.0f} | "
        f"{np.median(seconds):.0f} |"
    )


def run_design(study: Study, gate, name: str, n: int, size: int) -> str:
    design = DESIGNS[name]
    first = study.bench.seed + design.offset  # every comparison's first look, in one run
    study.pool(
        design.pool,
        [first + k * study.repeats + j for k in range(n) for j in range(study.repeats)],
        design.detector,
    )
    outcomes = []
    for k in range(n):
        sides = comparison_sides(study, design, k, size)
        t0 = time.perf_counter()
        code, seeds, flagged, pooled = gate(sides, study)
        outcomes.append((code, seeds, flagged, pooled, time.perf_counter() - t0))
    return summary(name, outcomes)


def holweg_lines(study: Study, gate) -> list[str]:
    """The bench's own detectors against holweg's keep 0.79 and 0.6, at the bench's seeds."""
    from slipbench.engine import registry

    if "holweg" not in study.bench.detectors:
        return [f"| holweg keep | 0 | - | - | - | {study.bench.path.name} has no holweg | | | |"]
    lines = []
    for keep in (0.79, 0.6):
        params = study.bench.detectors["holweg"] | {"keep": keep}
        changed = registry.detectors.get("holweg")(**params)
        t0 = time.perf_counter()
        code, used, flagged, pooled = gate(_bench_sides(study, changed, keep), study)
        outcome = (code, used, flagged, pooled, time.perf_counter() - t0)
        lines.append(summary(f"holweg keep 0.80 -> {keep:g} (bench detectors)", [outcome]))
    return lines


def _bench_sides(study: Study, holweg, keep: float) -> Sides:
    """Sides of the bench's detectors at its first seeds: the base, and the candidate with
    holweg replaced by ``holweg`` (the other detectors' rows are the base's: unchanged)."""
    from slipbench.engine import registry

    def sides(n: int) -> tuple[Path, Path]:
        seeds = list(range(study.bench.seed, study.bench.seed + n))
        base = {
            name: study.pool(f"bench-{name}", seeds, registry.detectors.get(name)(**params))
            for name, params in study.bench.detectors.items()
        }
        cand = base | {"holweg": study.pool(f"bench-holweg-{keep:g}", seeds, holweg)}
        work = study.root / "sides" / f"bench-{keep:g}-{n}"
        if not (work / "cand" / "results.parquet").exists():
            for side, folders in (("base", base), ("cand", cand)):
                parts = [cs.side(f, work / side / name, seeds) for name, f in folders.items()]
                _joined(parts, work / side)
        return work / "base", work / "cand"

    return sides


def _joined(parts: list[Path], out: Path) -> None:
    """One results folder of several (their rows concatenated, predictions linked)."""
    rows = pd.concat([pd.read_parquet(p / "results.parquet") for p in parts], ignore_index=True)
    (out / "predictions").mkdir(parents=True, exist_ok=True)
    for p in parts:
        for f in (p / "predictions").iterdir():
            (out / "predictions" / f.name).symlink_to(f.resolve())
    rows.to_parquet(out / "results.parquet")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--bench", type=Path, default=Path(__file__).parents[1] / "bench.toml")
    ap.add_argument("--gate", choices=sorted(GATES), default="today")
    ap.add_argument("--nulls", type=int, default=20, help="comparisons per null design")
    ap.add_argument("--powers", type=int, default=10, help="comparisons per damage")
    ap.add_argument("--work", type=Path, default=None, help="keep the pools here (reused)")
    ap.add_argument(
        "--pool", type=int, default=20, help="comparisons whose first looks the pools hold apart"
    )
    ap.add_argument(
        "--calibrate", type=int, default=21, help="seeds of the study bench's calibration (0: none)"
    )
    ap.add_argument(
        "--designs",
        nargs="*",
        default=None,
        help="only these designs (DESIGNS' names, 'holweg' for the bench's detectors)",
    )
    ap.add_argument(
        "--alternatives",
        action="store_true",
        help="print only the plans of the benches not shipped (ALTERNATIVES), then stop",
    )
    args = ap.parse_args()
    root = args.work or Path(tempfile.mkdtemp(prefix="gate-study-"))
    root.mkdir(parents=True, exist_ok=True)
    load = os.getloadavg()
    study = Study(root, args.bench)
    if args.alternatives:
        alternative_plans(study, args.calibrate)
        return
    b, gate = study.bench, GATES[args.gate]
    # seeds per pool: each comparison's first look its own; later looks wrap around the pool
    size = max(args.nulls, args.pool) * b.repeats
    seeds = list(range(b.seed, b.seed + size))
    base = study.pool("base", seeds, "half-logistic")
    # the damage is solved on the first DAMAGE_SEEDS seeds whatever --powers is: a damaged
    # candidate's pool is then the same plugin in every run of the study
    constants = damage_constants(base, seeds[: b.repeats * DAMAGE_SEEDS])
    constants["issue35"] = ISSUE35_SHIFT
    for label in DAMAGED:
        study.damage(label, **constants)
    print(
        f"Gate `{args.gate}` on {b.path.name}'s settings: protocols "
        f"{', '.join(f'{n} {p.get_params()}' for n, p in study.protocols.items())}; "
        f"{b.split} split; scale {b.scale:g}; {b.repeats} seeds a side, budget "
        f"{b.seeds_budget}; tolerances {b.gate}. HalfLogistic, each side retrained; damage: "
        f"{constants['drop']:.4f} of the windows inverted (drop), logits +{constants['shift']:.3f} "
        f"(shift). Pools of {size} seeds.\n"
    )
    if args.calibrate:  # the gate takes the study bench's calibration from here on
        print("The study bench's plan (`slipbench calibrate`, HalfLogistic):\n\n```text")
        print("\n".join(calibrated_plan(study, args.calibrate)) + "\n```\n", flush=True)
    else:  # the study bench's calibration as an earlier run left it, where there is one
        from slipbench.app.benchfile import plan_runs
        from slipbench.app.benchspec import load_benchmark

        bench = load_benchmark(study_bench(study))
        study.sources += _held(bench, plan_runs(bench, echo=lambda _: None, check_gate=False))
    print(
        "| design | comparisons | exit 0 | exit 1 | exit 6 | pooled tests flagged | mean "
        "change accuracy / TN / TP (points) | seeds a side (median / 95th pct) | compare s "
        "(median) |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    chosen = set(args.designs or [*DESIGNS, "holweg"])
    for name, design in DESIGNS.items():
        n = args.nulls if design.kind == "null" else args.powers
        if name in chosen:
            print(run_design(study, gate, name, n, size), flush=True)
    for line in holweg_lines(study, gate) if "holweg" in chosen else []:
        print(line, flush=True)
    print(
        f"\nMachine: {os.cpu_count()} processors, {b.jobs} workers; load average "
        f"{load[0]:.1f} at the start, {os.getloadavg()[0]:.1f} at the end (shared: compare's "
        "seconds are this machine's under that load)."
    )


if __name__ == "__main__":
    main()
