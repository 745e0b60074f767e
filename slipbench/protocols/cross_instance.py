"""Manufacturing variability (Van Wyk & Falco, section VIII, Table V): window 50 at full rate.
A model trained on one instance (finger) of a sensor type is tested on every instance of that
type, and a model trained on all instances combined is tested on each and on the combined set."""

from __future__ import annotations

from slipbench.params import WindowLength
from slipbench.protocol import (
    BaseProtocol,
    Cell,
    Layout,
    Part,
    Presentation,
    sensor_pairs,
    window_cells,
)
from slipbench.vocabulary import SENSOR_TYPE

COMBINED = "combined"


class CrossInstance(BaseProtocol):
    """Train on one unit (or all combined), test on every unit of its type (the paper's Table V)."""

    layout = Layout(rows=(SENSOR_TYPE, "train_instance"), column="test_instance")
    presentation = Presentation(
        "Classification trained and tested on data from one or all fingers of a single sensor type.",
        title="Cross-instance transfer",
        merge_rows=True,
        figure="matrix",
        paper_table="cross-instance",
    )
    _parameter_constraints = {"window": WindowLength()}

    def __init__(self, window=50):
        self.window = window

    def cells(self, recordings):
        by_type: dict[str, list[tuple[str, str]]] = {}
        for sensor in sensor_pairs(recordings):
            by_type.setdefault(sensor[0], []).append(sensor)
        for sensor_type, sensors in by_type.items():
            groups = {s[1]: (s,) for s in sensors} | {COMBINED: tuple(sensors)}
            lengths = {
                window for s in sensors for window, _, _ in window_cells(recordings, s, self.window)
            }
            ((n, _, short),) = window_cells(recordings, sensors[0], self.window)
            skip = short or (
                f"{self.window} is {sorted(lengths)} samples on the units of {sensor_type}: units with "
                "different rates cannot share a model"
                if len(lengths) > 1
                else ""
            )
            alone = (
                f"sensor type {sensor_type} has one instance: nothing to transfer to"
                if len(sensors) < 2
                else ""
            )
            for train_name, train in groups.items():
                for test_name, test in groups.items():
                    yield Cell(
                        key={
                            SENSOR_TYPE: sensor_type,
                            "train_instance": train_name,
                            "test_instance": test_name,
                        },
                        train=Part(train, "train"),
                        test=Part(test, "test"),
                        window=n,
                        skip=skip
                        or (
                            alone
                            if COMBINED in (train_name, test_name) or train_name != test_name
                            else ""
                        ),
                    )
