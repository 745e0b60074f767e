"""Sampling rate (Van Wyk & Falco, section VI.B, Table II): windows of 200 samples at full rate,
downsampled by 2 to 32 (Nano17 and OptoForce20: 500 to 31.25 Hz; BioTac SP: 425 to 26.56 Hz).

``decimation="plain"`` (the default) keeps every k-th sample, as the paper does, so content
above the new Nyquist frequency aliases into the band; ``"antialias"`` low-passes each recording
first (see ``Signals.antialiased``); ``"both"`` runs both. Factor 1, the full rate, is included
as the reference column.
"""

from __future__ import annotations

from slipbench.params import Interval, Options, Sequence, WindowLength
from slipbench.protocol import BaseProtocol, Cell, Layout, Part, sensor_pairs, unit_rate, window_cells

FACTORS = (1, 2, 4, 8, 16, 32)


class SamplingRate(BaseProtocol):
    """Accuracy against sampling rate, windows of 200 full-rate samples downsampled (Table II)."""

    layout = Layout(
        "Slip state classification at various sampling rates (Hz) across sensors and fingers, window 200 "
        "downsampled. Superscripts indicate the sensor type for the selected sampling rate.",
        ("sensor_type", "sensor_instance"), "downsample", title="Sampling rate", group="at Sampling Rate",
        split="decimation", column_label="rate_hz", figure="curve", x="rate_hz", x_label="sampling rate (Hz)",
        log_base=2, paper_table="sampling-rate")
    _parameter_constraints = {"decimation": Options(("plain", "antialias", "both")), "window": WindowLength(),
                              "factors": Sequence(Interval(int, 1, 1024))}

    def __init__(self, decimation="plain", window=200, factors=FACTORS):
        self.decimation = decimation
        self.window = window
        self.factors = factors

    def cells(self, recordings):
        variants = ("plain", "antialias") if self.decimation == "both" else (self.decimation,)
        factors = [self.factors] if isinstance(self.factors, int) else self.factors
        for sensor in sensor_pairs(recordings):
            rate = unit_rate(recordings, sensor)
            (n, key, short), = window_cells(recordings, sensor, self.window)
            for variant in variants:
                for factor in factors:
                    too_few = "" if n // factor >= 5 else f"window {n} downsampled by {factor} leaves {n // factor} samples"
                    yield Cell(
                        key={"sensor_type": sensor[0], "sensor_instance": sensor[1], "window": n,
                             "downsample": factor, "rate_hz": rate / factor, "decimation": variant},
                        train=Part((sensor,), "train"), test=Part((sensor,), "test"),
                        window=n, downsample=factor, decimation=variant if factor > 1 else "plain",
                        skip=short or too_few,
                    )
