"""Sampling rate (Van Wyk & Falco, section VI.B, Table II): windows of 200 samples at full rate,
downsampled by 2 to 32 (Nano17 and OptoForce20: 500 to 31.25 Hz; BioTac SP: 425 to 26.56 Hz).

``decimation="plain"`` (the default) keeps every k-th sample, as the paper does, so content
above the new Nyquist frequency aliases into the band; ``"antialias"`` low-passes each recording
first (see ``Signals.antialiased``); ``"both"`` runs both. Factor 1, the full rate, is included
as the reference column.
"""

from __future__ import annotations

from slipbench.base import BaseProtocol, Cell, Options, Part
from slipbench.data import sensor_pairs
from slipbench.errors import UsageError

FACTORS = (1, 2, 4, 8, 16, 32)
WINDOW = 200
DECIMATION = Options(("plain", "antialias", "both"))


class SamplingRate(BaseProtocol):
    name = "sampling-rate"
    table = {
        "title": "Slip state classification accuracy (%) at various sampling rates (Hz)",
        "rows": ["sensor_type", "sensor_instance"], "columns": "downsample",
    }

    def __init__(self, decimation="plain"):
        if not DECIMATION.check(decimation):
            raise UsageError(f"The 'decimation' option of sampling-rate must be {DECIMATION}. Got {decimation!r} instead.")
        self.decimation = decimation

    def cells(self, recordings):
        rates = recordings.groupby(["sensor_type", "sensor_instance"])["sampling_rate_hz"].first()
        variants = ("plain", "antialias") if self.decimation == "both" else (self.decimation,)
        for sensor in sensor_pairs(recordings):
            for variant in variants:
                for factor in FACTORS:
                    yield Cell(
                        key={"sensor_type": sensor[0], "sensor_instance": sensor[1], "window": WINDOW,
                             "downsample": factor, "rate_hz": rates[sensor] / factor, "decimation": variant},
                        train=Part((sensor,), "train"), test=Part((sensor,), "test"),
                        window=WINDOW, downsample=factor, decimation=variant if factor > 1 else "plain",
                    )
