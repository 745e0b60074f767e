"""Small datasets shaped like labs' recordings that slipbench once read without saying what it
did with them (issue 54): every object its own material, and slip labels that come in bursts too
short for a long window's majority. Each builder writes a dataset folder and reads it back."""

from __future__ import annotations

import numpy as np
import pandas as pd

from slipbench.data.format import Dataset
from slipbench.data.read import read_dataset
from slipbench.data.write import write_dataset


def _row(rid: str, unit: tuple[str, str], x: np.ndarray, rate: float, **meta) -> dict:
    return dict(
        recording_id=rid,
        sensor_type=unit[0],
        sensor_instance=unit[1],
        scenario=meta.get("scenario", "hold-slip"),
        material=meta.get("material"),
        speed_mm_s=meta.get("speed"),
        sampling_rate_hz=rate,
        channels=tuple(f"c{i}" for i in range(x.shape[1])),
        units=("count",) * x.shape[1],
        source="test lab",
        trial=meta.get("trial", rid),
    )


def objects_as_materials(
    folder, trials: int = 12, units: tuple[str, ...] = ("index", "middle"), seed: int = 0
) -> Dataset:
    """Hold-slip trials at 100 Hz with per-sample labels, each grasping another object that the
    lab logged as its material (``obj-0``, ``obj-1``, ...): every trial is its own material, so
    balancing within material makes one slip stratum and one held-contact stratum per trial.
    Trials slip for 10 to 90 % of their 400 samples (one of them only briefly), so those strata
    are uneven and the smallest sets what each keeps. Both fingers share each trial."""
    rng = np.random.default_rng(seed)
    rows, samples, labels = [], {}, {}
    n = 400
    slip = np.linspace(0.1, 0.9, trials)[rng.permutation(trials)]
    slip[0] = 0.06  # a brief slip: its stratum holds the fewest slip windows
    for k in range(trials):
        onset = int(n * (1 - slip[k]))
        for finger in units:
            x = rng.normal(0, 0.02, (n, 3)).cumsum(axis=0) + 5
            x[onset:] += rng.normal(0, 0.5, (n - onset, 3))
            rid = f"{finger}-obj{k}"
            samples[rid] = x
            labels[rid] = np.arange(n) >= onset
            rows.append(
                _row(
                    rid,
                    ("Nano17", finger),
                    x,
                    100.0,
                    material=f"obj-{k}",
                    speed=25.0,
                    trial=f"t{k}",
                )
            )
    return read_dataset(
        write_dataset(folder / "objects-as-materials", pd.DataFrame(rows), samples, labels)
    )


def bursty_labels(folder, trials: int = 8, seed: int = 0) -> Dataset:
    """Finger IMUs at 5 Hz whose per-frame slip labels come in bursts of 4 frames every 20:
    a window of 5 frames can be mostly slip, one of 50 never is (its majority is non-slip)."""
    rng = np.random.default_rng(seed)
    rows, samples, labels = [], {}, {}
    n = 200
    for k in range(trials):
        x = rng.normal(0, 1, (n, 6)).cumsum(axis=0)
        phase = (np.arange(n) + k) % 20
        lab = (phase >= 10) & (phase < 14)  # every trial holds before its first burst
        x[lab] += rng.normal(0, 3, (int(lab.sum()), 6))
        rid = f"imu-{k}"
        samples[rid] = x
        labels[rid] = lab
        rows.append(_row(rid, ("IMU", "index"), x, 5.0, material="box", speed=25.0))
    return read_dataset(write_dataset(folder / "bursty", pd.DataFrame(rows), samples, labels))


def few_windows(folder, per_scenario: int = 3, seed: int = 0) -> Dataset:
    """One unit at 100 Hz with ``per_scenario`` slip and pressing recordings of 110 samples:
    windows of 100 samples give one window each, so the paper split trains on 3 windows."""
    rng = np.random.default_rng(seed)
    rows, samples = [], {}
    for scenario, spread in (("slip", 1.0), ("press", 0.3)):
        for k in range(per_scenario):
            x = rng.normal(0, spread, (110, 3)).cumsum(axis=0)
            rid = f"{scenario}-{k}"
            samples[rid] = x
            rows.append(
                _row(
                    rid,
                    ("Nano17", "index"),
                    x,
                    100.0,
                    scenario=scenario,
                    material="box",
                    speed=25.0 if scenario == "slip" else None,
                )
            )
    return read_dataset(write_dataset(folder / "few-windows", pd.DataFrame(rows), samples))
