"""Small datasets shaped like labs' recordings as they come: units wired in other orders, a
slow sensor logged faster (repeated rows), a jittery logger, a time column with gaps, a slow
IMU with bursty per-frame labels, every object its own material, slip labels in bursts too short
for a long window's majority, and too few windows. Each builder writes a dataset folder and
returns it read back."""

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


def slow_sensor_logs(
    src, files: int = 6, hold: int = 4, logger_hz=(40.0,), gaps: int = 0, seed: int = 5
) -> None:
    """CSV files of a pad (two taxels, integer counts) whose sensor updates every ``hold``
    logger rows (a 10 Hz sensor logged at 40 Hz: hold 4), a time column ``t`` in s: file k
    logged at ``logger_hz[k % len(logger_hz)]`` with 3 % jitter on each step, and ``gaps``
    steps three times as long as the others in each file. A ``state`` column labels rows
    (hold, then slip)."""
    rng = np.random.default_rng(seed)
    src.mkdir(parents=True, exist_ok=True)
    for k in range(files):
        n = 240
        rate = logger_hz[k % len(logger_hz)]
        step = (1 / rate) * (1 + rng.uniform(-0.03, 0.03, n - 1))
        step[rng.choice(np.arange(10, n - 10), gaps, replace=False)] *= 3
        t = np.r_[0.0, np.cumsum(step)]
        updates = rng.normal(0, 3, (n // hold + 1, 2)).cumsum(0) + 500
        values = np.repeat(updates, hold, axis=0)[:n].round().astype(int)
        state = np.where(np.arange(n) < n // 2, "hold", "slip")
        pd.DataFrame(
            {"t": t.round(6), "taxel_0": values[:, 0], "taxel_1": values[:, 1], "state": state}
        ).to_csv(src / f"trial_{k}.csv", index=False)


def late_logs(src, files: int = 12, late: dict[int, int] | None = None, n: int = 60) -> None:
    """CSV files of a finger IMU's hold-slip trials at 10 Hz (``state`` per row: hold, slip,
    hold, slip) whose logger started late in some: file k of ``late`` (default 2 of 12, as 11
    of 192 in a real IMU set) starts in slip for its first ``late[k]`` rows, then holds."""
    late = {3: 4, 8: 7} if late is None else late
    src.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(11)
    for k in range(files):
        state = np.array(["hold"] * n, dtype=object)
        state[20:28] = "slip"
        state[40:] = "slip"
        state[: late.get(k, 0)] = "slip"
        a = rng.normal(0, 0.1, (n, 3)).cumsum(0) + 9.8
        pd.DataFrame({"ax": a[:, 0], "ay": a[:, 1], "az": a[:, 2], "state": state}).round(6).to_csv(
            src / f"imu_{k:02d}.csv", index=False
        )


LATE_MAPPING = {
    "files": ["*.csv"],
    "recording": {"sensor_type": "IMU", "sensor_instance": "index", "scenario": "hold-slip"},
    "channels": {"names": ["ax", "ay", "az"], "units": "m/s^2"},
    "rate": {"hz": 10.0},
    "labels": {"column": "state", "slip": ["slip"], "no_slip": ["hold"]},
}


LOG_MAPPING = {
    "files": ["*.csv"],
    "recording": {"sensor_type": "Pad", "sensor_instance": "left", "scenario": "hold-slip"},
    "channels": {"pattern": "taxel_.*", "units": "count"},
    "labels": {"column": "state", "slip": ["slip"], "no_slip": ["hold"]},
}


def repeated_rows(folder, hold: int = 4, rate: float = 40.0) -> Dataset:
    """A dataset whose one unit repeats each reading ``hold`` times (a 10 Hz sensor at 40 Hz)."""
    rng = np.random.default_rng(0)
    rows, samples = [], {}
    for k in range(3):
        updates = rng.normal(0, 3, (100 // hold, 2)).cumsum(0) + 500
        samples[f"r{k}"] = np.repeat(updates, hold, axis=0).round().astype(np.int64)
        rows.append(
            dict(
                recording_id=f"r{k}",
                sensor_type="Pad",
                sensor_instance="left",
                scenario=("slip", "press")[k % 2],
                material="foam",
                speed_mm_s=None,
                sampling_rate_hz=rate,
                channels=("taxel_0", "taxel_1"),
                units=("count", "count"),
                source="lab shapes",
                trial=f"t{k}",
            )
        )
    return read_dataset(write_dataset(folder / "repeated", pd.DataFrame(rows), samples))


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
