"""The worker's job: fit one model (or load it from an earlier run) and score its test sets.

Runs in whatever process an executor chooses, so it takes and returns plain data only. A
detector that raises, or returns scores that are not probabilities, fails its cells with the
reason; the rest of a run goes on.
"""

from __future__ import annotations

import json
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import psutil

from slipbench.base import BaseDetector, FitJob, clone, plugin_id
from slipbench.errors import EnvironmentFault, UsageError
from slipbench.seeding import seed_int
from slipbench.stats.metrics import chance_interval, classification_figures, stream_low_n
from slipbench.store import models
from slipbench.store.columns import BALANCED_ACCURACY, overridden
from slipbench.store.keys import file_digest, unkeyed
from slipbench.store.reads import reading
from slipbench.stream.cell import StreamTest, streamed_figures


class PeakMemory:
    """Peak resident memory above the starting level while a block runs (sampled every 5 ms;
    catches torch and numpy allocations alike, unlike tracemalloc)."""

    def __enter__(self):
        self._proc = psutil.Process()
        self._base = self._peak = self._proc.memory_info().rss
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, daemon=True)
        self._thread.start()
        return self

    def _watch(self):
        while not self._stop.wait(0.005):
            self._peak = max(self._peak, self._proc.memory_info().rss)

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        self._peak = max(self._peak, self._proc.memory_info().rss)
        self.mb = (self._peak - self._base) / 2**20


@dataclass
class TestSet:
    """What one cell is tested on: windows (n, length) (channels: (n, length, n_channels)),
    labels (n,), the cluster of each window
    (n,): the unit its bootstrap resamples (a trial), and its balancing stratum (n,)."""

    x: np.ndarray
    y: np.ndarray
    groups: np.ndarray
    strata: np.ndarray | None = None


#: a field of a result, never of a row: warnings the process that records the cell says once
#: each (a saved model refused and fitted again)
NOTICES = "notices"


class Result(NamedTuple):
    """One tested cell: its result fields (columns of :mod:`slipbench.store.columns`, and
    :data:`NOTICES`) and the scores of its test windows (None for a streaming or failed cell)."""

    fields: dict[str, Any]
    scores: np.ndarray | None = None


class Stored(Result):
    """A cell's whole row, already in the results folder (written where the cell ran: an
    array task of a SLURM run)."""


@dataclass
class Job:
    """One model's work, as plain data (it crosses to worker processes): fit ``detector`` on
    ``train_x`` and ``train_y``, then test it on each of ``tests``.

    With ``model_path``, a model an earlier run saved there for the same training windows is
    loaded instead of refitted (its training cost is reported as measured then), and a newly
    fitted one is saved there. ``name`` is the detector's registry id: a worker process imports
    the class afresh, without the id the registry stamped on it in the parent, and messages
    must name the id a user can pass (``minirocket``), not the class. ``train_groups`` is the
    trial of each training window (a detector may hold whole trials out for validation).
    """

    detector: BaseDetector
    seed: int
    sampling_rate: float
    train_x: np.ndarray
    train_y: np.ndarray
    tests: list[TestSet | StreamTest]
    model_path: str | None = None
    name: str = ""
    train_groups: np.ndarray | None = None
    draw: int = 0  # which draw of the detector's seed stream it trains from (Run.retrained)

    @property
    def fit_seed(self) -> int:
        """The seed ``fit`` receives: the run seed's ``detector`` stream (draw 0, as runs
        always had), or another draw of it."""
        return seed_int(self.seed, "detector", *((self.draw,) if self.draw else ()))


@dataclass
class Lockstep:
    """Models of one :attr:`~slipbench.base.BaseDetector.lockstep` class that one task trains
    together (:meth:`~slipbench.base.BaseDetector.fit_lockstep`), each then tested as
    :func:`fit_and_test` tests it alone; its results are those of ``jobs`` in order."""

    jobs: list[Job]


def perform(work: Job | Lockstep, on_phase: Callable[[str], None] | None = None) -> list[Result]:
    """A task's results: :func:`fit_and_test` of a Job, :func:`fit_and_test_together` of a
    Lockstep."""
    if isinstance(work, Lockstep):
        return fit_and_test_together(work.jobs, on_phase)
    return fit_and_test(work, on_phase)


def fit_and_test(job: Job, on_phase: Callable[[str], None] | None = None) -> list[Result]:
    """Fit one model, test it on each test set: classify its windows (:class:`TestSet`), or
    stream its recordings (:class:`~slipbench.stream.cell.StreamTest`, no scores returned).
    Returns, per test set, its result fields and its scores.

    ``on_phase("test")`` is called when the model is trained and testing starts, so a worker
    can say which phase a process that vanished was in. Whatever the plugin raises, or ends the
    process with (``sys.exit``), fails the cells with the reason and the phase.
    """
    _stamp_name(job)
    saved, said = _saved(job)
    try:
        got = saved if saved is not None else _fitted(job)
    except EnvironmentFault:
        raise
    except (Exception, SystemExit) as exc:  # noqa: BLE001
        return _told(_failed_cells(job, exc, "fit"), said)
    if on_phase is not None:
        on_phase("test")
    return _told(_tested(job, *got), said)


def fit_and_test_together(
    jobs: list[Job], on_phase: Callable[[str], None] | None = None
) -> list[Result]:
    """:func:`fit_and_test` of each job, the models fitted together where the class trains in
    lockstep: the results of the jobs, in order. A model saved by an earlier run is loaded; a
    member that cannot train (one class, bad windows) fails alone with its reason."""
    for job in jobs:
        _stamp_name(job)
    trained, said = _trained_together(jobs)
    if on_phase is not None:
        on_phase("test")
    out: list[Result] = []
    for job, got, told in zip(jobs, trained, said, strict=True):
        if isinstance(got, BaseException):
            out += _told(_failed_cells(job, got, "fit"), told)
        else:
            out += _told(_tested(job, *got), told)
    return out


def _told(results: list[Result], said: list[str]) -> list[Result]:
    if not said:
        return results
    return [Result({**r.fields, NOTICES: tuple(said)}, r.scores) for r in results]


def _stamp_name(job: Job) -> None:
    if job.name and not type(job.detector).__dict__.get("name"):
        type(job.detector).name = job.name


def _failed_cells(job: Job, exc: BaseException, phase: str) -> list[Result]:
    reason = _raised(plugin_id(type(job.detector)), exc, phase)
    return [Result({"status": "failed", "reason": reason})] * len(job.tests)


def _tested(
    job: Job, detector: BaseDetector, cost: dict[str, Any], notes: list[str] | None = None
) -> list[Result]:
    """A fitted model's results on each of the job's test sets; what the plugin raises (or
    ends the process with) in testing fails them with the reason."""
    try:
        learned, warning = _learned(detector, job.train_y, detector.predict_proba(job.train_x))
        choices = _choices(
            detector,
            job.sampling_rate,
            (notes or []) + ([warning] if warning else []) + _read_warnings(cost),
        )
        common = {"n_train": len(job.train_x), "sampling_rate_hz": job.sampling_rate}
        return [
            _streamed(detector, job.seed, test, common | cost | learned | choices)
            if isinstance(test, StreamTest)
            else _classified(detector, job.seed, test, common | cost | learned | choices)
            for test in job.tests
        ]
    except EnvironmentFault:
        raise  # a full disk is the machine's fault, not the detector's: the run stops, exit 5
    # whatever a plugin raises stays in its cells; sys.exit too, which would end a run
    # that lost them with exit 0 (SystemExit is no Exception)
    except (Exception, SystemExit) as exc:  # noqa: BLE001
        return _failed_cells(job, exc, "test")


def _streamed(detector: BaseDetector, seed: int, test: StreamTest, fields: dict) -> Result:
    streamed = streamed_figures(detector, seed, test)
    low_n = stream_low_n(
        streamed["n_onset_trials"], streamed["n_onsets"], streamed["n_nonslip_trials"]
    )
    return Result(
        {
            "status": "ok",
            "reason": "",
            "n_test_trials": len(set(test.test.trials)),
            **streamed,
            "low_n": low_n,
            **fields,
        },
        None,
    )


def _classified(detector: BaseDetector, seed: int, test: TestSet, fields: dict) -> Result:
    t0 = time.perf_counter()
    scores = detector.predict_proba(test.x)
    infer_s = time.perf_counter() - t0
    y_pred = (scores >= 0.5).astype(np.int8)
    figures = classification_figures(
        test.y, y_pred, test.groups, seed, scores=scores, strata=test.strata
    )
    return Result(
        {
            "status": "ok",
            "reason": _one_class(test.y),
            "n_test": len(test.x),
            "n_test_trials": int(len(np.unique(test.groups))),
            **figures,
            **fields,
            **_constant(test.y),
            "infer_us_per_window": infer_s / len(test.x) * 1e6,
            # with the figures' intervals (a bootstrap): what a plan charges a cell's test
            "test_s": time.perf_counter() - t0,
        },
        scores,
    )


def _raised(who: str, exc: BaseException, phase: str) -> str:
    if isinstance(exc, SystemExit):
        return (
            f"detector {who!r} raised SystemExit({exc.code!r}) in {phase}: plugin code must "
            "not end the process"
        )
    detail = "".join(traceback.format_exception_only(type(exc), exc)).strip()
    return f"detector {who!r} raised: {detail} (in {phase})"


def _one_class(y: np.ndarray) -> str:
    """A note for a test set of one class: the rates of the other class do not exist."""
    if len(np.unique(y)) == 2:
        return ""
    there, absent = ("slip", "TN rate") if y[0] == 1 else ("non-slip", "TP rate")
    return f"the test set holds {there} windows only: accuracy is the {'TP' if y[0] == 1 else 'TN'} rate; the {absent} does not exist"


def _constant(y: np.ndarray) -> dict[str, float]:
    """On a test set of one class, the accuracy a detector that always says "slip" scores
    (1 on slip windows only, 0 on non-slip only): what a figure there is to be read against.
    Absent on a set of both classes, so the rows of balanced cells keep their columns."""
    if len(np.unique(y)) == 2:
        return {}
    return {"constant_slip_accuracy": float(np.mean(y == 1))}


def _learned(
    detector: BaseDetector, train_y: np.ndarray, train_scores: np.ndarray
) -> tuple[dict[str, float], str]:
    """Whether the fitted model learned, judged at threshold 0.5 by balanced accuracy with its
    95 % Wilson interval (:func:`slipbench.stats.metrics.chance_interval`) on its own training
    windows and, for a detector that held a validation part out (``validation_y_`` and
    ``validation_scores_``, as :class:`~slipbench.torch.TorchDetector` keeps them), on those
    windows too. A warning where an interval reaches 0.5 (or lies below it): its test figures
    then say the model did not learn, not that it fails to generalize.

    The validation part catches what the training windows cannot: a network fits its own
    training windows above chance (tcn on BioTac SP DoS: 0.58-0.64, the interval clear of 0.5)
    while what it fitted is noise, at chance on windows it did not train on."""
    c = chance_interval(train_y, train_scores >= 0.5)
    fields = {
        "train_balanced_accuracy": c[BALANCED_ACCURACY.name],
        "train_balanced_accuracy_lo": c["lo"],
        "train_balanced_accuracy_hi": c["hi"],
    }
    held = _validation_part(detector)
    v = None
    if held is not None:
        v = chance_interval(held[0], held[1] >= 0.5)
        fields |= {
            "validation_balanced_accuracy": v[BALANCED_ACCURACY.name],
            "validation_balanced_accuracy_lo": v["lo"],
            "validation_balanced_accuracy_hi": v["hi"],
        }
    if c["chance"]:
        return fields, _at_chance(c, f"on its own {len(train_y)} training windows")
    if held is not None and v is not None and v["chance"]:
        where = f"on its {len(held[0])} held-out validation windows"
        return fields, _at_chance(v, where) + (
            f", though its own training windows score {c[BALANCED_ACCURACY.name]:.2f}"
        )
    return fields, ""


def _validation_part(detector: BaseDetector) -> tuple[np.ndarray, np.ndarray] | None:
    """(labels, scores) of the windows a detector held out of its training, where it kept them."""
    y = getattr(detector, "validation_y_", None)
    scores = getattr(detector, "validation_scores_", None)
    if y is None or scores is None or not len(y):
        return None
    return np.asarray(y), np.asarray(scores)


def _at_chance(c: dict, where: str) -> str:
    return (
        f"did not learn: {where} its balanced accuracy, {c[BALANCED_ACCURACY.name]:.2f} (95 % "
        f"interval {c['lo']:.2f}-{c['hi']:.2f}), cannot be told from chance (0.5)"
    )


def _choices(
    detector: BaseDetector, sampling_rate: float, warnings: list[str] | None = None
) -> dict[str, Any]:
    """The detector's fitted choices as JSON (and ``epochs``, where it reports the epochs it
    ran), with the parameters it ran otherwise than asked (``overrides``), and warnings:
    ``warnings`` given, then one per override, then about a band that thresholds drift (from
    0 Hz) or reaches the Nyquist frequency."""
    choices = detector.fitted_choices()
    warnings = list(warnings or [])
    ran = detector.overrides()
    if ran:
        asked = detector.get_params()
        choices["overrides"] = json.loads(
            json.dumps(
                {k: {"ran": v, "asked": asked.get(k), "why": why} for k, (v, why) in ran.items()}
            )
        )
        warnings += [
            f"ran {overridden(k, v['ran'], v['asked'], v['why'])}"
            for k, v in choices["overrides"].items()
        ]
    band = choices.get("band_hz")
    if band is not None:
        if band[0] <= 0:
            warnings.append(
                f"the fitted band {band[0]:g}-{band[1]:g} Hz starts at 0 Hz: it thresholds drift, not vibration"
            )
        if band[1] >= sampling_rate / 2:
            warnings.append(
                f"the fitted band {band[0]:g}-{band[1]:g} Hz reaches the Nyquist frequency ({sampling_rate / 2:g} Hz)"
            )
    out: dict[str, Any] = {
        "fitted": json.dumps(choices, sort_keys=True),
        "warnings": "; ".join(warnings),
    }
    if "epochs" in choices:
        out["epochs"] = int(choices["epochs"])
    return out


def unkeyed_reads(cls: type, opened: set[str]) -> dict[str, str]:
    """``{"unkeyed_reads": JSON {path: digest}}`` of the files a fit read that its code identity
    does not hash (none: no field, so rows of plugins that read nothing keep their columns).
    The key had to exist before the fit, so a later run compares the digests instead
    (:func:`slipbench.store.keys.changed_reads`) and refits where one differs."""
    paths = unkeyed(cls, opened)
    if not paths:
        return {}
    return {"unkeyed_reads": json.dumps({str(p): file_digest(p) for p in paths}, sort_keys=True)}


def _read_warnings(cost: dict[str, Any]) -> list[str]:
    return [
        f"the fit read {path}, which is not part of the detector's code identity (declare it "
        "in data_files): its content is checked when the cell is reused"
        for path in json.loads(cost.get("unkeyed_reads") or "{}")
    ]


def _saved(job: Job) -> tuple[tuple[BaseDetector, dict[str, Any]] | None, list[str]]:
    """The model an earlier run saved at ``model_path`` for these windows, with its cost, once
    it proves itself (None: none saved, or one refused); and, for a refused one, a warning
    naming its file: it is fitted again, never reused and never blamed on the detector."""
    if job.model_path is None:
        return None, []
    try:
        return models.reuse(type(job.detector), Path(job.model_path)), []
    except models.Unproved as exc:
        return None, [f"{exc}; fitting it again"]


def _kept(job: Job, detector: BaseDetector, cost: dict[str, Any]) -> list[str]:
    """Save a newly fitted model at ``model_path`` (where there is one) with its proof; a model
    whose state cannot be saved safely is used in this run only, and the warning returned says
    so in its rows (every later run fits it again)."""
    if job.model_path is None:
        return []
    try:
        models.keep(detector, Path(job.model_path), cost)
    except UsageError as exc:
        return [f"model not saved, so every run fits it again: {exc}"]
    return []


def _cost(job: Job, train_s: float, peak_mb: float, opened: set[str]) -> dict[str, Any]:
    x = job.train_x
    return {
        "train_s": train_s,
        # per sample of time: a window of channels is as many samples as one of the signal
        "train_us_per_sample": train_s / (x.shape[0] * x.shape[1]) * 1e6,
        "peak_mem_mb": peak_mb,
        **unkeyed_reads(type(job.detector), opened),
    }


def _fitted(job: Job) -> tuple[BaseDetector, dict[str, Any], list[str]]:
    """A newly fitted detector, its training cost (kept at ``model_path``) and the warnings
    of keeping it."""
    detector = clone(job.detector)
    with PeakMemory() as mem, reading() as opened:
        t0 = time.perf_counter()
        detector.fit(
            job.train_x,
            job.train_y,
            sampling_rate=job.sampling_rate,
            seed=job.fit_seed,
            groups=job.train_groups,
        )
        train_s = time.perf_counter() - t0
    cost = _cost(job, train_s, mem.mb, opened)
    return detector, cost, _kept(job, detector, cost)


Trained = tuple[BaseDetector, dict[str, Any]] | tuple[BaseDetector, dict[str, Any], list[str]]


def _trained_together(jobs: list[Job]) -> tuple[list[Trained | BaseException], list[list[str]]]:
    """Per job, its fitted detector and cost (and notes), or what it raised: saved models are
    loaded, the others fitted together through ``fit_lockstep``. A member that fails fit's
    checks is left out with its reason; should the lockstep fit itself raise, each model is
    fitted alone instead, so that the error lands on the member that caused it, and its rows
    say so. Also, per job, the warnings about a saved model refused."""
    out: list[Trained | BaseException | None] = [None] * len(jobs)
    fresh: list[tuple[int, BaseDetector]] = []
    said: list[list[str]] = []
    for i, job in enumerate(jobs):
        out[i], told = _saved(job)
        said.append(told)
        try:
            if out[i] is None:
                detector = clone(job.detector)
                detector._checked_fit_args(
                    job.train_x, job.train_y, job.sampling_rate, job.train_groups
                )
                fresh.append((i, detector))
        except EnvironmentFault:
            raise
        except (Exception, SystemExit) as exc:  # noqa: BLE001
            out[i] = exc
    try:
        for i, got in _fitted_together([jobs[i] for i, _ in fresh], [d for _, d in fresh]):
            out[fresh[i][0]] = got
    except EnvironmentFault:
        raise
    except (Exception, SystemExit) as exc:  # noqa: BLE001
        note = f"fitted alone: training {len(fresh)} models in lockstep raised {exc!r}"
        for i, _ in fresh:
            out[i] = _alone(jobs[i], note)
    assert all(got is not None for got in out)
    return out, said  # type: ignore[return-value]


def _fitted_together(jobs: list[Job], detectors: list[BaseDetector]) -> list[tuple[int, Trained]]:
    """Fit ``detectors`` on ``jobs`` in one ``fit_lockstep``; each model's training time is the
    group's divided among its models (they train at once), its peak memory the group's."""
    if not jobs:
        return []
    fit_jobs = [
        FitJob(j.train_x, j.train_y, j.fit_seed, j.sampling_rate, j.train_groups) for j in jobs
    ]
    with PeakMemory() as mem, reading() as opened:
        t0 = time.perf_counter()
        type(detectors[0]).fit_lockstep(detectors, fit_jobs)
        train_s = (time.perf_counter() - t0) / len(jobs)
    out: list[tuple[int, Trained]] = []
    for i, (job, detector) in enumerate(zip(jobs, detectors, strict=True)):
        cost = _cost(job, train_s, mem.mb, opened)
        out.append((i, (detector, cost, _kept(job, detector, cost))))
    return out


def _alone(job: Job, note: str) -> Trained | BaseException:
    try:
        detector, cost, notes = _fitted(job)
        return detector, cost, [note, *notes]
    except EnvironmentFault:
        raise
    except (Exception, SystemExit) as exc:  # noqa: BLE001
        return exc
