"""The results schema: every column a result row may hold, with its type, unit and meaning.

Rows are checked against it where they are made (:func:`checked`) and where the store writes
them; ``docs/reference/results-columns.md`` is written from it (``docs/tools/results_columns.py``). A
protocol's cell-key columns (``sensor_type``, ``window``, ...) are its own: a row may hold the
keys its ``cell`` column names. Adding a figure is one entry in :data:`WINDOWED_FIGURES` or
:data:`STREAMED_FIGURES`; its interval columns follow from the entry.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Column:
    """One results column: its name, its Arrow type (``string``, ``int64``, ``float64``,
    ``bool``), its unit ("" where it has none) and what it means."""

    name: str
    type: str
    unit: str
    meaning: str


@dataclass(frozen=True)
class Figure:
    """A figure of a cell with its interval: ``name``, ``name_lo``, ``name_hi`` and, with
    ``se``, ``name_se``; with ``wilson``, the window-level ``name_wilson_lo``/``_hi``; with
    ``operating``, the same at the streaming operating point (``op_`` prefixed)."""

    name: str
    unit: str
    meaning: str
    se: bool = False
    wilson: bool = False
    operating: bool = False

    def columns(self) -> Iterator[Column]:
        for prefix, where in [("", "")] + [("op_", " at the operating point")] * self.operating:
            name, meaning = prefix + self.name, self.meaning + where
            yield Column(name, "float64", self.unit, meaning)
            yield Column(
                f"{name}_lo", "float64", self.unit, f"lower end of the 95 % interval of {name}"
            )
            yield Column(
                f"{name}_hi", "float64", self.unit, f"upper end of the 95 % interval of {name}"
            )
            if self.se:
                yield Column(
                    f"{name}_se", "float64", self.unit, f"bootstrap standard error of {name}"
                )
            if self.wilson:
                for end in ("lo", "hi"):
                    yield Column(
                        f"{name}_wilson_{end}",
                        "float64",
                        self.unit,
                        f"window-level Wilson bound of {name} (as if windows were independent)",
                    )


STR, INT, FLOAT, BOOL = "string", "int64", "float64", "bool"
JSON = "JSON"

#: a windowed cell's figures (cluster bootstrap over test trials)
WINDOWED_FIGURES = (
    Figure("accuracy", "fraction", "share of test windows classified right", se=True, wilson=True),
    Figure(
        "tp_rate",
        "fraction",
        "share of slip windows called slip (1 - misses)",
        se=True,
        wilson=True,
    ),
    Figure(
        "tn_rate",
        "fraction",
        "share of non-slip windows called non-slip (1 - false alarms)",
        se=True,
        wilson=True,
    ),
    Figure("balanced_accuracy", "fraction", "mean of the TP and TN rates", se=True),
    Figure("auroc", "fraction", "area under the ROC curve of the scores", se=True),
)
#: a streaming cell's figures (bootstrap over test trials), at the detector's threshold and at
#: the operating point
STREAMED_FIGURES = (
    Figure("detection_rate", "fraction", "share of slip onsets detected in time", operating=True),
    Figure("median_delay_ms", "ms", "median delay from onset to detection", operating=True),
    Figure("p95_delay_ms", "ms", "95th percentile of the detection delay", operating=True),
    Figure(
        "false_alarms_per_min", "1/min", "alarms per minute of non-slip streaming", operating=True
    ),
)

IDENTITY = (
    Column("key", STR, "", "content address of the cell: data, code, parameters, seed"),
    Column("model_key", STR, "", "content address of the model the cell tests"),
    Column("run_id", STR, "", "UTC time stamp of the run that computed the cell"),
    Column("protocol", STR, "", "protocol id"),
    Column("protocol_params", STR, JSON, "the protocol's parameters"),
    Column(
        "protocol_layout", STR, JSON, "what the protocol's cells are: its table's rows and columns"
    ),
    Column(
        "protocol_presentation",
        STR,
        JSON,
        "how the protocol's table and figure look ('' where it declares none)",
    ),
    Column("detector", STR, "", "detector id"),
    Column("detector_params", STR, JSON, "the detector's parameters"),
    Column(
        "detector_reference",
        BOOL,
        "",
        "the detector is the registered reference, the baseline tables compare against",
    ),
    Column("split", STR, "", "how windows were split into training and test sides"),
    Column("seed", INT, "", "the run's seed"),
    Column("labels", STR, "", "how windows were labelled (scenario or samples)"),
    Column("normalize", STR, "", "how recordings were scaled before windowing"),
    Column("input", STR, "", "univariate signal or channels"),
)
CELL = (
    Column("sensor_type", STR, "", "cell key: the sensor type of the unit"),
    Column("sensor_instance", STR, "", "cell key: the finger of the unit"),
    Column("window", INT, "samples", "window length"),
    Column("window_ms", FLOAT, "ms", "window length in time at the unit's rate"),
    Column("hop", INT, "samples", "streaming hop between two scores"),
    Column("rate_hz", FLOAT, "Hz", "cell key: the sampling rate after downsampling"),
    Column("downsample", INT, "", "decimation factor"),
    Column("decimation", STR, "", "how the signal was decimated"),
    Column("antialias", BOOL, "", "whether a low-pass filter preceded decimation"),
    Column("cell", STR, JSON, "the cell's key, whole"),
    Column("train_sensors", STR, JSON, "units of the training side"),
    Column("train_where", STR, JSON, "filters of the training side"),
    Column("test_sensors", STR, JSON, "units of the test side"),
    Column("test_where", STR, JSON, "filters of the test side"),
    Column("test_stream", STR, JSON, "streaming settings of the test ('' for windows)"),
    Column("train_slip_windows", INT, "windows", "slip windows on the training side"),
    Column("train_nonslip_windows", INT, "windows", "non-slip windows on the training side"),
    Column("test_slip_windows", INT, "windows", "slip windows on the test side"),
    Column("test_nonslip_windows", INT, "windows", "non-slip windows on the test side"),
    Column(
        "normalize_scale_train", FLOAT, "", "median scale the training recordings were divided by"
    ),
    Column("normalize_scale_test", FLOAT, "", "median scale the test recordings were divided by"),
)
OUTCOME = (
    Column("status", STR, "", "ok, skipped, failed or timeout"),
    Column("reason", STR, "", "why a cell was skipped or failed, or a note on a one-class test"),
    Column("n_train", INT, "windows", "training windows"),
    Column("n_test", INT, "windows", "test windows"),
    Column("n_test_trials", INT, "trials", "test trials (the bootstrap's clusters)"),
    Column("sampling_rate_hz", FLOAT, "Hz", "sampling rate the detector saw"),
    Column("tp", INT, "windows", "slip windows called slip"),
    Column("tn", INT, "windows", "non-slip windows called non-slip"),
    Column("fp", INT, "windows", "non-slip windows called slip"),
    Column("fn", INT, "windows", "slip windows called non-slip"),
    Column("df", FLOAT, "", "degrees of freedom of the intervals"),
    Column("ci_note", STR, "", "why an interval is missing or wide"),
    Column("n_test_clusters_slip", INT, "trials", "test trials holding slip windows"),
    Column("n_test_clusters_nonslip", INT, "trials", "test trials holding non-slip windows"),
    Column("low_n", BOOL, "", "a class rests on fewer trials than LOW_N: read as inconclusive"),
    Column(
        "constant_slip_accuracy",
        FLOAT,
        "fraction",
        "accuracy of always saying slip (one-class tests)",
    ),
)
STREAM = (
    Column("n_trials", INT, "trials", "test trials streamed"),
    Column("n_onset_trials", INT, "trials", "test trials with a slip onset"),
    Column("n_nonslip_trials", INT, "trials", "test trials without slip"),
    Column("n_onsets", INT, "", "slip onsets in the test streams"),
    Column("n_detected", INT, "", "onsets detected in time"),
    Column("n_missed", INT, "", "onsets not detected in time"),
    Column("n_censored", INT, "", "onsets too near a recording's end to judge"),
    Column("n_at_start", INT, "", "recordings that start in slip (no onset)"),
    Column("false_alarms", INT, "", "alarms during non-slip streaming"),
    Column("nonslip_minutes", FLOAT, "min", "minutes of non-slip streaming"),
    Column("threshold", FLOAT, "", "the detector's own threshold"),
    Column("false_alarms_by_scenario", STR, JSON, "false alarms per scenario"),
    Column("op_threshold", FLOAT, "", "threshold of the operating point (training streams)"),
    Column("op_budget_per_min", FLOAT, "1/min", "false-alarm budget of the operating point"),
    Column("op_note", STR, "", "why there is no operating point"),
    Column("tradeoff", STR, JSON, "threshold sweep of the test streams"),
    Column("compute_ms_per_hop", FLOAT, "ms", "scoring time per hop"),
    Column("compute_budget_ms", FLOAT, "ms", "time one hop lasts"),
    Column("realtime", BOOL, "", "whether scoring keeps up with the stream"),
    Column("compute_processor", STR, "", "the processor that timed it"),
    Column("n_test_recordings", INT, "", "test recordings streamed"),
    Column("n_train_recordings", INT, "", "training recordings streamed (operating point)"),
    Column("stream_s", FLOAT, "s", "wall time spent streaming"),
)
FIT = (
    Column("train_s", FLOAT, "s", "fit time"),
    Column("train_us_per_sample", FLOAT, "us", "fit time per window sample"),
    Column("peak_mem_mb", FLOAT, "MiB", "peak resident memory above the start during the fit"),
    Column("infer_us_per_window", FLOAT, "us", "scoring time per test window"),
    Column(
        "train_balanced_accuracy",
        FLOAT,
        "fraction",
        "balanced accuracy on its own training windows",
    ),
    Column("train_balanced_accuracy_lo", FLOAT, "fraction", "its 95 % Wilson lower bound"),
    Column("train_balanced_accuracy_hi", FLOAT, "fraction", "its 95 % Wilson upper bound"),
    Column(
        "validation_balanced_accuracy",
        FLOAT,
        "fraction",
        "balanced accuracy on the validation part a detector held out (TorchDetector)",
    ),
    Column("validation_balanced_accuracy_lo", FLOAT, "fraction", "its 95 % Wilson lower bound"),
    Column("validation_balanced_accuracy_hi", FLOAT, "fraction", "its 95 % Wilson upper bound"),
    Column("fitted", STR, JSON, "what the fit chose (bands, thresholds)"),
    Column("epochs", INT, "", "epochs a network trained"),
    Column("warnings", STR, "", "warnings about the fit, '; '-separated"),
    Column(
        "unkeyed_reads", STR, JSON, "files the fit read outside its code identity: path -> digest"
    ),
)
PROVENANCE = (
    Column("dataset_fingerprint", STR, "", "content fingerprint of the dataset"),
    Column("dataset_path", STR, "", "where the dataset was read"),
    Column("train_dataset_path", STR, "", "transfer: the training dataset"),
    Column("train_dataset_fingerprint", STR, "", "transfer: its fingerprint"),
    Column("test_dataset_path", STR, "", "transfer: the test dataset"),
    Column("test_dataset_fingerprint", STR, "", "transfer: its fingerprint"),
    Column("sensor_map", STR, JSON, "transfer: training unit -> test unit"),
    Column("slipbench_version", STR, "", "slipbench's version"),
    Column("interval_method", STR, "", "the intervals' method"),
    Column("python_version", STR, "", "Python's version"),
    Column("numpy_version", STR, "", "NumPy's version"),
    Column("numba_version", STR, "", "numba's version"),
    Column("torch_version", STR, "", "torch's version ('' where not loaded)"),
    Column("platform", STR, "", "the machine's platform"),
    Column("finished_at", STR, "", "UTC time the row was made"),
)

#: the groups of columns, in the order of the docs page
GROUPS: dict[str, tuple[Column, ...]] = {
    "What was run": IDENTITY,
    "The cell": CELL,
    "Outcome and counts": OUTCOME,
    "Figures of a windowed cell": tuple(c for f in WINDOWED_FIGURES for c in f.columns()),
    "Streaming counts and checks": STREAM,
    "Figures of a streaming cell": tuple(c for f in STREAMED_FIGURES for c in f.columns()),
    "Fit": FIT,
    "Provenance": PROVENANCE,
}
COLUMNS: dict[str, Column] = {c.name: c for group in GROUPS.values() for c in group}

_ACCEPTS: dict[str, tuple[type, ...]] = {
    "string": (str,),
    "int64": (int, np.integer),
    "float64": (float, int, np.floating, np.integer),
    "bool": (bool, np.bool_),
}


def row_problems(row: dict[str, Any]) -> list[str]:
    """What in ``row`` the schema does not declare: unknown columns (other than the cell-key
    columns its ``cell`` names) and values of another type (None and NaN pass anywhere)."""
    own = set(json.loads(row["cell"])) if isinstance(row.get("cell"), str) else set()
    problems = []
    for name, value in row.items():
        column = COLUMNS.get(name)
        if column is None:
            if name not in own:
                problems.append(f"{name}: not a declared results column")
            continue
        if value is None or _is_bool(value) != (column.type == "bool"):
            if value is not None:
                problems.append(f"{name}: {value!r} is not a {column.type}")
            continue
        if not isinstance(value, _ACCEPTS[column.type]):
            problems.append(f"{name}: {value!r} is not a {column.type}")
    return problems


def _is_bool(value: Any) -> bool:
    return isinstance(value, (bool, np.bool_))


def checked(row: dict[str, Any]) -> dict[str, Any]:
    """``row`` itself, once it holds declared columns only; a TypeError names the others (a
    defect of slipbench, which makes every row)."""
    problems = row_problems(row)
    if problems:
        raise TypeError(f"a result row breaks the results schema: {'; '.join(problems)}")
    return row
