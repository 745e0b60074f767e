"""Streaming (issue 10): how soon a detector notices slip, and how often it cries wolf.

Per sensor unit, a model trained as usual on balanced windows of the training trials is run
causally over every test recording of the unit with per-sample labels, one score every ``hop``
samples (:mod:`slipbench.base`), and scored by :mod:`slipbench.stream.metrics`: detection rate and
delay per slip onset within ``max_delay_ms``, false alarms per minute of non-slip time. Test
trials are never trained on: whatever the run's split, streaming holds out whole trials
(``trial_sides`` with the run's seed; with ``--split datasets``, the test dataset). ``window``
and ``hop`` take samples or milliseconds ("50ms"), both in the same unit.
"""

from __future__ import annotations

from slipbench.base import DEFAULT_HOP
from slipbench.errors import UsageError
from slipbench.params import Interval, WindowLength, parse_ms, window_samples
from slipbench.protocol import (
    BaseProtocol,
    Cell,
    Layout,
    Part,
    Presentation,
    sensor_pairs,
    unit_rate,
    window_cells,
)
from slipbench.vocabulary import MAX_DELAY_MS, SENSOR_TYPE

METRICS = ("detection_rate", "median_delay_ms", "p95_delay_ms", "false_alarms_per_min")
LAYOUT = Layout(rows=(SENSOR_TYPE, "sensor_instance"), column="window", metrics=METRICS)


class Streaming(BaseProtocol):
    """Detection rate, delay and false alarms per minute of a detector run causally (issue 10)."""

    _parameter_constraints = {
        "window": WindowLength(),
        "hop": WindowLength(low=1),
        "max_delay_ms": Interval(float, 1.0, 60_000.0),
    }
    layout = LAYOUT
    presentation = Presentation(
        "Slip onsets detected, their delays and false alarms while streaming test recordings, "
        "per sensor unit.",
        title="Streaming",
        group="At the detector's own threshold (0.5)",
        figure="tradeoff",
        x="false_alarms_per_min",
        x_label="false alarms per minute",
    )

    def __init__(self, window=50, hop=DEFAULT_HOP, max_delay_ms=MAX_DELAY_MS):
        self.window = window
        self.hop = hop
        self.max_delay_ms = max_delay_ms

    def validate_params(self) -> None:
        super().validate_params()
        if isinstance(self.window, str) != isinstance(self.hop, str):
            raise UsageError(
                f"The 'window' and 'hop' options of streaming take samples or milliseconds, both the same; "
                f"got window={self.window!r}, hop={self.hop!r}"
            )
        if isinstance(self.window, str):
            hop_ms, window_ms = parse_ms(self.hop), parse_ms(self.window)
            assert hop_ms is not None and window_ms is not None  # both checked by super()
            too_long = hop_ms > window_ms
        else:
            too_long = self.hop > self.window
        if too_long:
            raise UsageError(
                f"The 'hop' option of streaming must not exceed the window: a score every {self.hop} "
                f"leaves samples no window sees; got hop={self.hop!r}, window={self.window!r}"
            )

    def cells(self, recordings):
        for sensor in sensor_pairs(recordings):
            ((n, key, skip),) = window_cells(recordings, sensor, self.window)
            rate = unit_rate(recordings, sensor)
            hop = window_samples(self.hop, rate)
            if not skip and hop < 1:
                skip = f"hop {self.hop} is less than one sample at {rate:g} Hz"
            hop = min(
                max(hop, 1), n
            )  # only a skipped cell is clipped; the option's check keeps hop <= window
            yield Cell(
                {SENSOR_TYPE: sensor[0], "sensor_instance": sensor[1], **key, "hop": hop},
                Part((sensor,), "train"),
                Part((sensor,), "test"),
                n,
                stream={"hop": hop, "max_delay_ms": float(self.max_delay_ms)},
                skip=skip,
            )
