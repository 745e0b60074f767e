"""The protocol contract: BaseProtocol, the cells it yields, and how its table reads and looks.

A protocol is a standardized experiment built from the dataset's metadata alone: a list of
:class:`Cell` objects, each naming the windows that train a model and the windows that test it.
Protocols never train anything (the runner does) and never see samples. Each declares a
:class:`Layout` (what its cells are: a table's rows, columns, pairs) and may declare a
:class:`Presentation` (how its table and figure look: captions, titles, the figure's kind).
Every result row records both (:func:`as_record`): the report reads them from the rows, for
built-in and plugin protocols alike.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, TypeVar

import numpy as np
import pandas as pd

from slipbench.params import Parameterized, WindowLength, window_samples
from slipbench.vocabulary import DATASET_SIDE, MAX_WINDOW, MIN_WINDOW, SENSOR_TYPE, sensor_pairs

__all__ = [
    "BaseProtocol",
    "Cell",
    "HoldoutProtocol",
    "Layout",
    "Part",
    "Presentation",
    "NO_CELL",
    "as_record",
    "described",
    "from_record",
    "holdout_cells",
    "no_cell",
    "sensor_pairs",
    "unit_rate",
    "window_cells",
]

SIDES = ("train", "test")
OPERATORS = ("==", "!=")
DECIMATIONS = ("plain", "lag")
FIGURE_KINDS = ("curve", "with-without", "matrix", "tradeoff")
STREAM_KEYS = ("hop", "max_delay_ms")
# The key of the stand-in cell a run records for a protocol that makes no cell on a dataset
# (:func:`no_cell`); reports and checks find such rows by it.
NO_CELL_KEY = {"cells": "none"}
NO_CELL = json.dumps(NO_CELL_KEY, sort_keys=True)  # the rows' ``cell`` column


@dataclass(frozen=True)
class Part:
    """Windows that train or test a cell.

    Attributes
    ----------
    sensors : the (sensor_type, sensor_instance) pairs whose windows are pooled.
    side : "train" or "test": which half of each sensor's balanced split.
    where : filters on recording columns, ``(column, "==" or "!=", value)`` triples, all of
        which a window's recording must meet.
    """

    sensors: tuple[tuple[str, str], ...]
    side: str
    where: tuple[tuple[str, str, Any], ...] = ()

    def __post_init__(self) -> None:
        if self.side not in SIDES:
            raise ValueError(f"Part.side must be one of {SIDES}, got {self.side!r}")
        if not self.sensors or not all(isinstance(s, tuple) and len(s) == 2 for s in self.sensors):
            raise ValueError(
                f"Part.sensors must be a non-empty tuple of (sensor_type, instance) pairs, got {self.sensors!r}"
            )
        for condition in self.where:
            if len(condition) != 3 or condition[1] not in OPERATORS:
                raise ValueError(
                    f"Part.where holds (column, operator, value) triples with operator one of "
                    f"{OPERATORS}; got {condition!r}"
                )

    def mask(self, recordings: pd.DataFrame) -> np.ndarray:
        """(n_recordings,) bool: recordings of these sensors that meet every condition."""
        # compared as arrays: a MultiIndex built per call took 30 ms, most of planning a run
        types = recordings[SENSOR_TYPE].to_numpy()
        instances = recordings["sensor_instance"].to_numpy()
        keep = np.zeros(len(recordings), bool)
        for sensor_type, instance in self.sensors:
            keep |= (types == sensor_type) & (instances == instance)
        for column, op, value in self.where:
            equal = recordings[column].eq(value).to_numpy()
            keep &= equal if op == "==" else ~equal
        return np.asarray(keep, bool)


@dataclass(frozen=True)
class Cell:
    """One entry of a protocol's table: what trains, what tests, at which window and rate.

    Attributes
    ----------
    key : names the cell in results and tables (e.g. sensor, instance, window); plain JSON
        values (str, int, float, bool).
    train, test : the windows that fit the model and the windows it is scored on.
    window : window length in samples at the full rate.
    downsample : the window as a sensor ``downsample`` times slower sees it (1: full rate).
    decimation : how the slower sensor's samples are made (see ``Windows.downsample``):
        "plain" (every k-th sample of the full-rate difference) or "lag" (the difference
        ||a_t|| - ||a_{t-k}|| on every k-th sample).
    antialias : low-pass the norm before decimating (see ``Signals.antialiased``).
    stream : None (test on the ``test`` windows), or ``{"hop": samples, "max_delay_ms": ms}``:
        test by streaming whole recordings through the model, a score every ``hop`` samples
        (1 <= hop <= window), an onset missed when no alarm comes within ``max_delay_ms``. The
        ``test`` part then names the recordings streamed (those of its units that meet its
        conditions, carry per-sample labels and lie on the test side of a split by whole
        trials); training windows come from the training side of that split, whatever the run's.
        Only at the full rate (``downsample`` 1).
    skip : a reason the cell cannot run on this dataset, reported instead of results.
    holdout : None, or ``(column, value)`` for a cell of a "with and without" pair on that
        value (:func:`holdout_cells`): the planner skips the cell, with the reason, when the
        training side of its units holds no window of that value, since the models with and
        without it are then the same model (across datasets, say, a material only the test
        dataset has). Not part of the cell's keys.
    """

    key: dict[str, Any]
    train: Part
    test: Part
    window: int
    downsample: int = 1
    decimation: str = "plain"
    antialias: bool = False
    stream: dict[str, Any] | None = None
    skip: str = ""
    holdout: tuple[str, Any] | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.key, dict) or not self.key:
            raise ValueError(f"Cell.key must be a non-empty dict, got {self.key!r}")
        # NumPy scalars become Python values, so keys and messages never hold reprs like np.float64(25.0)
        object.__setattr__(
            self,
            "key",
            {k: v.item() if isinstance(v, np.generic) else v for k, v in self.key.items()},
        )
        for k, v in self.key.items():
            if not isinstance(k, str) or type(v) not in (str, int, float, bool):
                raise ValueError(
                    f"Cell.key maps names to plain str/int/float/bool values; {k!r}: {v!r} is not"
                )
        if not (isinstance(self.train, Part) and isinstance(self.test, Part)):
            raise ValueError("Cell.train and Cell.test must be Part objects")
        if self.train.side != "train" or self.test.side != "test":
            raise ValueError(
                f"a cell trains on the train side and tests on the test side; got train={self.train.side!r}, "
                f"test={self.test.side!r}"
            )
        for name in ("window", "downsample"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"Cell.{name} must be a positive int, got {value!r}")
        if self.decimation not in DECIMATIONS:
            raise ValueError(
                f"Cell.decimation must be one of {DECIMATIONS}, got {self.decimation!r}"
            )
        if not isinstance(self.antialias, (bool, np.bool_)):
            raise ValueError(f"Cell.antialias must be a bool, got {self.antialias!r}")
        if self.stream is not None:
            self._check_stream()
        if self.holdout is not None and not (
            isinstance(self.holdout, tuple)
            and len(self.holdout) == 2
            and isinstance(self.holdout[0], str)
        ):
            raise ValueError(f"Cell.holdout must be None or (column, value), got {self.holdout!r}")

    def _check_stream(self) -> None:
        if not isinstance(self.stream, dict) or set(self.stream) != set(STREAM_KEYS):
            raise ValueError(
                f"Cell.stream must be None or a dict with keys {STREAM_KEYS}, got {self.stream!r}"
            )
        hop, max_delay = self.stream["hop"], self.stream["max_delay_ms"]
        if (
            isinstance(hop, bool)
            or not isinstance(hop, (int, np.integer))
            or not 1 <= hop <= self.window
        ):
            raise ValueError(
                f"Cell.stream['hop'] must be an int in [1, window = {self.window}], got {hop!r}"
            )
        if (
            isinstance(max_delay, bool)
            or not isinstance(max_delay, (int, float))
            or not 0 < max_delay < float("inf")
        ):
            raise ValueError(
                f"Cell.stream['max_delay_ms'] must be a positive number, got {max_delay!r}"
            )
        if self.downsample != 1:
            raise ValueError(
                f"a streaming cell runs at the full rate (downsample 1), got downsample {self.downsample}"
            )
        object.__setattr__(self, "stream", {"hop": int(hop), "max_delay_ms": float(max_delay)})

    @property
    def name(self) -> str:
        """The key as canonical JSON: how results name the cell."""
        return json.dumps(self.key, sort_keys=True)


@dataclass(frozen=True)
class Layout:
    """What a protocol's cells are, as its table reads them (how they look is its
    :class:`Presentation`).

    Attributes
    ----------
    rows : cell-key columns that label the table's rows, outermost first.
    column : the cell-key column whose values make the value columns.
    pair : a cell-key column with values "with" and "without": each table cell shows both
        results, the second starred (the paper's "without explicit training").
    split : a cell-key column, or a tuple of them: one table per value (combination).
    metrics : result columns shown as the value columns, one each, instead of one column per
        value of ``column`` (which then has one value per row; the streaming protocol's detection
        rate, delays and false alarms). Empty: the usual table of one metric.
    """

    rows: tuple[str, ...]
    column: str
    pair: str | None = None
    split: str | tuple[str, ...] | None = None
    metrics: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if (
            not isinstance(self.rows, tuple)
            or not self.rows
            or not all(isinstance(r, str) for r in self.rows)
        ):
            raise ValueError(
                f"Layout.rows must be a non-empty tuple of column names, got {self.rows!r}"
            )
        if not isinstance(self.column, str) or not self.column:
            raise ValueError("Layout.column must name the cell-key column of the value columns")
        split = (self.split,) if isinstance(self.split, str) else self.split
        if split is not None and not (
            isinstance(split, tuple) and split and all(isinstance(c, str) for c in split)
        ):
            raise ValueError(
                f"Layout.split must be None, a column name or a non-empty tuple of them, got {self.split!r}"
            )
        if not isinstance(self.metrics, tuple) or not all(isinstance(m, str) for m in self.metrics):
            raise ValueError(
                f"Layout.metrics must be a tuple of result column names, got {self.metrics!r}"
            )

    @property
    def keys(self) -> list[str]:
        """Every cell-key column the layout reads."""
        return [*self.rows, self.column, *([self.pair] if self.pair else []), *self.splits]

    @property
    def splits(self) -> list[str]:
        """The ``split`` columns as a list (none, one or several)."""
        return (
            []
            if not self.split
            else [self.split]
            if isinstance(self.split, str)
            else list(self.split)
        )


@dataclass(frozen=True)
class Presentation:
    """How a protocol's table and figure look (what its cells are is its :class:`Layout`).
    Every field is optional; a protocol without a presentation is captioned "Protocol {id}.".

    Attributes
    ----------
    caption : the table's caption. A result column named in braces ("window {window}") is
        replaced by the values the table's rows hold there; ``{sensors}`` by what units they
        are ("three types of sensors and fingers", "the fingers of one sensor type (BioTac SP)").
    title : a short name for headings and figure titles (default: the protocol's id).
    group : text after the metric's name over the value columns ("at Window Size").
    merge_rows : one row-label column ("Nano17, Index") instead of one per row key.
    column_label : a result column whose values, per sensor type, label the value columns
        (the paper's per-sensor sampling rates over Table II).
    note_column : a result column whose values, per sensor type and value column, a note
        under the table lists (a window's length in the other unit).
    figure : "curve" (the figure against ``x``), "with-without" (heatmaps with and without
        the layout's ``pair``), "matrix" (rows by columns heatmap per sensor type), "tradeoff"
        (detection against false alarms over a threshold sweep), or None.
    x, x_label, log_base : a curve's x column (default: the layout's ``column``), its axis label
        with the unit, and its log scale base (0: linear).
    paper_table : the name of the published table with the same cells (``--paper``).
    """

    caption: str = ""
    title: str = ""
    group: str = ""
    merge_rows: bool = False
    column_label: str | None = None
    note_column: str | None = None
    figure: str | None = None
    x: str | None = None
    x_label: str = ""
    log_base: int = 0
    paper_table: str | None = None

    def __post_init__(self) -> None:
        for name in ("caption", "title", "group", "x_label"):
            if not isinstance(getattr(self, name), str):
                raise ValueError(f"Presentation.{name} must be a str, got {getattr(self, name)!r}")
        if self.figure is not None and self.figure not in FIGURE_KINDS:
            raise ValueError(
                f"Presentation.figure must be one of {FIGURE_KINDS} or None, got {self.figure!r}"
            )
        if self.log_base not in (0, 2, 10):
            raise ValueError(
                f"Presentation.log_base must be 0 (linear), 2 or 10, got {self.log_base!r}"
            )


_Record = TypeVar("_Record", Layout, Presentation)


def as_record(value: Layout | Presentation) -> str:
    """A layout or presentation as the JSON its protocol's result rows record
    (``protocol_layout``, ``protocol_presentation``): what a report reads."""
    return json.dumps(dataclasses.asdict(value), sort_keys=True)


def from_record(cls: type[_Record], text: str) -> _Record:
    """The layout or presentation (``cls``) a result row records (:func:`as_record`); the keys
    ``cls`` does not know are left out (a newer slipbench's), a list is a tuple again. A
    ValueError says what does not fit."""
    try:
        given = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"not JSON ({exc})") from None
    if not isinstance(given, dict):
        raise ValueError(f"not a JSON object: {text[:80]!r}")
    known = {f.name for f in dataclasses.fields(cls)}
    fields: dict[str, Any] = {
        k: tuple(v) if isinstance(v, list) else v for k, v in given.items() if k in known
    }
    try:
        return cls(**fields)
    except TypeError as exc:  # a required field missing
        raise ValueError(str(exc)) from None


class BaseProtocol(Parameterized):
    """A standardized experiment: cells from the dataset's metadata alone.

    Subclasses declare ``layout`` (a :class:`Layout`) and optionally ``presentation`` (a
    :class:`Presentation`), options as keyword arguments of ``__init__`` with
    ``_parameter_constraints`` (as detectors do), and implement :meth:`cells`. The registry
    gives each protocol class its id (``name``). Like a detector,
    it may declare ``requires`` (modules slipbench does not install; ``slipbench list``
    reports the absent ones) with ``install_hint``, and ``data_files`` (files it reads, part of
    its code identity).
    """

    name: ClassVar[str] = ""
    requires: ClassVar[tuple[str, ...]] = ()
    install_hint: ClassVar[str | None] = None
    data_files: ClassVar[tuple[str, ...]] = ()
    if TYPE_CHECKING:
        # read on an instance only: a class attribute, or a property where they depend on the
        # options (window_size's unit)
        @property
        def layout(self) -> Layout | None: ...
        @property
        def presentation(self) -> Presentation | None: ...
    else:
        layout = presentation = None
    _parameter_constraints: ClassVar[dict[str, Any]] = {}

    def cells(self, recordings: pd.DataFrame) -> Iterable[Cell]:
        """The protocol's cells.

        Parameters
        ----------
        recordings : the dataset's metadata, one row per recording (columns as in
            ``datasets.md``: recording_id, sensor_type, sensor_instance, scenario, material,
            speed_mm_s, sampling_rate_hz, ..., plus the columns :meth:`columns` adds).
        """
        raise NotImplementedError

    def columns(self, recordings: pd.DataFrame) -> dict[str, np.ndarray]:
        """Extra per-recording columns (name -> (n_recordings,) array) that this protocol's
        ``where`` filters refer to."""
        return {}

    def why_no_cells(self, recordings: pd.DataFrame) -> str:
        """Why :meth:`cells` yields nothing on these recordings (asked only then): what the data
        lack, in a few words, for the skipped stand-in row the run records instead."""
        scenarios = ", ".join(sorted(set(recordings["scenario"].astype(str))))
        return f"no cell fits these recordings (scenarios: {scenarios})"


def described(protocol: BaseProtocol) -> dict[str, str]:
    """What every result row of ``protocol`` records of how its table reads and looks:
    ``protocol_layout`` and ``protocol_presentation`` as JSON (:func:`as_record`; "" for what
    it does not declare)."""
    layout, presentation = protocol.layout, protocol.presentation
    return {
        "protocol_layout": as_record(layout) if isinstance(layout, Layout) else "",
        "protocol_presentation": as_record(presentation)
        if isinstance(presentation, Presentation)
        else "",
    }


def no_cell(name: str, why: str, recordings: pd.DataFrame) -> Cell:
    """A skipped stand-in for protocol ``name`` that makes no cell on ``recordings``, so a run
    records why instead of stopping (key :data:`NO_CELL_KEY`, the first recording's unit)."""
    unit = tuple(recordings[[SENSOR_TYPE, "sensor_instance"]].iloc[0])
    part = Part((unit,), "train")
    return Cell(
        dict(NO_CELL_KEY),
        part,
        Part(part.sensors, "test"),
        1,
        skip=f"protocol {name!r} makes no cell on this dataset: {why}",
    )


def holdout_cells(
    recordings: pd.DataFrame,
    name: str,
    levels: Iterable[Any],
    window: int | str,
    test_column: str | None = None,
) -> Iterator[Cell]:
    """Cells "with" and "without" explicit training on each level of column ``name``, per sensor.

    Test windows are those whose ``test_column`` (default: ``name``) equals the level; the
    "with" model trains on every training window, the "without" model on those whose ``name``
    differs from the level. The cell key holds sensor_type, sensor_instance, ``name`` and
    ``training`` ("with" or "without"); ``window`` is in samples or milliseconds ("50ms").
    Each cell carries ``holdout=(name, level)``: where the training side holds no window of the
    level, the planner skips the pair (the two models are one). Across two datasets (a
    ``dataset_side`` column), a unit's levels are those its test side has (in ``name`` and in
    ``test_column``): a level only the training dataset has has nothing to test, and is no
    column of the table.
    """
    column = test_column or name
    levels = [v.item() if isinstance(v, np.generic) else v for v in levels]
    for sensor in sensor_pairs(recordings):
        ((n, _, skip),) = window_cells(recordings, sensor, window)
        tested = levels
        if DATASET_SIDE in recordings and column in recordings:
            rows = recordings[
                (recordings[SENSOR_TYPE] == sensor[0])
                & (recordings["sensor_instance"] == sensor[1])
                & (recordings[DATASET_SIDE] == "test")
            ]
            tested = [v for v in levels if rows[name].eq(v).any() and rows[column].eq(v).any()]
        for level in tested:
            test = Part((sensor,), "test", ((column, "==", level),))
            key = {SENSOR_TYPE: sensor[0], "sensor_instance": sensor[1], name: level}
            held = (name, level)
            yield Cell(
                {**key, "training": "with"},
                Part((sensor,), "train"),
                test,
                n,
                skip=skip,
                holdout=held,
            )
            yield Cell(
                {**key, "training": "without"},
                Part((sensor,), "train", ((name, "!=", level),)),
                test,
                n,
                skip=skip,
                holdout=held,
            )


class HoldoutProtocol(BaseProtocol):
    """Each level of one recording column with and without explicit training on it, per unit,
    at one window (the paper's Tables III and IV; cells from :func:`holdout_cells`).

    Subclasses declare ``layout``, ``holdout_column`` (the column whose levels are held out),
    optionally ``test_column`` (the column that picks a level's test windows; default
    ``holdout_column``), and implement :meth:`levels`.
    """

    holdout_column: ClassVar[str] = ""
    test_column: ClassVar[str | None] = None
    _parameter_constraints = {"window": WindowLength()}

    def __init__(self, window=50):
        self.window = window

    def levels(self, recordings: pd.DataFrame) -> list[Any]:
        """The levels of ``holdout_column`` to hold out, in the order the table shows them."""
        raise NotImplementedError

    def why_no_cells(self, recordings: pd.DataFrame) -> str:
        column = self.holdout_column
        if column not in recordings or recordings[column].isna().all():
            return f"no recording gives a {column}: there is nothing to hold out"
        return super().why_no_cells(recordings)

    def cells(self, recordings: pd.DataFrame) -> Iterator[Cell]:
        # the test column may be one this protocol adds (speed-holdout's speed_group)
        added = {k: v for k, v in self.columns(recordings).items() if k not in recordings}
        return holdout_cells(
            recordings.assign(**added) if added else recordings,
            self.holdout_column,
            self.levels(recordings),
            self.window,
            test_column=self.test_column,
        )


def unit_rate(recordings: pd.DataFrame, sensor: tuple[str, str]) -> float:
    """The sampling rate (Hz) of one unit: its recordings' pooled rate (``unit_rate_hz``, the
    median of rates within tolerance) where the dataset gives it, else their median."""
    rows = recordings[
        (recordings[SENSOR_TYPE] == sensor[0]) & (recordings["sensor_instance"] == sensor[1])
    ]
    column = "unit_rate_hz" if "unit_rate_hz" in rows else "sampling_rate_hz"
    return float(np.median(rows[column].to_numpy(dtype=float)))


def window_cells(
    recordings: pd.DataFrame, sensor: tuple[str, str], windows: int | str | Iterable[int | str]
) -> Iterator[tuple[int, dict[str, Any], str]]:
    """Each window of ``windows`` (samples, or milliseconds as "50ms") for one unit: its length in
    samples at the unit's rate, the cell-key items ``window`` (samples) and ``window_ms``, and a
    skip reason when it is shorter than MIN_WINDOW samples or longer than MAX_WINDOW."""
    rate = unit_rate(recordings, sensor)
    for window in [windows] if isinstance(windows, (int, str)) else windows:
        n = window_samples(window, rate)
        ms = float(window[:-2]) if isinstance(window, str) else round(1000.0 * n / rate, 1)
        skip = ""
        if not MIN_WINDOW <= n <= MAX_WINDOW:
            bound = f"at least {MIN_WINDOW}" if n < MIN_WINDOW else f"at most {MAX_WINDOW}"
            skip = f"{window} is {n} samples at {rate:g} Hz; a window needs {bound} samples"
        yield max(n, 1), {"window": n, "window_ms": ms}, skip
