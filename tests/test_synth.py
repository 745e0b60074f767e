"""The simulated design of experiments: size, determinism, and the physics DESIGN.md lists."""

from __future__ import annotations

import numpy as np
import pytest

from slipbench.signals import univariate
from slipbench.spectra import amplitude_spectrum
from slipbench.synth import SENSORS, Design, generate, with_physics


def _spectrum(samples: dict, ids: list[str], fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Mean amplitude spectrum of half-second stretches of the univariate signal (2 Hz bins)."""
    n = int(fs) // 2
    signals = [univariate(samples[r]) for r in ids]
    pieces = [s[: n * (len(s) // n)].reshape(-1, n) for s in signals if len(s) >= n]
    freqs, amp = amplitude_spectrum(np.concatenate(pieces), fs)
    return freqs, amp.mean(axis=0)


def test_same_seed_same_data_and_the_scale_sets_the_size(small):
    rec, samples, labels = generate(scale=0.002, seed=5, design=Design(sensors=("BioTacSP",)))
    rec2, samples2, _ = generate(scale=0.002, seed=5, design=Design(sensors=("BioTacSP",)))
    _, samples3, _ = generate(scale=0.002, seed=6, design=Design(sensors=("BioTacSP",)))
    assert rec.equals(rec2) and all(np.array_equal(samples[k], samples2[k]) for k in samples)
    assert not np.array_equal(samples[rec["recording_id"][0]], samples3[rec["recording_id"][0]])
    # 8,000 s per unit at scale 1.0, i.e. ~8 M samples at 1 kHz; the scale-0.02 fixture holds 160 s
    per_unit = small.recordings.assign(n=[len(small.samples[r]) for r in small.recordings["recording_id"]])
    seconds = per_unit.groupby(["sensor_type", "sensor_instance"]).apply(lambda g: (g["n"] / g["sampling_rate_hz"]).sum())
    assert seconds.between(0.02 * 8000 * 0.98, 0.02 * 8000 * 1.02).all(), seconds


def test_channels_units_and_slip_labels(small):
    for sensor, model in SENSORS.items():
        rec = small.recordings[small.recordings["sensor_type"] == sensor]
        assert set(rec["sensor_instance"]) == set(model.instances)
        assert all(len(small.samples[r][0]) == len(model.channels) for r in rec["recording_id"])
        assert (rec["sampling_rate_hz"] == model.rate_hz).all()
    slip = small.recordings.loc[small.recordings["scenario"] == "slip", "recording_id"]
    still = small.recordings.loc[small.recordings["scenario"] != "slip", "recording_id"]
    assert np.mean([small.slip_labels[r].mean() for r in slip]) > 0.8  # the contact slides most of the time...
    assert not any(small.slip_labels[r].any() for r in still)  # ...and never outside slip trials


def test_arm_idle_vibration_reaches_nano17_but_not_optoforce20(small):
    rec = small.recordings
    peaks = {}
    for sensor in ("Nano17", "OptoForce20"):
        ids = list(rec.loc[(rec["sensor_type"] == sensor) & (rec["scenario"] == "press"), "recording_id"])
        freqs, amp = _spectrum(small.samples, ids, 1000.0)
        near = (freqs > 180) & (freqs < 220) & (np.abs(freqs - 200) > 3)
        peaks[sensor] = amp[freqs == 200][0] / np.median(amp[near])
    assert peaks["Nano17"] > 5 and peaks["OptoForce20"] < 2, peaks


def test_stick_slip_snaps_carry_the_slip_signature():
    """Without snaps, slip loses most of its content around the finger's resonance (60-70 Hz)."""
    design = Design(sensors=("Nano17",), materials=("aluminum",), slip_speeds=(50.0,))
    bands = {}
    for name, d in (("snaps", design), ("none", with_physics(design, snap_n_per_n=0.0))):
        rec, samples, _ = generate(scale=0.05, seed=0, design=d)
        ids = list(rec.loc[rec["scenario"] == "slip", "recording_id"])
        freqs, amp = _spectrum(samples, ids, 1000.0)
        bands[name] = amp[(freqs >= 55) & (freqs <= 75)].mean()
    assert bands["snaps"] > 3 * bands["none"], bands


def test_scale_must_be_positive():
    with pytest.raises(ValueError, match="scale must be > 0"):
        generate(scale=0.0)
