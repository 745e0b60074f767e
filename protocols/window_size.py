"""Window size (Van Wyk & Falco, section VI.A, Table I): windows of 5 to 200 samples at each
sensor's full rate, trained and tested per sensor instance."""

from __future__ import annotations

from slipbench.base import BaseProtocol, Cell, Part

WINDOWS = (5, 10, 25, 50, 100, 200)


def sensor_pairs(recordings) -> list[tuple[str, str]]:
    """(sensor_type, instance) pairs of a dataset, in order of first appearance."""
    pairs = recordings[["sensor_type", "sensor_instance"]].drop_duplicates()
    return list(pairs.itertuples(index=False, name=None))


class WindowSize(BaseProtocol):
    name = "window-size"
    table = {
        "title": "Slip state classification accuracy (%) at various window sizes",
        "rows": ["sensor_type", "sensor_instance"], "columns": "window",
    }

    def cells(self, recordings):
        for sensor in sensor_pairs(recordings):
            part = (sensor,)
            for window in WINDOWS:
                yield Cell(
                    key={"sensor_type": sensor[0], "sensor_instance": sensor[1], "window": window},
                    train=Part(part, "train"), test=Part(part, "test"), window=window,
                )
