"""Planning a run: every cell of the reproduction's detectors on every protocol (grouped
split), planned on the simulated design's layout at SCALE, with the parts' recording masks as
they are (arrays, once per part) against the earlier masks (a MultiIndex built per call, per
window and detector) measured in the same run. Planning is what `slipbench run FILE --plan`
costs, and what every run spends before its first model.

    python benchmarks/bench_planning.py [SCALE]   (default 0.02)
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from tempfile import TemporaryDirectory
from unittest import mock

import numpy as np
import pandas as pd

from slipbench.app.benchspec import load_benchmark
from slipbench.app.planning import planning
from slipbench.protocol import Part

FILE = """
[dataset]
scale = {scale}
[run]
split = "grouped"
[detectors.features]
[detectors.holweg]
[detectors.bandpass]
[detectors.wavelet-svm]
[detectors.lstm]
max_epochs = 100
[protocols.window-size]
[protocols.sampling-rate]
decimation = "both"
[protocols.material-holdout]
[protocols.speed-holdout]
[protocols.cross-instance]
[protocols.streaming]
"""


def earlier_mask(self: Part, recordings: pd.DataFrame) -> np.ndarray:
    """Part.mask before: a MultiIndex of the recordings' units, built at every call."""
    pairs = pd.MultiIndex.from_frame(recordings[["sensor_type", "sensor_instance"]])
    keep = pairs.isin(list(self.sensors))
    for column, op, value in self.where:
        equal = recordings[column].eq(value).to_numpy()
        keep &= equal if op == "==" else ~equal
    return np.asarray(keep, bool)


def timed(bench) -> tuple[float, int]:
    start = time.perf_counter()
    p = planning(bench, [], lambda line: None)
    return time.perf_counter() - start, len(p.plan.cells)


def main(scale: float) -> None:
    with TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.toml"
        path.write_text(FILE.format(scale=scale))
        bench = load_benchmark(path)
        timed(bench)  # imports and caches warm
        now, cells = timed(bench)
        with (
            mock.patch.object(Part, "mask", earlier_mask),
            mock.patch(
                "slipbench.engine.plan.CellData._mask",
                lambda self, part: part.mask(self.signals.recordings),
            ),
        ):
            before, cells_before = timed(bench)
    assert cells == cells_before
    print(
        f"planning {cells} cells (5 detectors x 6 protocols, grouped split, scale {scale:g}, "
        f"laid out): {before:.1f} s with the earlier masks, {now:.1f} s now: "
        f"{before / now:.1f}x faster"
    )


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 0.02)
