"""Window size (Van Wyk & Falco, section VI.A, Table I): windows of 5 to 200 samples at each
sensor's full rate, trained and tested per sensor instance."""

from __future__ import annotations

from slipbench.base import BaseProtocol, Cell, Part
from slipbench.data import sensor_pairs

WINDOWS = (5, 10, 25, 50, 100, 200)


class WindowSize(BaseProtocol):
    name = "window-size"
    table = {
        "title": "Slip state classification accuracy (%) at various window sizes",
        "rows": ["sensor_type", "sensor_instance"], "columns": "window",
    }

    def cells(self, recordings):
        for sensor in sensor_pairs(recordings):
            for window in WINDOWS:
                yield Cell(
                    key={"sensor_type": sensor[0], "sensor_instance": sensor[1], "window": window},
                    train=Part((sensor,), "train"), test=Part((sensor,), "test"), window=window,
                )
