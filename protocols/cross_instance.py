"""Manufacturing variability (Van Wyk & Falco, section VIII, Table V): window 50 at full rate.
A model trained on one instance (finger) of a sensor type is tested on every instance of that
type, and a model trained on all instances combined is tested on each and on the combined set."""

from __future__ import annotations

from slipbench.base import BaseProtocol, Cell, Part
from slipbench.data import sensor_pairs

WINDOW = 50
COMBINED = "combined"


class CrossInstance(BaseProtocol):
    name = "cross-instance"
    table = {
        "title": "Classification accuracy (%) trained and tested on one or all instances of a sensor type",
        "rows": ["sensor_type", "train_instance"], "columns": "test_instance",
    }

    def cells(self, recordings):
        by_type: dict[str, list[tuple[str, str]]] = {}
        for sensor in sensor_pairs(recordings):
            by_type.setdefault(sensor[0], []).append(sensor)
        for sensor_type, sensors in by_type.items():
            groups = {s[1]: (s,) for s in sensors} | {COMBINED: tuple(sensors)}
            skip = f"sensor type {sensor_type} has one instance: nothing to transfer to" if len(sensors) < 2 else ""
            for train_name, train in groups.items():
                for test_name, test in groups.items():
                    yield Cell(
                        key={"sensor_type": sensor_type, "train_instance": train_name, "test_instance": test_name},
                        train=Part(train, "train"), test=Part(test, "test"), window=WINDOW,
                        skip=skip if COMBINED in (train_name, test_name) or train_name != test_name else "",
                    )
