"""Train on one dataset, test on another (``evaluate --train-dataset A --dataset B``).

The two are combined into one dataset whose recording ids say their role (``train/...`` and
``test/...``, so swapping the two is another dataset) and whose column ``dataset_side`` the
``datasets`` split follows: a cell's model trains on A's balanced windows and is tested on
every window of B (balanced when B holds both classes). B's sensor types, or units, are matched
to A's by name or by a map. A test set of one class is not a dead end: the rate that exists
(the TP rate of a slip-only set) is reported and the row says so.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd

from slipbench.data.format import Dataset
from slipbench.data.schema import RATE_TOLERANCE
from slipbench.errors import UsageError
from slipbench.vocabulary import DATASET_SIDE, SENSOR_TYPE

SIDE_COLUMN = DATASET_SIDE


UnitKey = tuple[str, str]  # (sensor_type, sensor_instance)
MAP_SYNTAX = "TEST_TYPE[:INSTANCE]=TRAIN_TYPE[:INSTANCE]"


def parse_sensor_map(
    items: tuple[str, ...] | list[str],
) -> dict[tuple[str, str | None], tuple[str, str | None]]:
    """``["Vib=BioTacSP", "Taxels:left=Nano17:index"]`` -> {(type, instance or None): (type, instance or None)}."""
    out: dict[tuple[str, str | None], tuple[str, str | None]] = {}
    for item in items:
        src, sep, dst = item.partition("=")
        if not sep or not src or not dst or src.endswith(":") or dst.endswith(":"):
            raise UsageError(f"--sensor-map {item!r}: expected {MAP_SYNTAX}")
        out[_unit(src)] = _unit(dst)
    return out


def _unit(text: str) -> tuple[str, str | None]:
    """``"Taxels:left"`` -> ("Taxels", "left"); ``"Vib"`` -> ("Vib", None)."""
    sensor_type, sep, instance = text.partition(":")
    return (sensor_type, instance) if sep else (text, None)


def _name(unit: tuple[str, str | None]) -> str:
    return unit[0] + (f":{unit[1]}" if unit[1] else "")


def _names(units) -> str:
    return ", ".join(sorted(map(_name, units))) or "none"


def resolve_sensor_map(
    sensor_map: dict[tuple[str, str | None], tuple[str, str | None]],
    test_units: list[UnitKey],
    train_units: list[UnitKey],
) -> dict[UnitKey, UnitKey]:
    """Each test unit a map entry names -> the training unit it is tested as.

    An entry naming an instance (``Taxels:left=...``) wins over one naming only the type
    (``Taxels=...``). A training side naming an instance takes it; one naming only the type
    (``BioTac=BioTacSP``) takes, for each test instance, the same-named instance of that type
    in the training dataset, else its only instance; where it has several and none of that
    name the entry is refused, since picking one would be a guess. UsageError naming the entry
    when a side names a sensor its dataset lacks.
    """
    out: dict[UnitKey, UnitKey] = {}
    for (src_type, src_inst), (dst_type, dst_inst) in sorted(
        sensor_map.items(), key=lambda kv: kv[0][1] is None
    ):
        entry = f"--sensor-map {_name((src_type, src_inst))}={_name((dst_type, dst_inst))}"
        hits = [u for u in test_units if u[0] == src_type and src_inst in (None, u[1])]
        if not hits:
            raise UsageError(
                f"{entry}: the test dataset has no sensor {_name((src_type, src_inst))} "
                f"(its units: {_names(test_units)})"
            )
        candidates = [u for u in train_units if u[0] == dst_type and dst_inst in (None, u[1])]
        if not candidates:
            raise UsageError(
                f"{entry}: the training dataset has no sensor {_name((dst_type, dst_inst))} "
                f"(its units: {_names(train_units)})"
            )
        for unit in hits:
            if unit in out:  # an entry naming the instance came first
                continue
            same = [c for c in candidates if c[1] == unit[1]]
            if same or len(candidates) == 1:
                out[unit] = (same or candidates)[0]
                continue
            raise UsageError(
                f"{entry}: the test unit {_name(unit)} has no same-named {dst_type} instance in the "
                f"training dataset, which has several ({_names(candidates)}); name the one to test "
                f"it as, e.g. --sensor-map {_name(unit)}={_name(candidates[0])}"
            )
    return out


def _rate(recordings: pd.DataFrame, unit: UnitKey) -> float:
    rows = recordings[
        (recordings[SENSOR_TYPE] == unit[0]) & (recordings["sensor_instance"] == unit[1])
    ]
    return float(np.median(rows["sampling_rate_hz"].to_numpy(dtype=float)))


def _same_rates(matched: dict[UnitKey, UnitKey], train: pd.DataFrame, test: pd.DataFrame) -> None:
    """UsageError naming a test unit whose rate is not its training unit's: a window of n
    samples would span another time and band, and one unit cannot hold two rates."""
    for unit, as_ in matched.items():
        lo, hi = sorted((_rate(test, unit), _rate(train, as_)))
        if hi > lo * (1 + RATE_TOLERANCE):
            raise UsageError(
                f"the test unit {_name(unit)} is sampled at {_rate(test, unit):g} Hz, the training unit "
                f"{_name(as_)} it is tested as at {_rate(train, as_):g} Hz: a model of windows at one "
                "rate cannot be tested at another (resample one dataset first, or map the test unit "
                "to a training unit of its rate)"
            )


def combine(train: Dataset, test: Dataset, sensor_map: dict | None = None) -> Dataset:
    """One dataset holding ``train``'s recordings (side "train") and ``test``'s (side "test"),
    ``test``'s units renamed by ``sensor_map`` (see :func:`resolve_sensor_map`); UsageError
    when no unit of ``test`` matches one of ``train``. Its ``origin`` names both datasets (path,
    fingerprint) and which test unit is tested as which training unit."""
    a, b = train.recordings.copy(), test.recordings.copy()
    units_a, units_b = train.sensors(), test.sensors()
    resolved = resolve_sensor_map(sensor_map or {}, units_b, units_a)
    pairs = list(zip(b[SENSOR_TYPE], b["sensor_instance"]))
    renamed = [resolved.get(u, u) for u in pairs]
    b[SENSOR_TYPE] = [u[0] for u in renamed]
    b["sensor_instance"] = [u[1] for u in renamed]
    matched = {u: resolved.get(u, u) for u in units_b if resolved.get(u, u) in set(units_a)}
    _same_rates(matched, train.recordings, test.recordings)
    if not matched:
        raise UsageError(
            f"no unit of the test dataset ({_names(units_b)}) has the name of a unit of the "
            f"training dataset ({_names(units_a)}); say which to test as which with "
            f"--sensor-map {MAP_SYNTAX} (a type alone maps every instance of it)"
        )
    parts: list[pd.DataFrame] = []
    samples: dict[str, np.ndarray] = {}
    labels: dict[str, np.ndarray] = {}
    for side, frame, ds in (("train", a, train), ("test", b, test)):
        frame = frame.assign(**{SIDE_COLUMN: side})
        old = frame["recording_id"].tolist()
        frame["recording_id"] = [f"{side}/{r}" for r in old]
        frame["trial"] = [f"{side}/{t}" for t in frame["trial"]]
        samples |= {f"{side}/{r}": ds.samples[r] for r in old}
        labels |= {f"{side}/{r}": ds.slip_labels[r] for r in old if r in ds.slip_labels}
        parts.append(frame)
    recordings = pd.concat(parts, ignore_index=True)
    # where one dataset has per-sample labels and the other not, the other's recordings stay
    # unlabelled (-1): labelling by samples skips them with the reason, never by their scenario
    origin = {
        "train_dataset_path": str(train.path or ""),
        "train_dataset_fingerprint": train.fingerprint,
        "test_dataset_path": str(test.path or ""),
        "test_dataset_fingerprint": test.fingerprint,
        "sensor_map": json.dumps({_name(u): _name(v) for u, v in sorted(matched.items())}),
    }
    return Dataset(recordings, samples, labels, origin=origin)
