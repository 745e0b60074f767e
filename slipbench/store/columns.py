"""The results schema: every column a result row may hold, with its type, unit and meaning.

Rows are checked against it where they are made (:func:`checked`) and where the store writes
them; ``docs/reference/results-columns.md`` is written from it (``docs/tools/results_columns.py``). A
protocol's cell-key columns (``sensor_type``, ``window``, ...) are its own: a row may hold the
keys its ``cell`` column names. Adding a figure is one entry in :data:`FIGURES` (what it is, how
it reads, whether the gate reads it); its interval columns follow from the entry, and every
table, test and verdict takes its names from here (:func:`figures`), never from a list of its
own.
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from slipbench.vocabulary import SENSOR_INSTANCE, SENSOR_TYPE


@dataclass(frozen=True)
class Column:
    """One results column: its name, its Arrow type (``string``, ``int64``, ``float64``,
    ``bool``), its unit ("" where it has none), what it means, and the numbers it may hold: in
    ``bounds`` (NaN and null pass unless ``finite``: then it is a finite number wherever a row
    holds the column).

    What makes two rows two results (:func:`identity`): its ``role`` (:data:`ROLES`; "" for a
    column that tells no results apart), the fields of the cell's key it records (``keys``,
    :func:`slipbench.engine.plan.keys`; none for a setting outside the key), the column whose
    value fixes it already (``follows``: the protocol lays a cell's parts out from its key, a
    combined dataset's fingerprint holds both datasets and the sensor map) and, for a setting,
    whether it records a version of what the run read (``version``: the data, the code, the
    interval method) rather than a condition chosen for it. A ``named`` column names a result
    wherever a table, pairing or series lists results (the protocol, the detector, the split,
    the seed, the cell key); its role's other columns name one only where rows differ in them
    (:func:`slipbench.stats.factors.differing_settings`, :func:`~slipbench.stats.factors.entrant_names`)."""

    name: str
    type: str
    unit: str
    meaning: str
    bounds: tuple[float, float] = (-math.inf, math.inf)
    finite: bool = False
    role: str = ""
    keys: tuple[str, ...] = ()
    follows: str = ""
    version: bool = False
    named: bool = False

    @property
    def allowed(self) -> str:
        """The numbers it may hold, for messages and the docs ("" where any number goes)."""
        low, high = self.bounds
        within = (
            f"in [{_number(low)}, {_number(high)}]"
            if math.isfinite(low) and math.isfinite(high)
            else (f">= {_number(low)}" if math.isfinite(low) else "")
        )
        return " and ".join(p for p in ("finite" if self.finite else "", within) if p)

    def problem(self, value: Any) -> str | None:
        """What is wrong with ``value`` here, if it is a number outside what the column allows;
        None otherwise (a value of another type is the type check's)."""
        if not isinstance(value, (int, float, np.integer, np.floating)) or _is_bool(value):
            return None
        x, (low, high) = float(value), self.bounds
        if self.finite and not math.isfinite(x):
            return f"{self.name} {_number(x)} is not a finite number"
        if not (math.isnan(x) or low <= x <= high):
            return f"{self.name} {_number(x)} is not {self.allowed.removeprefix('finite and ')}"
        return None


def _number(x: float) -> str:
    """A number as a message shows it: 4294967295, 0.5, nan (never 4.29497e+09)."""
    return str(int(x)) if math.isfinite(x) and float(x).is_integer() else f"{x:.6g}"


#: the roles of a column (:attr:`Column.role`): the repeat (the one thing a figure averages over);
#: the detector that competes (its id and parameters); what it reads (input, normalization; with
#: the detector, an entrant); the conditions of the run (two values: two tables); which cell of
#: a protocol it is; a figure of the cell
SEED, ENTRANT, READING, SETTING, CELL_ROLE, FIGURE = (
    "seed",
    "entrant",
    "reading",
    "setting",
    "cell",
    "figure",
)
ROLES = (SEED, ENTRANT, READING, SETTING, CELL_ROLE, FIGURE)
#: columns code names on its own (the input a detector reads, ...), spelled once; the unit's
#: columns (``SENSOR_TYPE``) are the contract's (:mod:`slipbench.vocabulary`)
INPUT, PROTOCOL, BALANCE = "input", "protocol", "balance"
DETECTOR = "detector"

#: a figure's kind: the cells that hold it
WINDOWED, STREAMED = "windowed", "streamed"
#: the windows a rate is the share of (the correct ones among them)
EVERY_WINDOW, SLIP_WINDOWS, NONSLIP_WINDOWS = "every window", "slip windows", "non-slip windows"


@dataclass(frozen=True)
class Figure:
    """A figure of a cell with its interval: ``name``, ``name_lo``, ``name_hi`` and, with
    ``se``, ``name_se``; with ``wilson``, the window-level ``name_wilson_lo``/``_hi``; with
    ``operating``, the same at the streaming operating point (``op_`` prefixed).

    What every table, test and verdict reads of it: ``kind`` (:data:`WINDOWED` or
    :data:`STREAMED` cells hold it), ``label`` (a table's heading, the paper's word), ``called``
    (its name in a sentence), ``display`` (the unit a table shows it in) and ``decimals``,
    ``worse`` (-1: a lower value is worse, +1: a higher one), ``rate`` (the windows it is the
    share of: :data:`EVERY_WINDOW`, :data:`SLIP_WINDOWS` or :data:`NONSLIP_WINDOWS`; "" for any
    other figure) and ``tolerance`` (the gate reads it, with this default tolerance in its
    change unit; None: the gate does not read it). The tolerance is also the margin within
    which a contrast of the figure reads "no difference" (:mod:`slipbench.stats.contrast`)."""

    name: str
    unit: str
    meaning: str
    kind: str = WINDOWED
    label: str = ""
    called: str = ""
    display: str = "%"
    decimals: int = 1
    worse: int = -1
    rate: str = ""
    tolerance: float | None = None
    se: bool = False
    wilson: bool = False
    operating: bool = False
    bounds: tuple[float, float] = (-math.inf, math.inf)  # of the figure and its interval
    finite: bool = False  # the figure (not its interval) is a number wherever a row holds it

    @property
    def scale(self) -> float:
        """Stored value -> shown value: fractions are shown in percent (changes in points)."""
        return 100.0 if self.unit == "fraction" else 1.0

    @property
    def change_unit(self) -> str:
        """The unit of a change of the figure and of its tolerance."""
        return "points" if self.unit == "fraction" else self.display

    @property
    def header(self) -> str:
        """A table column's heading: ``Detection rate (%)``."""
        return f"{self.label} ({self.display})"

    @property
    def one_class(self) -> bool:
        """A rate over the windows of one class (the TP or TN rate): absent from a test set
        without that class, and no summary of a detector on its own."""
        return self.rate in (SLIP_WINDOWS, NONSLIP_WINDOWS)

    def columns(self) -> Iterator[Column]:
        within = self.bounds
        for prefix, where in [("", "")] + [("op_", " at the operating point")] * self.operating:
            name, meaning = prefix + self.name, self.meaning + where
            yield Column(name, "float64", self.unit, meaning, within, self.finite, FIGURE)
            yield Column(
                f"{name}_lo",
                "float64",
                self.unit,
                f"lower end of the 95 % interval of {name}",
                within,
            )
            yield Column(
                f"{name}_hi",
                "float64",
                self.unit,
                f"upper end of the 95 % interval of {name}",
                within,
            )
            if self.se:
                yield Column(
                    f"{name}_se",
                    "float64",
                    self.unit,
                    f"bootstrap standard error of {name}",
                    (0.0, within[1] - within[0]),
                )
            if self.wilson:
                for end in ("lo", "hi"):
                    yield Column(
                        f"{name}_wilson_{end}",
                        "float64",
                        self.unit,
                        f"window-level Wilson bound of {name} (as if windows were independent)",
                        within,
                    )


STR, INT, FLOAT, BOOL = "string", "int64", "float64", "bool"
JSON = "JSON"
FRACTION = (0.0, 1.0)  # a rate, a share, an area under a curve
AT_LEAST_0 = (0.0, math.inf)  # counts, durations, delays, rates per minute

# a windowed cell's figures (cluster bootstrap over test trials)
ACCURACY = Figure(
    "accuracy",
    "fraction",
    "share of test windows classified right",
    label="Classification Accuracy",
    called="accuracy",
    rate=EVERY_WINDOW,
    tolerance=1.0,
    se=True,
    wilson=True,
    finite=True,  # every windowed cell tests windows
    bounds=FRACTION,
)
TP_RATE = Figure(
    "tp_rate",
    "fraction",
    "share of slip windows called slip (1 - misses)",
    label="TP Rate",
    called="TP rate (misses)",
    rate=SLIP_WINDOWS,
    tolerance=1.0,
    se=True,
    wilson=True,
    bounds=FRACTION,
)
TN_RATE = Figure(
    "tn_rate",
    "fraction",
    "share of non-slip windows called non-slip (1 - false alarms)",
    label="TN Rate",
    called="TN rate (false alarms)",
    rate=NONSLIP_WINDOWS,
    tolerance=1.0,
    se=True,
    wilson=True,
    bounds=FRACTION,
)
BALANCED_ACCURACY = Figure(
    "balanced_accuracy",
    "fraction",
    "mean of the TP and TN rates",
    label="Balanced Accuracy",
    called="balanced accuracy",
    se=True,
    bounds=FRACTION,
)
AUROC = Figure(
    "auroc",
    "fraction",
    "area under the ROC curve of the scores",
    label="AUROC",
    called="AUROC",
    se=True,
    bounds=FRACTION,
)
# a streaming cell's figures (bootstrap over test trials), at the detector's threshold and at
# the operating point
DETECTION_RATE = Figure(
    "detection_rate",
    "fraction",
    "share of slip onsets detected in time",
    kind=STREAMED,
    label="Detection rate",
    called="detection rate",
    tolerance=1.0,
    operating=True,
    bounds=FRACTION,
)
MEDIAN_DELAY = Figure(
    "median_delay_ms",
    "ms",
    "median delay from onset to detection",
    kind=STREAMED,
    label="Median delay",
    called="median delay",
    display="ms",
    worse=1,
    tolerance=10.0,
    operating=True,
    bounds=AT_LEAST_0,
)
P95_DELAY = Figure(
    "p95_delay_ms",
    "ms",
    "95th percentile of the detection delay",
    kind=STREAMED,
    label="95th pct. delay",
    called="95th percentile delay",
    display="ms",
    worse=1,
    operating=True,
    bounds=AT_LEAST_0,
)
FALSE_ALARMS = Figure(
    "false_alarms_per_min",
    "1/min",
    "alarms per minute of non-slip streaming",
    kind=STREAMED,
    label="False alarms",
    called="false alarms per minute",
    display="per min",
    decimals=2,
    worse=1,
    tolerance=0.5,
    operating=True,
    bounds=AT_LEAST_0,
)
#: every figure by name, in the order tables and the gate list them
FIGURES: dict[str, Figure] = {
    f.name: f
    for f in (
        ACCURACY,
        TP_RATE,
        TN_RATE,
        BALANCED_ACCURACY,
        AUROC,
        DETECTION_RATE,
        MEDIAN_DELAY,
        P95_DELAY,
        FALSE_ALARMS,
    )
}


def figures(kind: str | None = None, *, gated: bool | None = None) -> tuple[Figure, ...]:
    """The declared figures, in order: those of ``kind`` (every kind where None) and, with
    ``gated``, those the gate reads (True) or does not (False)."""
    return tuple(
        f
        for f in FIGURES.values()
        if kind in (None, f.kind) and gated in (None, f.tolerance is not None)
    )


def names(kind: str | None = None, *, gated: bool | None = None) -> tuple[str, ...]:
    """The names of :func:`figures`."""
    return tuple(f.name for f in figures(kind, gated=gated))


@functools.cache  # a table asks it of every cell: each column's name is read once
def figure_of(column: str) -> Figure | None:
    """The figure a results or change column shows (``accuracy``, ``op_detection_rate_lo``,
    ``d_tn_rate_se``, ``base_accuracy``), or None where it shows none."""
    name = column
    for prefix in ("d_", "base_", "candidate_", "op_"):
        name = name.removeprefix(prefix)
    for suffix in ("_lo", "_hi", "_se"):
        name = name.removesuffix(suffix)
    return FIGURES.get(name)


IDENTITY = (
    Column("key", STR, "", "content address of the cell: data, code, parameters, seed"),
    Column("model_key", STR, "", "content address of the model the cell tests"),
    Column("run_id", STR, "", "UTC time stamp of the run that computed the cell"),
    Column("protocol", STR, "", "protocol id", role=CELL_ROLE, keys=("protocol",), named=True),
    Column(
        "protocol_params",
        STR,
        JSON,
        "the protocol's parameters",
        role=SETTING,
        keys=("protocol_params",),
    ),
    Column(
        "protocol_layout", STR, JSON, "what the protocol's cells are: its table's rows and columns"
    ),
    Column(
        "protocol_presentation",
        STR,
        JSON,
        "how the protocol's table and figure look ('' where it declares none)",
    ),
    Column("detector", STR, "", "detector id", role=ENTRANT, keys=("detector",), named=True),
    Column(
        "detector_params", STR, JSON, "the detector's parameters", role=ENTRANT, keys=("params",)
    ),
    Column(
        "detector_reference",
        BOOL,
        "",
        "the detector is the registered reference, the baseline tables compare against",
    ),
    Column(
        "split",
        STR,
        "",
        "how windows were split into training and test sides",
        role=SETTING,
        keys=("split", "run_split"),
        named=True,
    ),
    Column(
        "seed", INT, "", "the run's seed", (0, 2**32 - 1), role=SEED, keys=("seed",), named=True
    ),
    Column(
        "labels",
        STR,
        "",
        "how windows were labelled (scenario or samples)",
        role=SETTING,
        keys=("labels",),
    ),
    Column(
        "normalize",
        STR,
        "",
        "how recordings were scaled before windowing",
        role=READING,
        keys=("normalize",),
    ),
    Column("input", STR, "", "univariate signal or channels", role=READING, keys=("input",)),
    Column(
        "balance",
        STR,
        "",
        "how balancing kept classes equal: within each material (the paper) or across materials",
        role=SETTING,
        keys=("balance",),
    ),
    Column(
        "code_identity",
        STR,
        "",
        "digest of the code that computed the cell: slipbench's, the detector's and the "
        "protocol's source",
    ),
)
CELL = (
    Column(SENSOR_TYPE, STR, "", "cell key: the sensor type of the unit"),
    Column(SENSOR_INSTANCE, STR, "", "cell key: the finger of the unit"),
    Column(
        "window",
        INT,
        "samples",
        "window length",
        (1, math.inf),
        role=CELL_ROLE,
        keys=("window",),
        follows="cell",
    ),
    Column("window_ms", FLOAT, "ms", "window length in time at the unit's rate", AT_LEAST_0),
    Column("hop", INT, "samples", "streaming hop between two scores", (1, math.inf)),
    Column("rate_hz", FLOAT, "Hz", "cell key: the sampling rate after downsampling", AT_LEAST_0),
    Column(
        "downsample",
        INT,
        "",
        "decimation factor",
        (1, math.inf),
        role=CELL_ROLE,
        keys=("downsample",),
        follows="cell",
    ),
    Column(
        "decimation",
        STR,
        "",
        "how the signal was decimated",
        role=CELL_ROLE,
        keys=("decimation",),
    ),
    Column(
        "antialias",
        BOOL,
        "",
        "whether a low-pass filter preceded decimation",
        role=CELL_ROLE,
        keys=("antialias",),
    ),
    Column("cell", STR, JSON, "the cell's key, whole", role=CELL_ROLE, keys=("cell",), named=True),
    *(
        Column(
            f"{side}_{part}",
            STR,
            JSON,
            f"{what} of the {name} side",
            role=CELL_ROLE,
            keys=(side,),
            follows="cell",
        )
        for side, name in (("train", "training"), ("test", "test"))
        for part, what in (("sensors", "units"), ("where", "filters"))
    ),
    Column(
        "test_stream",
        STR,
        JSON,
        "streaming settings of the test ('' for windows)",
        role=CELL_ROLE,
        keys=("stream",),
    ),
    Column("train_slip_windows", INT, "windows", "slip windows on the training side", AT_LEAST_0),
    Column(
        "train_nonslip_windows", INT, "windows", "non-slip windows on the training side", AT_LEAST_0
    ),
    Column("test_slip_windows", INT, "windows", "slip windows on the test side", AT_LEAST_0),
    Column("test_nonslip_windows", INT, "windows", "non-slip windows on the test side", AT_LEAST_0),
    *(
        Column(
            f"{side}_{cls}_available",
            INT,
            "windows",
            f"{name} windows the {side} side could hold before balancing (its units and "
            "conditions; the paper split, which halves the balanced windows, counts half)",
            AT_LEAST_0,
        )
        for side in ("train", "test")
        for cls, name in (("slip", "slip"), ("nonslip", "non-slip"))
    ),
    Column(
        "balance_warning",
        STR,
        "",
        "where balancing kept under half of a class's windows: how many, why, and what keeps more",
    ),
    Column(
        "normalize_scale_train", FLOAT, "", "median scale the training recordings were divided by"
    ),
    Column("normalize_scale_test", FLOAT, "", "median scale the test recordings were divided by"),
)
OUTCOME = (
    Column("status", STR, "", "ok, skipped, failed or timeout"),
    Column("reason", STR, "", "why a cell was skipped or failed, or a note on a one-class test"),
    Column("n_train", INT, "windows", "training windows", AT_LEAST_0),
    Column("n_test", INT, "windows", "test windows", AT_LEAST_0),
    Column("n_test_trials", INT, "trials", "test trials (the bootstrap's clusters)", AT_LEAST_0),
    Column("sampling_rate_hz", FLOAT, "Hz", "sampling rate the detector saw", AT_LEAST_0, True),
    Column("tp", INT, "windows", "slip windows called slip", AT_LEAST_0),
    Column("tn", INT, "windows", "non-slip windows called non-slip", AT_LEAST_0),
    Column("fp", INT, "windows", "non-slip windows called slip", AT_LEAST_0),
    Column("fn", INT, "windows", "slip windows called non-slip", AT_LEAST_0),
    Column("df", FLOAT, "", "degrees of freedom of the intervals", AT_LEAST_0),
    Column("ci_note", STR, "", "why an interval is missing or wide"),
    Column("n_test_clusters_slip", INT, "trials", "test trials holding slip windows", AT_LEAST_0),
    Column(
        "n_test_clusters_nonslip", INT, "trials", "test trials holding non-slip windows", AT_LEAST_0
    ),
    Column("low_n", BOOL, "", "a class rests on fewer trials than LOW_N: read as inconclusive"),
    Column(
        "constant_slip_accuracy",
        FLOAT,
        "fraction",
        "accuracy of always saying slip (one-class tests)",
        FRACTION,
    ),
)
STREAM = (
    Column("n_trials", INT, "trials", "test trials streamed", AT_LEAST_0),
    Column("n_onset_trials", INT, "trials", "test trials with a slip onset", AT_LEAST_0),
    Column("n_nonslip_trials", INT, "trials", "test trials without slip", AT_LEAST_0),
    Column("n_onsets", INT, "", "slip onsets in the test streams", AT_LEAST_0),
    Column("n_detected", INT, "", "onsets detected in time", AT_LEAST_0),
    Column("n_missed", INT, "", "onsets not detected in time", AT_LEAST_0),
    Column("n_censored", INT, "", "onsets too near a recording's end to judge", AT_LEAST_0),
    Column("n_at_start", INT, "", "recordings that start in slip (no onset)", AT_LEAST_0),
    Column("false_alarms", INT, "", "alarms during non-slip streaming", AT_LEAST_0),
    Column("nonslip_minutes", FLOAT, "min", "minutes of non-slip streaming", AT_LEAST_0),
    Column("threshold", FLOAT, "", "the detector's own threshold"),
    Column("false_alarms_by_scenario", STR, JSON, "false alarms per scenario"),
    Column("op_threshold", FLOAT, "", "threshold of the operating point (training streams)"),
    Column(
        "op_budget_per_min", FLOAT, "1/min", "false-alarm budget of the operating point", AT_LEAST_0
    ),
    Column("op_note", STR, "", "why there is no operating point"),
    Column("tradeoff", STR, JSON, "threshold sweep of the test streams"),
    Column("compute_ms_per_hop", FLOAT, "ms", "scoring time per hop", AT_LEAST_0),
    Column("compute_budget_ms", FLOAT, "ms", "time one hop lasts", AT_LEAST_0),
    Column("realtime", BOOL, "", "whether scoring keeps up with the stream"),
    Column("compute_processor", STR, "", "the processor that timed it"),
    Column("n_test_recordings", INT, "", "test recordings streamed", AT_LEAST_0),
    Column(
        "n_train_recordings", INT, "", "training recordings streamed (operating point)", AT_LEAST_0
    ),
    Column("stream_s", FLOAT, "s", "wall time spent streaming", AT_LEAST_0),
)
FIT = (
    Column("train_s", FLOAT, "s", "fit time", AT_LEAST_0),
    Column("train_us_per_sample", FLOAT, "us", "fit time per window sample", AT_LEAST_0),
    Column("peak_mem_mb", FLOAT, "MiB", "peak resident memory above the start during the fit"),
    Column("infer_us_per_window", FLOAT, "us", "scoring time per test window", AT_LEAST_0),
    Column("test_s", FLOAT, "s", "test time: scoring, figures and their intervals", AT_LEAST_0),
    Column(
        "train_balanced_accuracy",
        FLOAT,
        "fraction",
        "balanced accuracy on its own training windows",
        FRACTION,
    ),
    Column(
        "train_balanced_accuracy_lo", FLOAT, "fraction", "its 95 % Wilson lower bound", FRACTION
    ),
    Column(
        "train_balanced_accuracy_hi", FLOAT, "fraction", "its 95 % Wilson upper bound", FRACTION
    ),
    Column(
        "validation_balanced_accuracy",
        FLOAT,
        "fraction",
        "balanced accuracy on the validation part a detector held out (TorchDetector)",
        FRACTION,
    ),
    Column(
        "validation_balanced_accuracy_lo",
        FLOAT,
        "fraction",
        "its 95 % Wilson lower bound",
        FRACTION,
    ),
    Column(
        "validation_balanced_accuracy_hi",
        FLOAT,
        "fraction",
        "its 95 % Wilson upper bound",
        FRACTION,
    ),
    Column(
        "fitted",
        STR,
        JSON,
        "what the fit chose (bands, thresholds); 'overrides': parameters it ran otherwise than asked",
    ),
    Column("epochs", INT, "", "epochs a network trained", AT_LEAST_0),
    Column("warnings", STR, "", "warnings about the fit, '; '-separated"),
    Column(
        "unkeyed_reads", STR, JSON, "files the fit read outside its code identity: path -> digest"
    ),
)
PROVENANCE = (
    Column(
        "dataset_fingerprint",
        STR,
        "",
        "content fingerprint of the dataset",
        role=SETTING,
        keys=("dataset",),
        version=True,
    ),
    Column("dataset_path", STR, "", "where the dataset was read"),
    Column("train_dataset_path", STR, "", "transfer: the training dataset"),
    Column(
        "train_dataset_fingerprint",
        STR,
        "",
        "transfer: its fingerprint",
        role=SETTING,
        keys=("dataset",),
        follows="dataset_fingerprint",
        version=True,
    ),
    Column("test_dataset_path", STR, "", "transfer: the test dataset"),
    Column(
        "test_dataset_fingerprint",
        STR,
        "",
        "transfer: its fingerprint",
        role=SETTING,
        keys=("dataset",),
        follows="dataset_fingerprint",
        version=True,
    ),
    Column(
        "sensor_map",
        STR,
        JSON,
        "transfer: training unit -> test unit",
        role=SETTING,
        keys=("dataset",),
        follows="dataset_fingerprint",
    ),
    # not key fields, yet they change what a row's figures or intervals are
    Column("interval_method", STR, "", "the intervals' method", role=SETTING, version=True),
    Column("slipbench_version", STR, "", "slipbench's version", role=SETTING, version=True),
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
    "Figures of a windowed cell": tuple(c for f in figures(WINDOWED) for c in f.columns()),
    "Streaming counts and checks": STREAM,
    "Figures of a streaming cell": tuple(c for f in figures(STREAMED) for c in f.columns()),
    "Fit": FIT,
    "Provenance": PROVENANCE,
}
COLUMNS: dict[str, Column] = {c.name: c for group in GROUPS.values() for c in group}


def identity(
    *roles: str,
    keyed: bool | None = None,
    follows: bool | None = None,
    version: bool | None = None,
    named: bool | None = None,
    but: tuple[str, ...] = (),
) -> tuple[str, ...]:
    """The names of the columns of ``roles`` (:data:`ROLES`), in the schema's order: with
    ``keyed``, those recording a field of the cell's key (True) or none (False); with
    ``follows``, those another column fixes already (True) or not (False); with ``version``,
    those recording a version of what the run read (True) or not (False); with ``named``, those
    naming a result wherever results are listed (True) or only where rows differ in them
    (False); never those of ``but``. Every list of identity or setting columns is one of these
    queries."""
    unknown = set(roles) - set(ROLES)
    if unknown:
        raise ValueError(f"not a column role: {sorted(unknown)} (roles: {', '.join(ROLES)})")
    return tuple(
        c.name
        for c in COLUMNS.values()
        if c.role in roles
        and keyed in (None, bool(c.keys))
        and follows in (None, bool(c.follows))
        and version in (None, c.version)
        and named in (None, c.named)
        and c.name not in but
    )


#: a result but its seed, as tables group it: the protocol, the detector, the cell
ENTRANT_CELL = identity(ENTRANT, CELL_ROLE, named=True)


def recording(*keys: str) -> tuple[str, ...]:
    """The names of the columns recording the fields ``keys`` of the cell's key, in the order
    of ``keys`` (``recording("test", "stream")``: what a cell's test set is); a ValueError
    names a field no column records."""
    found = key_columns()
    unknown = [k for k in keys if k not in found]
    if unknown:
        raise ValueError(f"no results column records the key field(s) {unknown}")
    return tuple(c for k in keys for c in found[k][1])


def key_columns() -> dict[str, tuple[str, tuple[str, ...]]]:
    """Each field of the cell's key the rows record -> (its role, the columns recording it),
    in the schema's order."""
    out: dict[str, tuple[str, tuple[str, ...]]] = {}
    for c in COLUMNS.values():
        for key in c.keys:
            role, names = out.get(key, (c.role, ()))
            out[key] = (role, (*names, c.name))
    return out


_ACCEPTS: dict[str, tuple[type, ...]] = {
    "string": (str,),
    "int64": (int, np.integer),
    "float64": (float, int, np.floating, np.integer),
    "bool": (bool, np.bool_),
}


def _shown(value: Any) -> str:
    """A parameter's value as a reader reads it: numbers in %g, lists in brackets."""
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_shown(v) for v in value) + "]"
    if isinstance(value, float):
        return f"{value:.3g}"
    return "null" if value is None else str(value)


def overridden(name: str, ran: Any, asked: Any, why: str) -> str:
    """A parameter that ran with another value than the one asked, as rows and reports say
    it: ``band=[0.6, 2.16] (asked [50, 400]: above Nyquist 2.4 Hz)``."""
    return f"{name}={_shown(ran)} (asked {_shown(asked)}: {why})"


def row_problems(row: dict[str, Any]) -> list[str]:
    """What in ``row`` the schema does not declare: unknown columns (other than the cell-key
    columns its ``cell`` names), values of another type (None passes anywhere) and numbers
    outside what their column allows (:func:`out_of_range`)."""
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
    return problems + out_of_range(row)


def out_of_range(row: dict[str, Any]) -> list[str]:
    """The numbers of ``row`` outside what their column allows (a rate in [0, 1], a count
    >= 0, finite where the column says so): ``"accuracy 5 is not in [0, 1]"``."""
    found = (COLUMNS[name].problem(value) for name, value in row.items() if name in COLUMNS)
    return [problem for problem in found if problem]


def _is_bool(value: Any) -> bool:
    return isinstance(value, (bool, np.bool_))


def checked(row: dict[str, Any]) -> dict[str, Any]:
    """``row`` itself, once it holds declared columns only; a TypeError names the others (a
    defect of slipbench, which makes every row)."""
    problems = row_problems(row)
    if problems:
        raise TypeError(f"a result row breaks the results schema: {'; '.join(problems)}")
    return row
