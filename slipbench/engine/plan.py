"""Planning a run: every cell of every protocol, its windows, its keys and whether it can run,
computed once before anything trains.

Cells that train on exactly the same windows share one model: they are grouped into a
:class:`Task` that fits once and tests every cell of the group. A cell that cannot run on this
dataset (a window longer than every recording, a split side without one class) is planned as
skipped with its reason; it never stops the others.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from slipbench.base import BaseDetector
from slipbench.data.signals import LABELLINGS, SPLITS, Signals, Windows, balance, split, trial_sides
from slipbench.data.transfer import SIDE_COLUMN
from slipbench.engine.registry import detectors, protocols
from slipbench.errors import PluginError, UsageError
from slipbench.protocol import BaseProtocol, Cell, Part, no_cell
from slipbench.seeding import STREAM_SCHEME, rng_for
from slipbench.store.keys import canonical, cell_key, code_identity
from slipbench.stream.metrics import onsets

# a recordings column the runner adds: True where the dataset gives the recording per-sample
# slip labels (elsewhere Signals labels samples by scenario, which has no onset to time)
LABELLED = "has_slip_labels"


def stream_split(how: str) -> str:
    """The split a streaming cell trains and tests by: whole trials ("grouped"), whatever the
    run's split, since a stream is a whole recording and its trial twins must not train the
    model; across datasets, the datasets themselves."""
    return "datasets" if how == "datasets" else "grouped"


@dataclass
class Run:
    """One detector on one protocol, with a split, a seed and a way to label windows.

    ``detector`` and ``protocol`` are objects or ids (``"holweg"``, ``"window-size"``); an id
    is looked up in the registry, an object's id is the name its class is registered under.
    ``labels``: one of :data:`slipbench.data.signals.LABELLINGS`.
    """

    detector: BaseDetector | str
    protocol: BaseProtocol | str
    split: str = "paper"
    seed: int = 0
    labels: str = "scenario"
    detector_name: str = field(init=False)
    protocol_name: str = field(init=False)

    def __post_init__(self) -> None:
        if isinstance(self.detector, str):
            self.detector_name, self.detector = self.detector, detectors.get(self.detector)()
        else:
            self.detector_name = detectors.id_of(type(self.detector))
        if isinstance(self.protocol, str):
            self.protocol_name, self.protocol = self.protocol, protocols.get(self.protocol)()
        else:
            self.protocol_name = protocols.id_of(type(self.protocol))
        if self.split not in SPLITS:
            raise UsageError(f"unknown split {self.split!r}; choose one of: {', '.join(SPLITS)}")
        if self.labels not in LABELLINGS:
            raise UsageError(
                f"unknown labelling {self.labels!r}; choose one of: {', '.join(LABELLINGS)}"
            )
        if (
            isinstance(self.seed, bool)
            or not isinstance(self.seed, int)
            or not 0 <= self.seed < 2**32
        ):
            raise UsageError(f"seed must be an int in [0, 2**32 - 1], got {self.seed!r}")

    def validate(self) -> None:
        """Every detector parameter and protocol option, before any work starts."""
        self.detector.validate_params()
        self.protocol.validate_params()

    def cells(self, recordings: pd.DataFrame) -> list[Cell]:
        """The protocol's cells; a protocol that raises is a plugin fault naming it."""
        try:
            return list(self.protocol.cells(recordings))
        except Exception as exc:  # noqa: BLE001 - a plugin's bug, reported as such
            raise PluginError(
                f"protocol {self.protocol_name!r} failed to make its cells: {type(exc).__name__}: {exc}"
            ) from exc

    def cells_or_stand_in(self, recordings: pd.DataFrame) -> list[Cell]:
        """The protocol's cells, or where it makes none on these recordings one skipped stand-in
        (:func:`slipbench.protocol.no_cell`) saying why: results, reports and checks show the
        protocol and its reason instead of leaving it out."""
        cells = self.cells(recordings)
        if cells:
            return cells
        protocol = self.protocol  # an object since __post_init__; narrowed for the type checker
        try:
            why = protocol.why_no_cells(recordings) if isinstance(protocol, BaseProtocol) else ""
        except Exception as exc:  # noqa: BLE001 - a plugin's bug, reported as such
            raise PluginError(
                f"protocol {self.protocol_name!r} failed to say why it makes no cell: "
                f"{type(exc).__name__}: {exc}"
            ) from exc
        return [no_cell(self.protocol_name, str(why), recordings)]


def _concat(parts: list[Windows]) -> Windows:
    return Windows(
        None,
        np.concatenate([p.recording for p in parts]),
        np.concatenate([p.index for p in parts]),
        parts[0].recordings,
        np.concatenate([p.labels for p in parts]),
    )


class CellData:
    """Balanced, split windows per (sensor, window), computed once and shared by every cell that
    needs them. Balancing and splitting draw from the run's seed. Only positions are kept; a
    part's samples are cut when a model needs them, so memory holds one task's windows at a
    time. The same windows serve every downsampling, as the paper downsamples its 200-sample set."""

    def __init__(self, signals: Signals, how: str, seed: int, labelling: str = "scenario"):
        self.signals, self.how, self.seed, self.labelling = signals, how, seed, labelling
        self._sides = trial_sides(signals.recordings, seed) if how == "grouped" else None
        if how == "datasets" and SIDE_COLUMN not in signals.recordings:
            raise UsageError(
                "the datasets split needs a dataset combined by slipbench.data.transfer.combine "
                "(evaluate --train-dataset A --dataset B)"
            )
        self._cache: dict[tuple, tuple[Windows, Windows] | str] = {}
        self._antialiased: dict[int, Signals] = {}
        rec = signals.recordings
        self._rows = {
            k: np.flatnonzero((rec["sensor_type"] == k[0]) & (rec["sensor_instance"] == k[1]))
            for k in rec[["sensor_type", "sensor_instance"]]
            .drop_duplicates()
            .itertuples(index=False, name=None)
        }

    def sides(self, sensor: tuple[str, str], window: int) -> tuple[Windows, Windows]:
        """Train and test windows (positions only) of one sensor; UsageError saying why there
        are none (the cell that needs them is skipped with that reason)."""
        key = (sensor, window)
        if key not in self._cache:
            try:
                self._cache[key] = self._prepare(*key)
            except UsageError as exc:
                self._cache[key] = str(exc)
        if isinstance(self._cache[key], str):
            raise UsageError(self._cache[key])
        return self._cache[key]

    def _prepare(self, sensor, window):
        name = f"{sensor[0]} {sensor[1]}"
        if sensor not in self._rows:
            raise UsageError(f"the dataset has no recordings of sensor {name}")
        rows = self._rows[sensor]
        windows = self.signals.windows(window, rows, values=False, labelling=self.labelling)
        if len(windows) == 0:
            longest = int(np.max(np.diff(self.signals.offsets)[rows]))
            if longest < window:
                raise UsageError(
                    f"window {window} is longer than every recording of {name} (longest signal: {longest} samples)"
                )
            raise UsageError(
                f"no window of {window} samples of {name} can be labelled by {self.labelling}"
                + (
                    " (hold-slip recordings hold two states: label by samples, e.g. --labels majority)"
                    if self.labelling == "scenario"
                    else " (each touches an unlabelled sample)"
                )
            )
        rng = rng_for(self.seed, "balance", *sensor, window)
        if self.how == "datasets":
            return self._across_datasets(windows, rng, name)
        windows = windows.take(balance(windows, rng))
        train, test = split(windows, self.how, self.seed, self._sides)
        for side, idx in (("train", train), ("test", test)):
            classes = set(np.unique(windows.y[idx]))
            if classes != {0, 1}:
                missing = "slip" if 1 not in classes else "non-slip"
                raise UsageError(
                    f"the {self.how} split of {name} at window {window} leaves no {missing} windows on the {side} side"
                )
        return windows.take(train), windows.take(test)

    def _across_datasets(
        self, windows: Windows, rng: np.random.Generator, name: str
    ) -> tuple[Windows, Windows]:
        """Balanced windows of the training dataset; every window of the test dataset, balanced
        when it holds both classes (a one-class test set reports the rate that exists)."""
        on_test = windows.column(SIDE_COLUMN) == "test"
        train, test = windows.take(np.flatnonzero(~on_test)), windows.take(np.flatnonzero(on_test))
        if len(test) == 0:
            raise UsageError(f"the test dataset has no windows of {name}")
        train = train.take(balance(train, rng))
        if len(np.unique(test.y)) == 2:
            test = test.take(balance(test, rng))
        return train, test

    def streamed(self, part: Part) -> np.ndarray:
        """Rows of the recordings a streaming cell's part streams: those of its units that meet
        its conditions, carry per-sample labels and lie on its side of the split by whole trials
        (this CellData's split must be :func:`stream_split`'s). Sorted; may be empty."""
        rec = self.signals.recordings
        on_test = (
            (rec[SIDE_COLUMN] == "test").to_numpy() if self.how == "datasets" else self._sides == 1
        )
        labelled = rec[LABELLED].to_numpy(bool) if LABELLED in rec else np.zeros(len(rec), bool)
        return np.flatnonzero(part.mask(rec) & labelled & (on_test == (part.side == "test")))

    def part(self, part: Part, window: int) -> Windows:
        """The windows (positions) of a part."""
        side = 0 if part.side == "train" else 1
        chosen = _concat([self.sides(s, window)[side] for s in part.sensors])
        return chosen.take(np.flatnonzero(part.mask(self.signals.recordings)[chosen.recording]))

    def values(self, windows: Windows, cell: Cell) -> Windows:
        """``windows`` with their samples, as a sensor ``cell.downsample`` times slower gives
        them: low-passed first if ``cell.antialias``, then decimated as ``cell.decimation`` says.
        At the full rate there is nothing to filter or decimate."""
        if cell.downsample == 1:
            return Windows(
                self.signals.values(windows, cell.window),
                windows.recording,
                windows.index,
                windows.recordings,
                windows.labels,
            )
        signals = self.signals
        if cell.antialias:
            if cell.downsample not in self._antialiased:
                self._antialiased[cell.downsample] = self.signals.antialiased(cell.downsample)
            signals = self._antialiased[cell.downsample]
        out = Windows(
            signals.values(windows, cell.window),
            windows.recording,
            windows.index,
            windows.recordings,
            windows.labels,
        )
        return out.downsample(cell.downsample, cell.decimation)

    def sampling_rate(self, part: Part, downsample: int) -> float:
        """The rate (Hz) of a part's windows; UsageError naming recordings when it pools rates."""
        rec = self.signals.recordings
        rows = rec.loc[np.concatenate([self._rows[s] for s in part.sensors])]
        column = "unit_rate_hz" if "unit_rate_hz" in rows else "sampling_rate_hz"
        rates = rows[column].unique()
        if len(rates) > 1:
            lo, hi = rows.loc[rows[column].idxmin()], rows.loc[rows[column].idxmax()]
            raise UsageError(
                f"a cell pools sensors with different sampling rates: {float(lo[column]):g} Hz (recording "
                f"{lo['recording_id']}) to {float(hi[column]):g} Hz (recording {hi['recording_id']})"
            )
        return float(rates[0]) / downsample


@dataclass
class PlannedCell:
    """One cell of one run, with its keys and windows (positions), or the reason it is skipped."""

    run: Run
    cell: Cell
    key: str
    model_key: str
    train: Windows | None = None
    test: Windows | None = None
    sampling_rate: float = 0.0
    skip: str = ""
    streams: dict[str, np.ndarray] | None = (
        None  # streaming cells: "train"/"test" -> recording rows
    )


@dataclass
class Task:
    """One model to fit and the cells (of any protocol) it is tested on."""

    model_key: str
    cells: list[PlannedCell] = field(default_factory=list)

    @property
    def first(self) -> PlannedCell:
        """The cell that defines the model: every cell of a task shares its training windows,
        detector, split and seed (they share the model key)."""
        return self.cells[0]


@dataclass
class Plan:
    """Cells in the order of their runs and protocols; tasks for those still to compute."""

    cells: list[PlannedCell]
    tasks: list[Task]
    data: dict[tuple[str, int, str], CellData]

    def data_of(self, run: Run) -> CellData:
        return self.data[run.split, run.seed, run.labels]


def keys(run: Run, cell: Cell, fingerprint: str) -> tuple[str, str]:
    """Content addresses of a cell's result and of the model it tests (equal model keys train
    on the same windows). Both hold the identity of the code that runs: slipbench's and the
    detector's (and the cell key the protocol's), so a changed plugin or engine never returns
    results cached by the old code."""
    code = {
        "slipbench": code_identity(sys.modules["slipbench"]),
        "detector": code_identity(type(run.detector)),
    }
    try:
        params = canonical(run.detector.get_params())
    except TypeError as exc:
        raise UsageError(
            f"detector {run.detector_name!r}: a parameter is not a plain value: {exc}"
        ) from None
    common = {
        "dataset": fingerprint,
        "detector": run.detector_name,
        "params": params,
        "split": stream_split(run.split) if cell.stream else run.split,
        "seed": run.seed,
        "streams": STREAM_SCHEME,
        "labels": run.labels,
        "code": code,
    }
    # at the full rate every decimation gives the same windows: one model serves them all
    sampling = (
        {"decimation": "plain"}
        if cell.downsample == 1
        else {"decimation": cell.decimation, "antialias": bool(cell.antialias)}
    )
    model = cell_key(
        {
            **common,
            "train": cell.train,
            "window": cell.window,
            "downsample": cell.downsample,
            **sampling,
        }
    )
    key = cell_key(
        {
            **common,
            "protocol": run.protocol_name,
            "protocol_params": run.protocol.get_params(),
            "protocol_code": code_identity(type(run.protocol)),
            "cell": cell.key,
            "test": cell.test,
            "model": model,
            **({"stream": cell.stream, "run_split": run.split} if cell.stream else {}),
        }
    )
    return key, model


def _missing_classes(y: np.ndarray) -> str:
    classes = set(np.unique(y))
    return " and ".join(n for c, n in ((1, "slip"), (0, "non-slip")) if c not in classes)


def make_plan(
    signals: Signals, runs: list[tuple[Run, list[Cell]]], fingerprint: str, done: set[str]
) -> Plan:
    """Plan every cell of every run (a run with its protocol's cells); cells whose key is in
    ``done`` are listed but not computed."""
    data: dict[tuple[str, int, str], CellData] = {}
    planned: list[PlannedCell] = []
    tasks: dict[str, Task] = {}
    for run, cells in runs:
        if (run.split, run.seed, run.labels) not in data:
            data[run.split, run.seed, run.labels] = CellData(
                signals, run.split, run.seed, run.labels
            )
        cells_data = data[run.split, run.seed, run.labels]
        for cell in cells:
            key, model = keys(run, cell, fingerprint)
            pc = PlannedCell(run, cell, key, model, skip=cell.skip)
            planned.append(pc)
            if key in done or pc.skip:
                continue
            if cell.stream:
                _plan_stream(pc, data, signals)
                if not pc.skip:
                    tasks.setdefault(model, Task(model)).cells.append(pc)
                continue
            try:
                pc.train, pc.test = (
                    cells_data.part(cell.train, cell.window),
                    cells_data.part(cell.test, cell.window),
                )
                pc.sampling_rate = cells_data.sampling_rate(cell.train, cell.downsample)
            except UsageError as exc:
                pc.skip = str(exc)
                continue
            for windows, role in ((pc.train, "train"), (pc.test, "test")):
                missing = _missing_classes(windows.y)
                if missing and not (role == "test" and run.split == "datasets" and len(windows)):
                    pc.skip = f"no {missing} windows to {role} on"
                    break
            if not pc.skip:
                tasks.setdefault(model, Task(model)).cells.append(pc)
    return Plan(planned, list(tasks.values()), data)


def _plan_stream(
    pc: PlannedCell, data: dict[tuple[str, int, str], CellData], signals: Signals
) -> None:
    """A streaming cell's training windows (from the training trials) and the recordings it
    streams, or the reason it is skipped."""
    run, cell = pc.run, pc.cell
    how = stream_split(run.split)
    if (how, run.seed, run.labels) not in data:
        data[how, run.seed, run.labels] = CellData(signals, how, run.seed, run.labels)
    cells_data = data[how, run.seed, run.labels]
    units = ", ".join(f"{t} {i}" for t, i in cell.test.sensors)
    try:
        pc.train = cells_data.part(cell.train, cell.window)
        pc.sampling_rate = cells_data.sampling_rate(cell.train, 1)
    except UsageError as exc:
        pc.skip = str(exc)
        return
    missing = _missing_classes(pc.train.y)
    if missing:
        pc.skip = f"no {missing} windows to train on"
        return
    pc.streams = {side.side: cells_data.streamed(side) for side in (cell.train, cell.test)}
    test = pc.streams["test"]
    if not len(test):
        labelled = (
            LABELLED in signals.recordings
            and signals.recordings[LABELLED]
            .to_numpy(bool)[cell.test.mask(signals.recordings)]
            .any()
        )
        pc.skip = (
            f"no recording of {units} on the test side of the trial split carries per-sample slip labels"
            if labelled
            else f"the dataset gives no per-sample slip labels for {units}: streaming needs them to time slip onsets"
        )
        return
    o = signals.offsets
    # a recording that starts in slip shows no onset (slipbench.stream.cell.unknown_start)
    if not any((onsets(signals.labels[o[r] : o[r + 1]]) > 0).any() for r in test):
        pc.skip = (
            f"no slip onset in the {len(test)} test recordings of {units} (labels 0 followed by 1)"
        )
