"""Train on one dataset, test on another (``evaluate --train-dataset A --dataset B``).

The two are combined into one dataset whose recording ids say their role (``train/...`` and
``test/...``, so swapping the two is another dataset) and whose column ``dataset_side`` the
``datasets`` split follows: a cell's model trains on A's balanced windows and is tested on
every window of B (balanced when B holds both classes). B's sensor types, or units, are matched
to A's by name or by a map. A test set of one class is not a dead end: the rate that exists
(the TP rate of a slip-only set) is reported and the row says so.
"""

from __future__ import annotations

import pandas as pd

from slipbench.data.format import Dataset
from slipbench.errors import UsageError

SIDE_COLUMN = "dataset_side"


def parse_sensor_map(
    items: tuple[str, ...] | list[str],
) -> dict[tuple[str, str | None], tuple[str, str | None]]:
    """``["Vib=BioTacSP", "Taxels:left=Nano17:index"]`` -> {(type, instance or None): (type, instance or None)}."""
    out = {}
    for item in items:
        src, sep, dst = item.partition("=")
        if not sep or not src or not dst:
            raise UsageError(
                f"--sensor-map {item!r}: expected TYPE=TYPE or TYPE:INSTANCE=TYPE:INSTANCE"
            )
        key = tuple(src.split(":", 1)) if ":" in src else (src, None)
        value = tuple(dst.split(":", 1)) if ":" in dst else (dst, None)
        out[key] = value
    return out


def combine(train: Dataset, test: Dataset, sensor_map: dict | None = None) -> Dataset:
    """One dataset holding ``train``'s recordings (side "train") and ``test``'s (side "test"),
    ``test``'s sensors renamed by ``sensor_map``; UsageError when no unit of ``test`` matches
    one of ``train``."""
    sensor_map = sensor_map or {}
    a, b = train.recordings.copy(), test.recordings.copy()
    for (src_type, src_inst), (dst_type, dst_inst) in sensor_map.items():
        hit = b["sensor_type"].eq(src_type) & (
            b["sensor_instance"].eq(src_inst) if src_inst else True
        )
        if not hit.any():
            raise UsageError(
                f"--sensor-map: the test dataset has no sensor {src_type}{':' + src_inst if src_inst else ''}"
            )
        b.loc[hit, "sensor_type"] = dst_type
        if dst_inst:
            b.loc[hit, "sensor_instance"] = dst_inst
    units_a = set(zip(a["sensor_type"], a["sensor_instance"]))
    units_b = set(zip(b["sensor_type"], b["sensor_instance"]))
    if not units_a & units_b:
        raise UsageError(
            f"no unit of the test dataset ({', '.join(sorted(map(':'.join, units_b)))}) matches one of the "
            f"training dataset ({', '.join(sorted(map(':'.join, units_a)))}); map them with "
            "--sensor-map TEST_TYPE[:INSTANCE]=TRAIN_TYPE[:INSTANCE]"
        )
    parts, samples, labels = [], {}, {}
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
    return Dataset(recordings, samples, labels)
