"""Sampling rate (Van Wyk & Falco, section VI.B, Table II): windows of 200 samples at full rate,
seen by a sensor 2 to 32 times slower (Nano17 and OptoForce20: 500 to 31.25 Hz; BioTac SP: 425
to 26.56 Hz). Factor 1, the full rate, is the reference column of every table.

How the slower sensor's samples are made is two independent choices (``Windows.downsample``,
``Signals.antialiased``), and every cell says which in its key:

- ``decimation``: ``"plain"`` (default) keeps every k-th sample of the full-rate difference
  s_t = ||a_t|| - ||a_{t-1}||; ``"lag"`` takes ||a_t|| - ||a_{t-k}|| on every k-th sample, the
  difference a sensor sampled k times slower gives; ``"both"`` runs both.
- ``antialias``: ``False`` (default) decimates the raw norm, so content above the new Nyquist
  frequency aliases into the band; ``True`` low-passes the norm first (causal 4th-order
  Butterworth at 0.8 x the new Nyquist), as a sensor's anti-aliasing filter would; ``"both"``.

Which one the paper ran is ambiguous. It "downsampled by a factor of two by omitting every other
sensor reading within a sample sequence" the "datasets with a window size of 200 samples". Its
balancing section (II.D, windows of the data) precedes its preprocessing section (II.E, the
difference), and raw readings a_t decimated before differencing give ``lag``. But the paper
calls the values passed to the classifier "sensor readings" too ("window size dictates the number
of sequential sensor readings that are passed to a classifier", section VI.A), and those are
values of s: omitting every other one of them gives ``plain``. The default stays ``plain``, the
reading this project has reproduced so far, the paper's own words for what a window holds
favouring it slightly; results name the decimation, and the README gives the difference.
"""

from __future__ import annotations

from slipbench.params import Interval, Options, Sequence, WindowLength
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
from slipbench.vocabulary import MIN_WINDOW, SENSOR_TYPE

FACTORS = (1, 2, 4, 8, 16, 32)


class SamplingRate(BaseProtocol):
    """Accuracy against sampling rate, windows of 200 full-rate samples downsampled (Table II)."""

    layout = Layout(
        rows=(SENSOR_TYPE, "sensor_instance"),
        column="downsample",
        split=("decimation", "antialias"),
    )
    presentation = Presentation(
        "Slip state classification at various sampling rates (Hz) across sensors and fingers, "
        "window {window} downsampled. Superscripts indicate the sensor type for the selected "
        "sampling rate.",
        title="Sampling rate",
        group="at Sampling Rate",
        column_label="rate_hz",
        figure="curve",
        x="rate_hz",
        x_label="sampling rate (Hz)",
        log_base=2,
        paper_table="sampling-rate",
    )
    _parameter_constraints = {
        "decimation": Options(("plain", "lag", "both")),
        "antialias": Options((False, True, "both")),
        "window": WindowLength(),
        "factors": Sequence(Interval(int, 1, 1024)),
    }

    def __init__(self, decimation="plain", antialias=False, window=200, factors=FACTORS):
        self.decimation = decimation
        self.antialias = antialias
        self.window = window
        self.factors = factors

    def cells(self, recordings):
        decimations = ("plain", "lag") if self.decimation == "both" else (self.decimation,)
        filters = (False, True) if self.antialias == "both" else (bool(self.antialias),)
        factors = [self.factors] if isinstance(self.factors, int) else self.factors
        for sensor in sensor_pairs(recordings):
            rate = unit_rate(recordings, sensor)
            ((n, key, short),) = window_cells(recordings, sensor, self.window)
            for decimation in decimations:
                for antialias in filters:
                    for factor in factors:
                        too_few = (
                            ""
                            if n // factor >= MIN_WINDOW
                            else f"window {n} downsampled by {factor} leaves {n // factor} samples"
                        )
                        # the full-rate cell of every variant shares one model (the plan keys it so)
                        yield Cell(
                            key={
                                SENSOR_TYPE: sensor[0],
                                "sensor_instance": sensor[1],
                                "window": n,
                                "downsample": factor,
                                "rate_hz": rate / factor,
                                "decimation": decimation,
                                "antialias": antialias,
                            },
                            train=Part((sensor,), "train"),
                            test=Part((sensor,), "test"),
                            window=n,
                            downsample=factor,
                            decimation=decimation,
                            antialias=antialias,
                            skip=short or too_few,
                        )
