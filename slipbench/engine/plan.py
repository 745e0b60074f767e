"""Planning a run: every cell of every protocol, its windows, its keys and whether it can run,
computed once before anything trains.

Cells that train on exactly the same windows share one model: they are grouped into a
:class:`Task` that fits once and tests every cell of the group. A cell that cannot run on this
dataset (a window longer than every recording, a split side without one class) is planned as
skipped with its reason; it never stops the others.
"""

from __future__ import annotations

import copy
import sys
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from slipbench.base import BaseDetector, too_few_windows
from slipbench.data.channels import channel_match
from slipbench.data.format import Dataset
from slipbench.data.signals import (
    BALANCINGS,
    LABELLINGS,
    NORMALIZATIONS,
    SPLITS,
    Signals,
    Windows,
    balance,
    balance_limits,
    balanced_counts,
    has_sample_labels,
    split,
    trial_sides,
)
from slipbench.data.transfer import SIDE_COLUMN
from slipbench.engine.registry import detectors, protocols
from slipbench.errors import PluginError, UsageError
from slipbench.protocol import BaseProtocol, Cell, Part, no_cell
from slipbench.seeding import STREAM_SCHEME, rng_for
from slipbench.store.keys import canonical, cell_key, code_identity
from slipbench.stream.metrics import DELAY_CLOCK, onsets
from slipbench.vocabulary import INPUTS, SENSOR_TYPE

# a recordings column the runner adds: True where the dataset gives the recording per-sample
# slip labels (elsewhere Signals labels samples by scenario, which has no onset to time)
LABELLED = "has_slip_labels"


def stream_split(how: str) -> str:
    """The split a streaming cell trains and tests by: whole trials ("grouped"), whatever the
    run's split, since a stream is a whole recording and its trial twins must not train the
    model; across datasets, the datasets themselves."""
    return "datasets" if how == "datasets" else "grouped"


@dataclass(init=False)  # __init__ takes ids as well as objects; the fields hold objects
class Run:
    """One detector on one protocol, with a split, a seed and a way to label windows.

    ``detector`` and ``protocol`` are objects or ids (``"holweg"``, ``"window-size"``); an id
    is looked up in the registry, an object's id is the name its class is registered under.
    ``labels``: one of :data:`slipbench.data.signals.LABELLINGS`. ``normalize``: one of
    :data:`slipbench.data.signals.NORMALIZATIONS` (see :meth:`CellData.normalization`).
    ``input``: one of :data:`slipbench.vocabulary.INPUTS`, what the detector reads: windows of
    the univariate signal, or of the raw channels, each standardized by its training windows'
    statistics (the detector must declare it in ``inputs``). ``balance``: one of
    :data:`slipbench.data.signals.BALANCINGS`, whether balancing keeps classes equal within each
    material (the paper) or across materials pooled (:meth:`Windows.strata`).
    """

    detector: BaseDetector
    protocol: BaseProtocol
    split: str = "paper"
    seed: int = 0
    labels: str = "scenario"
    normalize: str = "none"
    input: str = "univariate"
    balance: str = "within"
    detector_name: str = field(init=False)
    protocol_name: str = field(init=False)
    #: which draw of the detector's seed stream its models train from (:meth:`retrained`)
    retrain: int = field(init=False, default=0)

    def __init__(  # noqa: PLR0913 (a run's settings, passed by position by its callers in app/)
        self,
        detector: BaseDetector | str,
        protocol: BaseProtocol | str,
        split: str = "paper",
        seed: int = 0,
        labels: str = "scenario",
        normalize: str = "none",
        input: str = "univariate",
        balance: str = "within",
    ) -> None:
        self.split, self.seed, self.labels, self.normalize = split, seed, labels, normalize
        self.input, self.balance, self.retrain = input, balance, 0
        if isinstance(detector, str):
            self.detector_name, self.detector = detector, detectors.get(detector)()
        else:
            self.detector_name, self.detector = detectors.id_of(type(detector)), detector
        if isinstance(protocol, str):
            self.protocol_name, self.protocol = protocol, protocols.get(protocol)()
        else:
            self.protocol_name, self.protocol = protocols.id_of(type(protocol)), protocol
        if self.split not in SPLITS:
            raise UsageError(f"unknown split {self.split!r}; choose one of: {', '.join(SPLITS)}")
        if self.labels not in LABELLINGS:
            raise UsageError(
                f"unknown labelling {self.labels!r}; choose one of: {', '.join(LABELLINGS)}"
            )
        if self.normalize not in NORMALIZATIONS:
            raise UsageError(
                f"unknown normalization {self.normalize!r}; choose one of: {', '.join(NORMALIZATIONS)}"
            )
        if self.input not in INPUTS:
            raise UsageError(f"unknown input {self.input!r}; choose one of: {', '.join(INPUTS)}")
        if self.balance not in BALANCINGS:
            raise UsageError(
                f"unknown balancing {self.balance!r}; choose one of: {', '.join(BALANCINGS)}"
            )
        if self.input == "channels" and self.normalize != "none":
            raise UsageError(
                f"--normalize {self.normalize} scales the univariate signal; the channels input "
                "standardizes each channel by its training windows' statistics instead: use "
                "--normalize none with --input channels"
            )
        if (
            isinstance(self.seed, bool)
            or not isinstance(self.seed, int)
            or not 0 <= self.seed < 2**32
        ):
            raise UsageError(f"seed must be an int in [0, 2**32 - 1], got {self.seed!r}")

    def retrained(self, draw: int) -> Run:
        """This run with every model trained from draw ``draw`` of the detector's seed stream
        (0: the run itself): the same split and windows, other training randomness. A detector
        that draws nothing in ``fit`` (a threshold on a fixed band) gives the same rows under
        every draw; one that does shows its retraining noise alone, apart from the split's
        (``slipbench calibrate`` runs a draw beside each seed). The draw is part of the keys."""
        if isinstance(draw, bool) or not isinstance(draw, int) or draw < 0:
            raise UsageError(f"a retraining draw is an int >= 0, got {draw!r}")
        twin = copy.copy(self)
        twin.retrain = draw
        return twin

    def validate(self) -> None:
        """Every detector parameter and protocol option, and the input the detector reads,
        before any work starts."""
        self.detector.validate_params()
        self.protocol.validate_params()
        takes = type(self.detector).inputs
        if self.input not in takes:
            raise UsageError(
                f"detector {self.detector_name!r} reads the {' or '.join(takes)} input, not "
                f"{self.input}"
            )

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


def check_labels(labelling: str, dataset: Dataset) -> None:
    """UsageError (exit 2), before any work, where labelling by samples (``majority``, ``any``,
    ``last``) meets a dataset none of whose recordings has per-sample slip labels: every cell
    would otherwise be labelled by scenario under another name. Where only some units (or one
    dataset of two) lack them, their cells are skipped with the reason instead
    (:meth:`CellData.sides`)."""
    if labelling == "scenario" or has_sample_labels(dataset).any():
        return
    if SIDE_COLUMN in dataset.recordings:
        where = "neither the training dataset nor the test dataset has"
    else:
        where = f"the dataset{f' {dataset.path}' if dataset.path else ''} has"
    raise UsageError(
        f"labelling {labelling!r} (--labels {labelling}) labels each window from its samples' slip "
        f"labels, but {where} no per-sample slip labels (no `slip` column, or every value empty); "
        "use --labels scenario, or add the labels (datasets.md)"
    )


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

    def __init__(  # noqa: PLR0913 (a run's settings that shape its windows)
        self,
        signals: Signals,
        how: str,
        seed: int,
        labelling: str = "scenario",
        normalize: str = "none",
        balancing: str = "within",
    ):
        self.signals, self.how, self.seed, self.labelling = signals, how, seed, labelling
        self.balancing = balancing
        # per (sensor, window): its windows before balancing, and why balancing keeps what it
        # keeps of each class (what a cell's rows and warnings count against)
        self._available: dict[tuple, Windows] = {}
        self._whys: dict[tuple, str] = {}
        self._sides = trial_sides(signals.recordings, seed) if how == "grouped" else None
        if how == "datasets" and SIDE_COLUMN not in signals.recordings:
            raise UsageError(
                "the datasets split needs a dataset combined by slipbench.data.transfer.combine "
                "(evaluate --train-dataset A --dataset B)"
            )
        self.normalize = normalize
        # (n_recordings, 2) centre and scale each recording's signal was normalized by
        self.scales: np.ndarray | None = None
        if normalize != "none":
            self.signals, self.scales = signals.normalized(*self.normalization(normalize))
        self._cache: dict[tuple, tuple[Windows, Windows] | str] = {}
        self._antialiased: dict[int, Signals] = {}
        self._masks: dict[tuple, np.ndarray] = {}
        self._antialiased_channels: dict[int, list[np.ndarray]] = {}
        rec = signals.recordings
        self._rows = {
            k: np.flatnonzero((rec[SENSOR_TYPE] == k[0]) & (rec["sensor_instance"] == k[1]))
            for k in rec[[SENSOR_TYPE, "sensor_instance"]]
            .drop_duplicates()
            .itertuples(index=False, name=None)
        }

    def normalization(self, how: str) -> tuple[np.ndarray, np.ndarray]:
        """The groups whose signal shares one centre and scale, and the recordings that give
        each group's statistics (see :meth:`Signals.normalized`).

        ``recording``: each recording alone, by its own statistics (the test side's too: they
        use no label). ``unit``: each sensor unit of each dataset (across datasets, the test
        dataset's unit is another physical unit than the training dataset's of that name), by
        its recordings on the training side of this split: every recording for ``paper``
        (windows of one recording lie on both sides), the training trials for ``grouped``; a
        unit with none there (the test dataset's units) by all of its own recordings.
        """
        rec = self.signals.recordings
        if how == "recording":
            return np.arange(len(rec)), np.ones(len(rec), bool)
        side = (
            rec[SIDE_COLUMN].astype(str).to_numpy() if SIDE_COLUMN in rec else np.full(len(rec), "")
        )
        units = pd.Series(
            [f"{d}|{t}|{i}" for d, t, i in zip(side, rec[SENSOR_TYPE], rec["sensor_instance"])]
        )
        groups = pd.factorize(units)[0]
        if self._sides is not None:  # grouped
            reference = np.asarray(self._sides == 0)
        elif self.how == "datasets":
            reference = np.asarray(side == "train")
        else:
            reference = np.ones(len(rec), bool)
        return groups, reference

    def sides(self, sensor: tuple[str, str], window: int) -> tuple[Windows, Windows]:
        """Train and test windows (positions only) of one sensor; UsageError saying why there
        are none (the cell that needs them is skipped with that reason)."""
        key = (sensor, window)
        if key not in self._cache:
            try:
                self._cache[key] = self._prepare(*key)
            except UsageError as exc:
                self._cache[key] = str(exc)
        cached = self._cache[key]
        if isinstance(cached, str):
            raise UsageError(cached)
        return cached

    def _prepare(self, sensor, window):
        name = f"{sensor[0]} {sensor[1]}"
        if sensor not in self._rows:
            raise UsageError(f"the dataset has no recordings of sensor {name}")
        rows = self._rows[sensor]
        self._require_labels(rows, name)
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
        self._available[sensor, window] = windows
        if self.how == "datasets":
            return self._across_datasets(windows, rng, name)
        windows = windows.take(balance(windows, rng, self.balancing))
        train, test = split(windows, self.how, self.seed, self._sides, self.balancing)
        for side, idx in (("train", train), ("test", test)):
            classes = set(np.unique(windows.y[idx]))
            if classes != {0, 1}:
                missing = "slip" if 1 not in classes else "non-slip"
                raise UsageError(
                    f"the {self.how} split of {name} at window {window} leaves no {missing} windows on the {side} side"
                )
        return windows.take(train), windows.take(test)

    def _require_labels(self, rows: np.ndarray, name: str) -> None:
        """UsageError where labelling by samples meets recordings of a unit (on a side of the
        datasets split) of which none has per-sample labels: its cells are skipped saying so,
        rather than labelled by scenario under another name."""
        labelled = self.signals.labelled
        if self.labelling == "scenario" or labelled is None:
            return
        rec = self.signals.recordings
        sides = (
            [("training dataset", rec[SIDE_COLUMN].to_numpy()[rows] == "train")]
            + [("test dataset", rec[SIDE_COLUMN].to_numpy()[rows] == "test")]
            if self.how == "datasets"
            else [("dataset", np.ones(len(rows), bool))]
        )
        for side, mine in sides:
            if mine.any() and not labelled[rows[mine]].any():
                raise UsageError(
                    f"the {side} gives no per-sample slip labels for {name}: labelling "
                    f"{self.labelling!r} needs them (--labels scenario labels by scenario)"
                )

    def _across_datasets(
        self, windows: Windows, rng: np.random.Generator, name: str
    ) -> tuple[Windows, Windows]:
        """Balanced windows of the training dataset; every window of the test dataset, balanced
        when it holds both classes (a one-class test set reports the rate that exists). Balancing
        keeps every class present (:func:`balance`), so a test set of both classes stays one."""
        on_test = windows.column(SIDE_COLUMN) == "test"
        train, test = windows.take(np.flatnonzero(~on_test)), windows.take(np.flatnonzero(on_test))
        if len(test) == 0:
            raise UsageError(f"the test dataset has no windows of {name}")
        if len(train) == 0:
            raise UsageError(f"the training dataset has no windows of {name}")
        try:
            train = train.take(balance(train, rng, self.balancing))
        except UsageError as exc:
            raise UsageError(f"the training dataset's windows of {name}: {exc}") from None
        if len(np.unique(test.y)) == 2:
            test = test.take(balance(test, rng, self.balancing))
        return train, test

    def available(self, part: Part, window: int) -> dict[int, int]:
        """{1: slip, 0: non-slip} windows a part could hold before balancing: its units' windows
        that meet its conditions, on its side where the split deals sides before balancing
        (grouped, datasets); with the paper split, which halves each unit's balanced windows,
        half of each unit's (the training side the smaller half, as the split gives it)."""
        counts = {1: 0, 0: 0}
        mask = self._mask(part)
        for sensor in part.sensors:
            self.sides(sensor, window)  # prepared, or the UsageError saying why not
            windows = self._available[sensor, window]
            keep = mask[windows.recording]
            if self._sides is not None:  # grouped
                keep &= (self._sides[windows.recording] == 1) == (part.side == "test")
            elif self.how == "datasets":
                keep &= windows.column(SIDE_COLUMN) == part.side
            for c in counts:
                n = int((windows.labels[keep] == c).sum())
                if self.how == "paper":
                    n = n // 2 if part.side == "train" else n - n // 2
                counts[c] += n
        return counts

    def balance_warning(self, cell: Cell, kept: dict[str, Windows]) -> str:
        """Where balancing kept under half of a class's windows a side could hold
        (:meth:`available`), "balancing kept 4 of 15 slip training windows. Why: " and, per
        unit of those sides ("; "-separated), why (:func:`balance_limits`) and what the other
        balancing keeps; "" where it kept at least half of each."""
        counts, units = [], []
        for role, windows in kept.items():
            part = cell.train if role == "train" else cell.test
            could = self.available(part, cell.window)
            for c, name in ((1, "slip"), (0, "non-slip")):
                used = int((windows.y == c).sum())
                if 2 * used < could[c]:
                    side = "training" if role == "train" else "test"
                    counts.append(f"{used} of {could[c]} {name} {side} windows")
                    # across datasets each side is balanced alone; otherwise the unit once
                    where = part.side if self.how == "datasets" else ""
                    units += [(s, where) for s in part.sensors]
        if not counts:
            return ""
        why = "; ".join(self._why(s, cell.window, side) for s, side in dict.fromkeys(units))
        return f"balancing kept {', '.join(counts)}. Why: {why}"

    def _why(self, sensor: tuple[str, str], window: int, side: str) -> str:
        """Why balancing keeps what it keeps of a unit's windows (of one side across datasets,
        which balances each alone), and what balancing across materials would keep; once per
        unit, window and side (every cell and detector of a run asks again)."""
        key = (sensor, window, side)
        if key not in self._whys:
            self._whys[key] = self._cause(sensor, window, side)
        return self._whys[key]

    def _cause(self, sensor: tuple[str, str], window: int, side: str) -> str:
        windows = self._available[sensor, window]
        if side:
            windows = windows.take(np.flatnonzero(windows.column(SIDE_COLUMN) == side))
        dataset = {"train": " of the training dataset", "test": " of the test dataset"}
        name = f"{sensor[0]} {sensor[1]}{dataset.get(side, '')} at window {window}"
        try:
            cause = balance_limits(windows, self.balancing)
        except UsageError:  # a test side of one class, kept whole
            return f"{name}: one class only"
        rec = windows.recordings.iloc[np.unique(windows.recording)]
        materials = rec["material"].dropna().nunique()
        trials = rec["trial"].nunique() if "trial" in rec else len(rec)
        if self.balancing == "within" and 1 < materials >= trials:
            cause = f"each material holds one trial, so {cause}"
        if self.balancing == "within":
            within, across = balanced_counts(windows, "within"), balanced_counts(windows, "across")
            if sum(across.values()) > sum(within.values()):
                held = {c: int((windows.y == c).sum()) for c in (1, 0)}
                cause += (
                    f", and --balance across keeps {across[1]} of its {held[1]} slip and "
                    f"{across[0]} of {held[0]} non-slip windows"
                )
        return f"{name}: {cause}"

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
        return chosen.take(np.flatnonzero(self._mask(part)[chosen.recording]))

    def _mask(self, part: Part) -> np.ndarray:
        """``part.mask`` of the recordings, once per part: every window and every detector of
        a run asks again (a mask reads the recordings' columns, most of planning's time)."""
        key = (part.sensors, part.where)
        try:
            hash(key)
        except TypeError:  # a plugin's condition on an unhashable value
            return part.mask(self.signals.recordings)
        if key not in self._masks:
            self._masks[key] = part.mask(self.signals.recordings)
        return self._masks[key]

    def values(self, windows: Windows, cell: Cell, input: str = "univariate") -> Windows:
        """``windows`` with their samples, as a sensor ``cell.downsample`` times slower gives
        them: low-passed first if ``cell.antialias``, then decimated as ``cell.decimation`` says.
        At the full rate there is nothing to filter or decimate. ``input``: the univariate
        signal, or the raw ``channels`` (:meth:`Signals.channel_values`; not standardized)."""
        filtered = cell.downsample > 1 and cell.antialias
        if input == "channels":
            source = None
            if filtered:
                if cell.downsample not in self._antialiased_channels:
                    self._antialiased_channels[cell.downsample] = self.signals.antialiased_channels(
                        cell.downsample
                    )
                source = self._antialiased_channels[cell.downsample]
            x = self.signals.channel_values(windows, cell.window, source)
        else:
            signals = self.signals
            if filtered:
                if cell.downsample not in self._antialiased:
                    self._antialiased[cell.downsample] = self.signals.antialiased(cell.downsample)
                signals = self._antialiased[cell.downsample]
            x = signals.values(windows, cell.window)
        out = windows.with_x(x)
        return out if cell.downsample == 1 else out.downsample(cell.downsample, cell.decimation)

    def sampling_rate(self, part: Part, downsample: int) -> float:
        """The rate (Hz) of a part's windows; UsageError naming recordings when it pools rates."""
        rec = self.signals.recordings
        ids = np.concatenate([self._rows[s] for s in part.sensors])
        column = "unit_rate_hz" if "unit_rate_hz" in rec else "sampling_rate_hz"
        # one column, not every column of the rows: the frame's rows took most of planning
        rates = rec[column].loc[ids].unique()
        if len(rates) > 1:
            rows = rec.loc[ids]
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
    # what planning chose for the cell that its row must say (its warnings)
    notes: list[str] = field(default_factory=list)
    streams: dict[str, np.ndarray] | None = (
        None  # streaming cells: "train"/"test" -> recording rows
    )
    # windows each side could hold before balancing (``train_slip_available``, ...)
    available: dict[str, int] = field(default_factory=dict)
    # where balancing kept under half of a class's windows: how many, why, what keeps more
    balance_warning: str = ""

    def windows(self, side: str) -> Windows:
        """The "train" or "test" windows of a cell that runs: planning set them (a streaming
        cell has train windows only)."""
        windows = self.train if side == "train" else self.test
        assert windows is not None, f"cell {self.key} has no {side} windows planned"
        return windows


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

    @property
    def models(self) -> int:
        return 1


@dataclass
class Batch:
    """Models of one lockstep class and key (:meth:`BaseDetector.lockstep_key`) that one worker
    trains together: its cells are those of its tasks, in order."""

    tasks: list[Task]

    @property
    def cells(self) -> list[PlannedCell]:
        return [pc for task in self.tasks for pc in task.cells]

    @property
    def models(self) -> int:
        return len(self.tasks)


LOCKSTEP_MAX = 16  # models per batch: two of the LSTM's 8-lane blocks; the bar moves between


def _lockstep_key(task: Task) -> tuple | None:
    """Which models may train together: one class, input, rate and window (None: alone)."""
    pc = task.first
    detector, cell = pc.run.detector, pc.cell
    if not type(detector).lockstep:
        return None
    window = detector.lockstep_key(cell.window)
    return (pc.run.detector_name, pc.run.input, cell.downsample, cell.decimation, window)


def batched(tasks: list[Task], workers: int, cap: int = LOCKSTEP_MAX) -> list[Task | Batch]:
    """``tasks`` with those of one lockstep key cut into batches, in plan order: each key gets
    batches in proportion to its share of the models, so that ``workers`` stay busy, of at
    most ``cap`` models; a batch of one is its task."""
    groups: dict[Any, list[Task]] = {}
    for n, task in enumerate(tasks):
        groups.setdefault(_lockstep_key(task) or n, []).append(task)
    lockstep = sum(len(g) for k, g in groups.items() if isinstance(k, tuple))
    out: list[Task | Batch] = []
    for key, group in groups.items():
        if not isinstance(key, tuple):
            out += group
            continue
        share = -(-max(workers, 1) * len(group) // lockstep)
        parts = min(len(group), max(share, -(-len(group) // cap)))
        for part in np.array_split(np.arange(len(group)), parts):
            members = [group[i] for i in part]
            out.append(members[0] if len(members) == 1 else Batch(members))
    return out


@dataclass
class Plan:
    """Cells in the order of their runs and protocols; tasks for those still to compute."""

    cells: list[PlannedCell]
    tasks: list[Task]
    data: dict[tuple[str, int, str, str, str], CellData]

    def data_of(self, pc: PlannedCell) -> CellData:
        """The windows and signal a cell was planned on (a streaming cell: its trial split's)."""
        run = pc.run
        how = stream_split(run.split) if pc.cell.stream else run.split
        return self.data[how, run.seed, run.labels, run.normalize, run.balance]


def _code(run: Run) -> dict[str, str]:
    return {
        "slipbench": code_identity(sys.modules["slipbench"]),
        "detector": code_identity(type(run.detector)),
    }


def run_code_identity(run: Run) -> str:
    """The identity of the code a run's cells ran: slipbench's, the detector's and the
    protocol's source, as their cell keys hold it. Rows that share it (and the detector's
    parameters) differ only in their seed: the history takes them as replicates."""
    return cell_key({**_code(run), "protocol": code_identity(type(run.protocol))})


def keys(run: Run, cell: Cell, fingerprint: str) -> tuple[str, str]:
    """Content addresses of a cell's result and of the model it tests (equal model keys train
    on the same windows). Both hold the identity of the code that runs: slipbench's and the
    detector's (and the cell key the protocol's), so a changed plugin or engine never returns
    results cached by the old code."""
    code = _code(run)
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
        # absent when "none" / "univariate", so the keys of runs without them stay those of
        # earlier versions
        **({"normalize": run.normalize} if run.normalize != "none" else {}),
        **({"input": run.input} if run.input != "univariate" else {}),
        **({"balance": run.balance} if run.balance != "within" else {}),
        **({"retrain": run.retrain} if run.retrain else {}),
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
            **(
                {"stream": cell.stream, "run_split": run.split, "delays": DELAY_CLOCK}
                if cell.stream
                else {}
            ),
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
    data: dict[tuple[str, int, str, str, str], CellData] = {}
    planned: list[PlannedCell] = []
    tasks: dict[str, Task] = {}
    for run, cells in runs:
        cells_data = _data(data, signals, run, run.split)
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
                train, test = (
                    cells_data.part(cell.train, cell.window),
                    cells_data.part(cell.test, cell.window),
                )
                pc.train, pc.test = train, test
                _count_kept(pc, cells_data, {"train": train, "test": test})
                pc.sampling_rate = cells_data.sampling_rate(cell.train, cell.downsample)
                pc.skip = _same_model(cells_data, cell)
            except UsageError as exc:
                pc.skip = str(exc)
            if pc.skip:
                continue
            if run.input == "channels":
                _match_channels(pc, signals, train.recording, test.recording)
                if pc.skip:
                    continue
            for windows, role in ((train, "train"), (test, "test")):
                missing = _missing_classes(windows.y)
                if missing and not (role == "test" and run.split == "datasets" and len(windows)):
                    pc.skip = f"no {missing} windows to {role} on"
                    break
            # a detector that needs more windows of a class than the cell trains on (a network
            # that validates on some) is skipped saying so, not failed in its fit
            pc.skip = pc.skip or too_few_windows(type(run.detector), train.y)
            if not pc.skip:
                tasks.setdefault(model, Task(model)).cells.append(pc)
    return Plan(planned, list(tasks.values()), data)


def _match_channels(pc: PlannedCell, signals: Signals, *rows: np.ndarray) -> None:
    """Skip a channels-input cell whose recordings (``rows``, on both sides) name different
    channels or units, saying which; note where some were reordered to match by name."""
    pc.skip, note = channel_match(signals.recordings, *rows)
    if note:
        pc.notes.append(note)


def _count_kept(pc: PlannedCell, cells_data: CellData, kept: dict[str, Windows]) -> None:
    """A cell's windows available on each side before balancing, and its balancing warning."""
    for role in kept:
        part = pc.cell.train if role == "train" else pc.cell.test
        could = cells_data.available(part, pc.cell.window)
        pc.available |= {f"{role}_slip_available": could[1], f"{role}_nonslip_available": could[0]}
    pc.balance_warning = cells_data.balance_warning(pc.cell, kept)


def _data(
    data: dict[tuple[str, int, str, str, str], CellData], signals: Signals, run: Run, how: str
) -> CellData:
    """The CellData of a run's split (``how``), made once and shared."""
    key = (how, run.seed, run.labels, run.normalize, run.balance)
    if key not in data:
        data[key] = CellData(signals, how, run.seed, run.labels, run.normalize, run.balance)
    return data[key]


def _same_model(cells_data: CellData, cell: Cell) -> str:
    """Why a cell of a "with and without" pair cannot run: the training side of its units
    holds no window of the held-out value, so with and without are the same model; "" if it
    holds some."""
    if cell.holdout is None:
        return ""
    column, value = cell.holdout
    where = tuple(c for c in cell.train.where if c != (column, "!=", value))
    trained = cells_data.part(Part(cell.train.sensors, "train", where), cell.window)
    if (trained.column(column) == value).any():
        return ""
    units = ", ".join(f"{t} {i}" for t, i in cell.train.sensors)
    shown = f"{value:g}" if isinstance(value, float) else str(value)
    return (
        f"with and without are the same model: the training side of {units} holds no "
        f"{column} {shown} windows"
    )


def _plan_stream(
    pc: PlannedCell, data: dict[tuple[str, int, str, str, str], CellData], signals: Signals
) -> None:
    """A streaming cell's training windows (from the training trials) and the recordings it
    streams, or the reason it is skipped."""
    run, cell = pc.run, pc.cell
    cells_data = _data(data, signals, run, stream_split(run.split))
    units = ", ".join(f"{t} {i}" for t, i in cell.test.sensors)
    try:
        pc.train = cells_data.part(cell.train, cell.window)
        _count_kept(pc, cells_data, {"train": pc.train})
        pc.sampling_rate = cells_data.sampling_rate(cell.train, 1)
    except UsageError as exc:
        pc.skip = str(exc)
        return
    missing = _missing_classes(pc.train.y)
    if missing:
        pc.skip = f"no {missing} windows to train on"
        return
    pc.skip = too_few_windows(type(run.detector), pc.train.y)
    if pc.skip:
        return
    pc.streams = {side.side: cells_data.streamed(side) for side in (cell.train, cell.test)}
    test = pc.streams["test"]
    if run.input == "channels":
        _match_channels(pc, signals, pc.train.recording, test, pc.streams["train"])
        if pc.skip:
            return
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
    labels = signals.sample_labels()
    if not any((onsets(labels[o[r] : o[r + 1]]) > 0).any() for r in test):
        pc.skip = (
            f"no slip onset in the {len(test)} test recordings of {units} (labels 0 followed by 1)"
        )
