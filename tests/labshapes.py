"""Small datasets shaped like labs' recordings as they come: units wired in other orders, a
slow sensor logged faster (repeated rows), a jittery logger, a time column with gaps, a slow
IMU with bursty per-frame labels. Each builder writes a dataset and returns it read."""

from __future__ import annotations

import numpy as np
import pandas as pd

from slipbench.data.format import Dataset
from slipbench.data.read import read_dataset
from slipbench.data.write import write_dataset

FORCE = (("fx", "N"), ("fy", "N"), ("fz", "N"))


def holdslip(
    folder,
    layouts: dict[str, tuple[tuple[str, str], ...]] | None = None,
    trials: int = 6,
    n: int = 400,
    rate: float = 1000.0,
    seed: int = 7,
) -> Dataset:
    """Hold-slip trials of Nano17 units (per-sample labels, both classes in each trial).
    ``layouts``: per unit (instance), its channels as (name, unit) pairs in column order; a
    channel's values follow its name, wherever its column lies, so that units wired in other
    orders hold the same physics. Default: index and middle, both (fx, fy, fz) in N."""
    layouts = layouts or {"index": FORCE, "middle": FORCE}
    rng = np.random.default_rng(seed)
    rows, samples, slip = [], {}, {}
    for unit, layout in layouts.items():
        for k in range(trials):
            onset = n // 3 + 10 * k
            # per name, a quiet drift that shakes after the onset; fx shakes most
            by_name = {}
            for j, name in enumerate(sorted({c for c, _ in layout})):
                x = rng.normal(0, 0.02, n).cumsum() + 5 + j
                x[onset:] += rng.normal(0, 0.8 if name == "fx" else 0.1, n - onset)
                by_name[name] = x
            rid = f"{unit}-{k}"
            samples[rid] = np.stack([by_name[c] for c, _ in layout], axis=1)
            lab = np.zeros(n, bool)
            lab[onset:] = True
            slip[rid] = lab
            rows.append(
                dict(
                    recording_id=rid,
                    sensor_type="Nano17",
                    sensor_instance=unit,
                    scenario="hold-slip",
                    material=("foam", "wood")[k % 2],
                    speed_mm_s=25.0,
                    sampling_rate_hz=rate,
                    channels=tuple(c for c, _ in layout),
                    units=tuple(u for _, u in layout),
                    source="lab shapes",
                    trial=f"{unit}-t{k}",
                )
            )
    return read_dataset(write_dataset(folder / "holdslip", pd.DataFrame(rows), samples, slip))


def slow_imu(folder, rate: float = 4.8, trials: int = 12, n: int = 120, seed: int = 3) -> Dataset:
    """A finger IMU at ``rate`` Hz (a few Hz: bandpass's 50-400 Hz band lies above Nyquist)
    whose per-frame labels come in bursts of 1-2 frames, each burst shaking the readings."""
    rng = np.random.default_rng(seed)
    rows, samples, slip = [], {}, {}
    for k in range(trials):
        lab = np.zeros(n, bool)
        for start in rng.choice(np.arange(5, n - 3), size=n // 10, replace=False):
            lab[start : start + rng.integers(1, 3)] = True
        a = rng.normal(0, 0.05, (n, 3)).cumsum(0) + 9.8
        a[lab] += rng.normal(0, 1.5, (int(lab.sum()), 3))
        rid = f"imu-{k}"
        samples[rid], slip[rid] = a, lab
        rows.append(
            dict(
                recording_id=rid,
                sensor_type="IMU",
                sensor_instance="index",
                scenario="hold-slip",
                material=("foam", "wood")[k % 2],
                speed_mm_s=None,
                sampling_rate_hz=rate,
                channels=("ax", "ay", "az"),
                units=("m/s^2",) * 3,
                source="lab shapes",
                trial=f"t{k}",
            )
        )
    return read_dataset(write_dataset(folder / "imu", pd.DataFrame(rows), samples, slip))
