"""The benchmark's vocabulary: the names of the paper's design (sensors, fingers, materials,
speeds), the order in which results list detectors, splits and key columns, how a key value and
a whole cell key read, and the thresholds every stage shares (the shortest window, the fewest
test trials to trust an interval). Defined here once, beside the plugin contract, so the
simulation, the protocols, the statistics and the report agree without importing each other.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # annotations only: the CLI reads this module before it needs pandas
    import pandas as pd

# ----------------------------------------------------------------------------- the paper's design
SENSOR_ORDER = ("Nano17", "OptoForce20", "BioTacSP")  # sensor types, in the paper's order
SENSOR_NAMES = {"Nano17": "Nano17", "OptoForce20": "OptoForce20", "BioTacSP": "Biotac SP"}
INSTANCE_ORDER = ("index", "middle", "little", "combined")  # fingers; "combined" pools them
MATERIALS = ("aluminum", "PVC", "neoprene", "cardboard", "plywood")  # in the paper's table order
SLIP_SPEEDS = (5.0, 25.0, 50.0, 75.0)  # mm/s, average speeds of slip
FREE_SPACE_SPEEDS = (25.0, 50.0, 75.0)  # mm/s, arm speeds of free-space motion

# a recording column the dataset reader derives: the recording holds slip (a slip recording, or
# one with a sample labelled slip; a hold-slip trial that held throughout does not)
SLIPS = "slips"

# what a detector reads: the paper's univariate signal s, or the raw channels it reduces
INPUTS = ("univariate", "channels")

# ----------------------------------------------------------------------------- thresholds
MIN_WINDOW = 5  # samples: the shortest window a detector is given
# the longest window a plan takes: 10 M samples (80 MB a window in float64, hours at any rate
# these sensors record), or an hour; beyond, one window's copy would not fit a machine
MAX_WINDOW = 10_000_000
MAX_WINDOW_MS = 3_600_000.0
LOW_N = 10  # test trials (clusters) per class below which a cell's intervals undercover
# a slip onset counts as detected within this delay: a grasp controller's reaction budget
MAX_DELAY_MS = 200.0
# a unit's columns, in recordings and in cell keys: its sensor type (the paper's sensors) and
# its instance (the finger); code names them by these constants, never spelled again
SENSOR_TYPE, SENSOR_INSTANCE = "sensor_type", "sensor_instance"
# the recordings column of a dataset combined from two (slipbench.data.transfer): "train" or
# "test", the side of the 'datasets' split each recording lies on
DATASET_SIDE = "dataset_side"

# ----------------------------------------------------------------------------- orders and names
DETECTOR_ORDER = ("holweg", "lstm")  # the paper's baseline, then its model; others follow by name
SPLIT_ORDER = ("plain", "lag", False, True)  # the paper's decimation first, without a filter first
KEY_ORDER = (
    SENSOR_TYPE,
    SENSOR_INSTANCE,
    "train_instance",
    "test_instance",
)  # how a cell's key reads
ORDERS: dict[str, Sequence[Any]] = {  # the known values of a key column, in the order shown
    SENSOR_TYPE: SENSOR_ORDER,
    SENSOR_INSTANCE: INSTANCE_ORDER,
    "train_instance": INSTANCE_ORDER,
    "test_instance": INSTANCE_ORDER,
    "material": MATERIALS,
}
SHORT = {  # how a cell-key value reads in a one-line cell label, in this order after KEY_ORDER
    "window": "window {}",
    "window_ms": "({} ms)",
    "rate_hz": "{} Hz",
    "downsample": "1/{}",
    "decimation": "{}",
    "antialias": "antialiased",
    "speed_mm_s": "{} mm/s",
}


def label(column: str, value: Any) -> str:
    """How a key value reads in a table."""
    if column == SENSOR_TYPE:
        return SENSOR_NAMES.get(value, str(value))
    if column in (SENSOR_INSTANCE, "train_instance", "test_instance", "material"):
        text = str(value)
        # the paper's own fingers and materials read capitalized, as in its tables; a lab's
        # names ("ff", "hd") as the dataset spells them
        known = value in ORDERS.get(column, ()) or text in INSTANCE_ORDER
        return text.capitalize() if known and not text.isupper() else text
    if column == "speed_mm_s":
        return f"{float(value):g} mm/s"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def cell_label(cell: str | dict) -> str:
    """A cell key as a short label: "Nano17 Index window 50 (50 ms)" (sensor and unit first,
    then the other keys); a transfer reads "Index → Middle"."""
    key = json.loads(cell) if isinstance(cell, str) else dict(cell)
    order = [*KEY_ORDER, *SHORT]
    names = sorted(key, key=lambda k: order.index(k) if k in order else len(order))
    parts: list[str] = []
    for k in names:
        v = key[k]
        if k == "test_instance" and "train_instance" in key:
            parts[-1] += f" → {label(k, v)}"
        elif (k == "downsample" and "rate_hz" in key) or (k == "antialias" and not v):
            continue  # the rate says it; no filter is the default
        elif k in SHORT:
            parts.append(SHORT[k].format(f"{v:g}" if isinstance(v, float) else v))
        else:
            parts.append(label(k, v))
    return " ".join(parts)


def sensor_pairs(recordings: pd.DataFrame) -> list[tuple[str, str]]:
    """(sensor_type, sensor_instance) pairs of a recordings table, in order of first appearance."""
    pairs = recordings[[SENSOR_TYPE, SENSOR_INSTANCE]].drop_duplicates()
    return list(pairs.itertuples(index=False, name=None))
