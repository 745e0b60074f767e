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

from slipbench.base import BaseDetector, clone, plugin_id
from slipbench.errors import EnvironmentFault, UsageError
from slipbench.seeding import seed_int
from slipbench.stats.metrics import chance_interval, classification_figures, stream_low_n
from slipbench.store.keys import file_digest, unkeyed
from slipbench.store.reads import reading
from slipbench.store.results import write_text_atomic
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


class Result(NamedTuple):
    """One tested cell: its result fields (columns of :mod:`slipbench.store.columns`) and the
    scores of its test windows (None for a streaming or failed cell)."""

    fields: dict[str, Any]
    scores: np.ndarray | None = None


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


def fit_and_test(job: Job, on_phase: Callable[[str], None] | None = None) -> list[Result]:
    """Fit one model, test it on each test set: classify its windows (:class:`TestSet`), or
    stream its recordings (:class:`~slipbench.stream.cell.StreamTest`, no scores returned).
    Returns, per test set, its result fields and its scores.

    ``on_phase("test")`` is called when the model is trained and testing starts, so a worker
    can say which phase a process that vanished was in. Whatever the plugin raises, or ends the
    process with (``sys.exit``), fails the cells with the reason and the phase.
    """
    detector, seed, sampling_rate = job.detector, job.seed, job.sampling_rate
    train_x, train_y, tests = job.train_x, job.train_y, job.tests
    if job.name and not type(detector).__dict__.get("name"):
        type(detector).name = job.name
    phase = "fit"
    try:
        detector, cost = _trained(job)
        phase = "test"
        if on_phase is not None:
            on_phase(phase)
        learned, warning = _learned(detector, train_y, detector.predict_proba(train_x))
        notes = [warning] if warning else []
        choices = _choices(detector, sampling_rate, notes + _read_warnings(cost))
        out: list[Result] = []
        for test in tests:
            if isinstance(test, StreamTest):
                trials, streamed = (
                    len(set(test.test.trials)),
                    streamed_figures(detector, seed, test),
                )
                out.append(
                    Result(
                        {
                            "status": "ok",
                            "reason": "",
                            "n_train": len(train_x),
                            "sampling_rate_hz": sampling_rate,
                            "n_test_trials": trials,
                            **streamed,
                            "low_n": stream_low_n(
                                streamed["n_onset_trials"],
                                streamed["n_onsets"],
                                streamed["n_nonslip_trials"],
                            ),
                            **cost,
                            **learned,
                            **choices,
                        },
                        None,
                    )
                )
                continue
            t0 = time.perf_counter()
            scores = detector.predict_proba(test.x)
            infer_s = time.perf_counter() - t0
            y_pred = (scores >= 0.5).astype(np.int8)
            out.append(
                Result(
                    {
                        "status": "ok",
                        "reason": _one_class(test.y),
                        "n_train": len(train_x),
                        "n_test": len(test.x),
                        "n_test_trials": int(len(np.unique(test.groups))),
                        "sampling_rate_hz": sampling_rate,
                        **classification_figures(
                            test.y, y_pred, test.groups, seed, scores=scores, strata=test.strata
                        ),
                        **cost,
                        **_constant(test.y),
                        "infer_us_per_window": infer_s / len(test.x) * 1e6,
                        **learned,
                        **choices,
                    },
                    scores,
                )
            )
        return out
    except EnvironmentFault:
        raise  # a full disk is the machine's fault, not the detector's: the run stops, exit 5
    # whatever a plugin raises stays in its cells; sys.exit too, which would end a run
    # that lost them with exit 0 (SystemExit is no Exception)
    except (Exception, SystemExit) as exc:  # noqa: BLE001
        reason = _raised(plugin_id(type(detector)), exc, phase)
        return [Result({"status": "failed", "reason": reason})] * len(tests)


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
        "train_balanced_accuracy": c["balanced_accuracy"],
        "train_balanced_accuracy_lo": c["lo"],
        "train_balanced_accuracy_hi": c["hi"],
    }
    held = _validation_part(detector)
    v = None
    if held is not None:
        v = chance_interval(held[0], held[1] >= 0.5)
        fields |= {
            "validation_balanced_accuracy": v["balanced_accuracy"],
            "validation_balanced_accuracy_lo": v["lo"],
            "validation_balanced_accuracy_hi": v["hi"],
        }
    if c["chance"]:
        return fields, _at_chance(c, f"on its own {len(train_y)} training windows")
    if held is not None and v is not None and v["chance"]:
        where = f"on its {len(held[0])} held-out validation windows"
        return fields, _at_chance(v, where) + (
            f", though its own training windows score {c['balanced_accuracy']:.2f}"
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
        f"did not learn: {where} its balanced accuracy, {c['balanced_accuracy']:.2f} (95 % "
        f"interval {c['lo']:.2f}-{c['hi']:.2f}), cannot be told from chance (0.5)"
    )


def _choices(
    detector: BaseDetector, sampling_rate: float, warnings: list[str] | None = None
) -> dict[str, Any]:
    """The detector's fitted choices as JSON (and ``epochs``, where it reports the epochs it
    ran), and warnings: ``warnings`` given, then about a band that thresholds drift (from 0 Hz)
    or reaches the Nyquist frequency."""
    choices = detector.fitted_choices()
    warnings = list(warnings or [])
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
    (:func:`changed_reads`) and refits where one differs."""
    paths = unkeyed(cls, opened)
    if not paths:
        return {}
    return {"unkeyed_reads": json.dumps({str(p): file_digest(p) for p in paths}, sort_keys=True)}


def changed_reads(row: dict[str, Any]) -> list[str]:
    """The files of a stored row's ``unkeyed_reads`` whose content is no longer what it was."""
    recorded = json.loads(row.get("unkeyed_reads") or "{}")
    return [path for path, digest in recorded.items() if file_digest(Path(path)) != digest]


def _read_warnings(cost: dict[str, Any]) -> list[str]:
    return [
        f"the fit read {path}, which is not part of the detector's code identity (declare it "
        "in data_files): its content is checked when the cell is reused"
        for path in json.loads(cost.get("unkeyed_reads") or "{}")
    ]


def _trained(job: Job) -> tuple[BaseDetector, dict[str, Any]]:
    """A fitted detector and its training cost, from ``model_path`` when an earlier run left it."""
    detector, model_path, train_x = job.detector, job.model_path, job.train_x
    cost_path = Path(f"{model_path}.json")  # read and written only where there is a model_path
    if model_path is not None and cost_path.is_file():
        return type(detector).load(model_path), json.loads(cost_path.read_text())
    detector = clone(detector)
    with PeakMemory() as mem, reading() as opened:
        t0 = time.perf_counter()
        detector.fit(
            train_x,
            job.train_y,
            sampling_rate=job.sampling_rate,
            seed=seed_int(job.seed, "detector"),
            groups=job.train_groups,
        )
        train_s = time.perf_counter() - t0
    cost = {
        "train_s": train_s,
        # per sample of time: a window of channels is as many samples as one of the signal
        "train_us_per_sample": train_s / (train_x.shape[0] * train_x.shape[1]) * 1e6,
        "peak_mem_mb": mem.mb,
        **unkeyed_reads(type(detector), opened),
    }
    if model_path is not None:
        try:
            detector.save(model_path)
        except UsageError:
            return detector, cost  # state that cannot be saved safely: reuse it in this run only
        write_text_atomic(cost_path, json.dumps(cost))  # written last: it marks the model complete
    return detector, cost
