"""The gate's plan of a bench file, before any cell runs: per detector, protocol and figure of
its ``[gate]``, the smallest drop the pooled test flags with 80 % power at the bench's seeds and
at its budget (:mod:`slipbench.gate.power`), from the calibration's noise, and what it costs;
and the refusal of a tolerance the bench cannot decide.

Two designs are planned. **Same seeds** (the workflow: both sides run the bench file, so seed
k of each made the same split) reads the calibration's paired noise, the twin's: retraining
alone. **Seeds apart** (a side run under other seeds) reads twice one side's seed noise: the
split's luck as well. Only the first is refused: it is what a pull request meets.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from slipbench.app.benchspec import Benchmark
from slipbench.app.calibrate import CalibrationStatus
from slipbench.engine.estimate import duration
from slipbench.engine.plan import Run
from slipbench.gate.calibration import Noise
from slipbench.gate.compare import POOLED_ALPHA
from slipbench.gate.gate import DEFAULT_TOLERANCE, unit
from slipbench.gate.power import Design, Sight, looks, nominal_levels, sight
from slipbench.store.columns import FIGURES, STREAMED, WINDOWED, names


@dataclass(frozen=True)
class PlannedTest:
    """One pooled test: a detector's mean of ``figure`` over a protocol's cells, its
    tolerance, and what each design sees (None where the calibration does not hold: ``why``)."""

    detector: str
    protocol: str
    figure: str
    tolerance: float
    deterministic: bool = False
    same: Sight | None = None
    apart: Sight | None = None
    why: str = ""


@dataclass(frozen=True)
class GatePlan:
    """The plan of a bench's gate: its ``design`` (seeds, budget, tests, level), its tests,
    the calibration's status, the cost of one seed of a side (None: not measured) and the
    simulated dataset's scale (None: a dataset folder), in what would decide a test."""

    design: Design
    tests: list[PlannedTest]
    status: CalibrationStatus
    seconds_per_seed: float | None
    scale: float | None = None  # the simulated dataset's (None: a dataset folder)
    side: dict[str, float] = field(default_factory=dict)  # the calibration's (Calibration.side)
    uncached: bool = False  # the simulated dataset is not in the cache: the first run makes it

    @property
    def undecided(self) -> list[PlannedTest]:
        """The tests whose tolerance the bench cannot decide at its budget, same seeds."""
        return [t for t in self.tests if t.same is not None and not t.same.decides]

    def lines(self) -> list[str]:
        """The plan as a reader takes it: the design and cost, then one line per test."""
        d = self.design
        at = looks(d.seeds, d.budget)
        head = (
            f"gate: {d.seeds} seeds a side, up to {d.budget} in looks of {d.seeds} "
            f"({', '.join(map(str, at))}); {d.tests} pooled tests held at {d.alpha:.1%}, "
            f"each at {d.level:.2g} a side"
        )
        spent = (
            "; spent over the looks (Lan-DeMets O'Brien-Fleming): one-sided levels "
            + ", ".join(f"{p:.2g}" for p in nominal_levels(d))
            if len(at) > 1
            else ""
        )
        out = [head + spent, *self.status.lines()]
        cal = self.status.calibration
        if cal is not None:
            m = cal.machine
            out.append(
                f"calibration: {len(cal.seeds)} seeds and their retrained twins, {cal.created}, "
                f"dataset {cal.dataset_fingerprint}"
            )
            if self.seconds_per_seed is not None:
                out.append(_cost_line(d, self.seconds_per_seed, self.side, m, self.uncached))
        return out + [_line(t, d, self.scale) for t in self.tests]


#: the parts of a side besides its models, as the calibration names them, and in words
SIDE_PARTS = {"start_s": "start", "read_s": "reading the data", "reports_s": "reports"}


def side_seconds(seeds: int, per_seed: float, side: dict[str, float]) -> tuple[float, bool]:
    """One side's wall seconds at ``seeds`` seeds (one `slipbench run`): its models at
    ``per_seed`` each, plus the start, the dataset's read and the reports as the calibration
    measured them (``side``; the reports scaled by seeds from the ``report_seeds`` they were
    timed on). Returns (seconds, whether the side's other costs were counted: False where
    the calibration predates measuring them, which counts the models alone)."""
    counted = all(math.isfinite(side.get(k, math.nan)) for k in (*SIDE_PARTS, "report_seeds"))
    seconds = seeds * per_seed
    if counted:
        reports = side["reports_s"] * seeds / max(side["report_seeds"], 1.0)
        seconds += side["start_s"] + side["read_s"] + reports
    return seconds, counted


def budget_seconds(d: Design, per_seed: float, side: dict[str, float]) -> float:
    """All looks' seconds on one side up to the budget: each look is a run of its new seeds
    (:func:`slipbench.gate.power.looks`), which starts, reads and reports again."""
    at = looks(d.seeds, d.budget)
    return sum(side_seconds(b - a, per_seed, side)[0] for a, b in zip([0, *at], at, strict=False))


def _simulating(side: dict[str, float], uncached: bool) -> tuple[float, str]:
    """What simulating the dataset first adds to the first run (seconds, words): nothing
    where it is cached; where it is not, what the calibration measured, or said uncounted."""
    if not uncached:
        return 0.0, ""
    seconds = side.get("simulate_s", math.nan)
    if math.isfinite(seconds):
        return seconds, f"; the first run simulates the dataset first ({seconds:.2g} s, counted)"
    return 0.0, (
        "; the simulated dataset is not in the cache: the first run simulates it first, not "
        "counted (the calibration did not simulate it)"
    )


def _cost_line(
    d: Design, per_seed: float, side: dict[str, float], m: dict, uncached: bool = False
) -> str:
    first, counted = side_seconds(d.seeds, per_seed, side)
    simulate, simulated = _simulating(side, uncached)
    if counted:
        parts = ", ".join(
            f"{word} {side[k]:.2g} s" for k, word in SIDE_PARTS.items() if k != "reports_s"
        )
        reports = side["reports_s"] * d.seeds / max(side["report_seeds"], 1.0)
        what = (
            f"counting {parts}, models {d.seeds * per_seed:.3g} s ({per_seed:.3g} s a seed) "
            f"and reports {reports:.2g} s"
        )
    else:
        what = (
            f"models only, {per_seed:.3g} s a seed: this calibration predates measuring the "
            "start, the data's read and the reports; `slipbench calibrate` measures them"
        )
    looks_n = len(looks(d.seeds, d.budget))
    budget = (
        f", {duration(simulate + budget_seconds(d, per_seed, side))} at the budget ({looks_n} runs)"
        if d.budget > d.seeds
        else ""
    )
    return (
        f"cost of a side: about {duration(simulate + first)} at {d.seeds} seeds{budget}; "
        f"{what}{simulated}; measured on {m.get('processors')} processors, {m.get('jobs')} "
        f"workers, load {'-'.join(map(str, m.get('load_average', [])))}"
    )


def _line(t: PlannedTest, d: Design, scale: float | None) -> str:
    name = f"{t.detector}, {t.protocol}, {FIGURES[t.figure].called}"
    u = unit(t.figure)
    if t.same is None or t.apart is None:
        return f"  {name} (tolerance {t.tolerance:g} {u}): not planned ({t.why})"
    same = (
        "its twin equals its run (retraining adds no noise), its test trials' noise remains: "
        if t.deterministic
        else ""
    ) + _seen(t.same, d, u, scale)
    return (
        f"  {name} (tolerance {t.tolerance:g} {u}): same seeds: {same}; seeds apart: "
        f"{_seen(t.apart, d, u, scale)}"
    )


def _seen(s: Sight, d: Design, u: str, scale: float | None) -> str:
    """What a design sees: the drops flagged with 80 % power at the seeds and the budget."""
    text = f"flags a drop of {s.tolerance + s.at_seeds:.2g} {u} at {d.seeds} seeds"
    if d.budget > d.seeds:
        text += f", {s.detectable:.2g} by {d.budget}"
    return text + ("" if s.decides else f" [cannot decide; would: {_would(s, u, scale)}]")


def _would(s: Sight, u: str, scale: float | None) -> str:
    """What would decide an undecided test: a budget, a tolerance, more data."""
    options = [f"a tolerance of {_up(s.at_budget)} {u}"]
    if s.budget_needed:
        options.insert(0, f"a budget of {s.budget_needed} seeds a side")
    if math.isfinite(s.data_needed):
        more = f"{s.data_needed:.2g} times the data, if the noise falls in proportion"
        options.append(f"scale {_up(scale * s.data_needed)} ({more})" if scale else more)
    return ", ".join(options[:-1]) + (" or " if len(options) > 1 else "") + options[-1]


def _up(x: float) -> str:
    """A tolerance that decides, rounded up to two significant digits."""
    if not (math.isfinite(x) and x > 0):
        return f"{x:g}"
    step = 10 ** (math.floor(math.log10(x)) - 1)
    return f"{math.ceil(x / step) * step:.2g}"


def gate_figures(bench: Benchmark, stream: bool) -> list[str]:
    """The figures the bench's gate reads in windowed (or streaming) cells, with their
    tolerances from its ``[gate]`` (every figure with its default where it has none)."""
    tolerances = bench.gate or DEFAULT_TOLERANCE
    return [f for f in names(STREAMED if stream else WINDOWED, gated=True) if f in tolerances]


def plan_gate(bench: Benchmark, runs: list[Run], status: CalibrationStatus) -> GatePlan:
    """The gate's plan of ``bench`` (its ``runs`` from :func:`plan_runs`) from ``status``."""
    tolerances = bench.gate or DEFAULT_TOLERANCE
    cal = status.calibration
    pairs = list(dict.fromkeys((r.detector_name, r.protocol_name) for r in runs))
    figures = {pair: _figures_of(bench, status, *pair) for pair in pairs}
    design = Design(
        bench.repeats,
        bench.seeds_budget,
        max(1, sum(len(f) for f in figures.values())),
        POOLED_ALPHA,
    )
    tests = []
    for (detector, protocol), gated in figures.items():
        for figure in gated:
            noise = (
                cal.noise(detector, protocol, figure)
                if cal is not None and status.holds(detector)
                else None
            )
            tests.append(
                _planned(detector, protocol, figure, tolerances[figure], noise, status, design)
            )
    per_seed = cal.wall_seconds_per_seed if cal is not None else math.nan
    return GatePlan(
        design,
        tests,
        status,
        per_seed if math.isfinite(per_seed) else None,
        bench.scale if bench.dataset is None else None,
        dict(cal.side) if cal is not None else {},
        _uncached(bench),
    )


def _uncached(bench: Benchmark) -> bool:
    """Whether the bench's simulated dataset is not in the cache (a run simulates it first)."""
    from slipbench.data.defaults import default_dataset_path

    if bench.dataset is not None:
        return False
    seed = bench.seed if bench.data_seed is None else bench.data_seed
    return not default_dataset_path(bench.scale, seed).is_dir()


def _figures_of(bench: Benchmark, status: CalibrationStatus, detector: str, protocol: str):
    """The gate's figures of one detector and protocol: those the calibration measured, else
    the windowed ones (a protocol's kind is known from its cells, which have not run)."""
    cal = status.calibration
    found = cal.detectors.get(detector) if cal is not None else None
    part = found.protocols.get(protocol) if found is not None else None
    tolerances = bench.gate or DEFAULT_TOLERANCE
    if part is not None and part.figures:
        return [f for f in names(gated=True) if f in part.figures and f in tolerances]
    return gate_figures(bench, stream=False)


def _planned(  # noqa: PLR0913 - one test's coordinates and what it is planned from
    detector: str,
    protocol: str,
    figure: str,
    tolerance: float,
    noise: Noise | None,
    status: CalibrationStatus,
    design: Design,
) -> PlannedTest:
    if noise is None:
        why = status.stale.get(detector) or (
            "no calibration" if status.calibration is None else "not in the calibration"
        )
        return PlannedTest(detector, protocol, figure, tolerance, why=why)
    cal = status.calibration
    assert cal is not None
    scale = FIGURES[figure].scale
    drop = 2 * tolerance / scale if FIGURES[figure].rate else None  # the drop it must flag
    same, apart = (
        sight(scale * math.sqrt(noise.per_seed(paired, drop)), noise.df(paired), tolerance, design)
        for paired in (True, False)
    )
    return PlannedTest(
        detector, protocol, figure, tolerance, cal.detectors[detector].deterministic, same, apart
    )


def refusal(plan: GatePlan, bench: Benchmark) -> tuple[str, str] | None:
    """The first tolerance the bench cannot decide, same seeds: (the ``[gate]`` key, a
    one-line reason with what would decide it); None where every planned test decides."""
    for t in plan.undecided:
        assert t.same is not None
        u = unit(t.figure)
        return t.figure, (
            f"a tolerance of {t.tolerance:g} {u} that this bench cannot decide: with its "
            f"calibrated noise ({t.same.sd:.2g} {u} a seed, {t.same.df:g} degrees of freedom), "
            f"the pooled test of {t.detector} on {t.protocol} flags with 80 % power only a "
            f"drop of {t.same.detectable:.2g} {u} at its budget of {bench.seeds_budget} seeds "
            f"a side; {_would(t.same, u, plan.scale)} would decide it"
        )
    return None
