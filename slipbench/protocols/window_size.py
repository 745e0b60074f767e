"""Window size (Van Wyk & Falco, section VI.A, Table I): windows of 5 to 200 samples at each
sensor's full rate, trained and tested per sensor instance. ``windows`` takes samples or
milliseconds ("50ms", converted per sensor by its rate), not a mix."""

from __future__ import annotations

from slipbench.errors import UsageError
from slipbench.params import Sequence, WindowLength
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

WINDOWS = (5, 10, 25, 50, 100, 200)
IN_SAMPLES = Layout(rows=(SENSOR_TYPE, "sensor_instance"), column="window")
IN_MS = Layout(rows=(SENSOR_TYPE, "sensor_instance"), column="window_ms")
CAPTION = "Slip state classification at various window sizes across {sensors}."
SHOWN_IN_SAMPLES = Presentation(
    CAPTION,
    title="Window size",
    group="at Window Size",
    note_column="window_ms",
    figure="curve",
    x_label="window (samples)",
    log_base=10,
    paper_table="window-size",
)
SHOWN_IN_MS = Presentation(
    CAPTION,
    title="Window size",
    group="at Window Size (ms)",
    note_column="window",
    figure="curve",
    x_label="window (ms)",
    log_base=10,
)


class WindowSize(BaseProtocol):
    """Accuracy against window length, per sensor unit (the paper's Table I)."""

    _parameter_constraints = {"windows": Sequence(WindowLength())}

    def __init__(self, windows=WINDOWS):
        self.windows = windows

    @property
    def _in_ms(self) -> list[bool]:
        return [
            isinstance(w, str)
            for w in (self.windows if isinstance(self.windows, (list, tuple)) else [self.windows])
        ]

    @property
    def layout(self) -> Layout:
        return IN_MS if all(self._in_ms) else IN_SAMPLES

    @property
    def presentation(self) -> Presentation:
        # the published table is in samples: a table in milliseconds has no paper beside it
        return SHOWN_IN_MS if all(self._in_ms) else SHOWN_IN_SAMPLES

    def validate_params(self) -> None:
        super().validate_params()
        if len(set(self._in_ms)) > 1:
            raise UsageError(
                f"The 'windows' option of window-size takes samples or milliseconds, not both; "
                f"got {self.windows!r}"
            )

    def cells(self, recordings):
        for sensor in sensor_pairs(recordings):
            for window, key, skip in window_cells(recordings, sensor, self.windows):
                yield Cell(
                    key={SENSOR_TYPE: sensor[0], "sensor_instance": sensor[1], **key},
                    train=Part((sensor,), "train"),
                    test=Part((sensor,), "test"),
                    window=window,
                    skip=skip,
                )
