"""Spectral analysis of slip and non-slip signals (section IV of Van Wyk & Falco).

One sensor type's (or one instance's) univariate signal is balanced into non-slip and slip
windows and pooled per class. Each of ``repeats`` rounds draws ``n_boot`` bootstrap sequences
per class, one second long (as many samples as the sampling rate, so FFT bins fall every 1 Hz),
takes their single-sided amplitude spectra from 0 Hz to Nyquist, and runs a two-sample
Kolmogorov-Smirnov test per frequency between the two classes' ``n_boot`` amplitudes. The
*significance* of a frequency is the share of rounds whose test rejects at ``alpha``.

How a sequence is drawn
-----------------------
The balanced data are cut into windows of ``segment`` samples, each from within one recording
(never across two); a sequence is ``ceil(sequence / segment)`` windows drawn at random, with
replacement, from one class's pool and joined end to end. The default ``segment`` is the whole
sequence: every sequence is then one contiguous second of one recording, so its spectrum holds
no seams, whose steps would add broadband content of their own. A shorter ``segment`` rebuilds
the paper's pooling (balanced windows concatenated per class) and works on recordings shorter
than a second; its seams cost some broadband content in both classes.

Balancing follows :func:`slipbench.data.signals.balance` (the paper's mix), once per instance, so
every instance of a pooled sensor type contributes equally.

Without peeking
---------------
By default every recording is analysed, test data included: a band chosen there and handed to
a detector has seen what the detector is tested on. With ``split`` the analysis reads only the
training side of a run with that split and seed, the very windows the runner trains on at
window ``segment`` (50 by default): a band chosen there is free of test data for every cell at
that window of runs with the same dataset, split and seed. Cells at another window are balanced
and split on their own, so their test side may hold samples the analysis read: analyse at their
window. Windows then join into one-second sequences as the paper pools them (seams included).

Bands
-----
- a bin is *significant* when its significance is at least ``level`` (default 0.95: the test
  rejects in at least 95 % of the rounds); *significant bands* are the maximal runs of
  significant bins, gaps of up to ``merge_hz`` closed;
- the *most significant band* is the run of significant bins around the bin with the largest
  mean KS statistic (the separation of the two classes' amplitude distributions, averaged over
  the rounds; unlike the significance it does not saturate at 1), extended while a bin's mean
  statistic stays at least ``keep`` times that peak. It is the band :class:`Holweg` (and band-pass
  detectors) take as ``band=[low_hz, high_hz]``.
"""

from __future__ import annotations

import json
import os
import tempfile
from dataclasses import astuple, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.stats import ks_2samp

from slipbench.data.format import Dataset
from slipbench.data.signals import SPLITS, Signals, Windows, balance
from slipbench.errors import UsageError, writing
from slipbench.seeding import rng_for
from slipbench.spectra import amplitude_spectrum, grow_band
from slipbench.vocabulary import SENSOR_TYPE

# Bytes of sequences (float32) gathered and transformed at once: bounds peak memory.
CHUNK_BYTES = 64 * 2**20
# The window of a run's training side analysed by default: the paper's Holweg baseline, and
# the window of the material, speed and cross-instance protocols.
TRAIN_WINDOW = 50


# ----------------------------------------------------------------------------- KS test
def ks_2samp_last_axis(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two-sided two-sample KS tests along the last axis, all at once.

    Gives exactly ``scipy.stats.ks_2samp(a, b, axis=-1)`` (method ``auto``): the statistic is
    computed here by one sort of the joined samples, and each distinct statistic's p-value comes
    from scipy on one column that has it (the exact p-value depends only on the statistic and the
    two sample sizes). Why by hand: on the ~100,000 tests of one sensor instance (200 rounds x 501
    bins, 100 vs 100 amplitudes) scipy's vectorised call takes ~9.4 s on the project's 2-core
    machine, this one ~0.8 s (``benchmarks/bench_spectral.py`` measures both).

    Parameters
    ----------
    a : (..., n) first samples.
    b : (..., m) second samples; leading shape as ``a``.

    Returns
    -------
    statistic : (...) float64.
    pvalue : (...) float64.
    """
    n, m = a.shape[-1], b.shape[-1]
    z = np.concatenate([a, b], axis=-1)
    order = np.argsort(z, axis=-1)
    zs = np.take_along_axis(z, order, axis=-1)
    # m * n * (F_a - F_b) in integers: +m per value of a, -n per value of b
    cum = np.cumsum(np.where(order < n, m, -n).astype(np.int64), axis=-1)
    # among tied values only the last position counts (both CDFs evaluated after the tie)
    last = np.ones(zs.shape, dtype=bool)
    last[..., :-1] = zs[..., 1:] != zs[..., :-1]
    d = np.max(np.abs(cum) * last, axis=-1)
    values, first = np.unique(d.ravel(), return_index=True)
    a2, b2 = a.reshape(-1, n), b.reshape(-1, m)
    p = np.array([ks_2samp(a2[i], b2[i]).pvalue for i in first])
    pvalue = p[np.searchsorted(values, d)]
    return d / (n * m), pvalue


# ----------------------------------------------------------------------------- analysis
@dataclass
class SpectralResult:
    """Per-frequency spectra, significance and bands of one analysis.

    Attributes
    ----------
    table : one row per frequency bin, 0 Hz to Nyquist: ``freq_hz``; ``nonslip_mean``,
        ``nonslip_lo``, ``nonslip_hi`` and the same for ``slip`` (mean and 2.5/97.5 percentiles
        of the amplitudes over all bootstrap sequences); ``ks_statistic`` (mean over rounds);
        ``significance`` (share of rounds that reject).
    bands : (n_bands, 2) significant bands, (low_hz, high_hz) inclusive.
    best_band : (low_hz, high_hz) the most significant band, or None if no bin is significant.
    params : the parameters and sizes that produced it.
    """

    table: pd.DataFrame
    bands: list[tuple[float, float]]
    best_band: tuple[float, float] | None
    params: dict = field(default_factory=dict)

    def summary(self) -> dict:
        return {
            **self.params,
            "significant_bands": [list(b) for b in self.bands],
            "most_significant_band": list(self.best_band) if self.best_band else None,
        }


def significant_bands(
    freqs: np.ndarray, significance: np.ndarray, level: float, merge_hz: float
) -> list[tuple[float, float]]:
    """Maximal runs of bins with ``significance >= level``; gaps up to ``merge_hz`` are closed.

    Parameters
    ----------
    freqs : (n_bins,) ascending Hz.
    significance : (n_bins,) in [0, 1].
    """
    idx = np.flatnonzero(significance >= level)
    if len(idx) == 0:
        return []
    # a new band starts where the gap to the previous significant bin exceeds merge_hz
    breaks = np.flatnonzero(np.diff(freqs[idx]) > merge_hz + 1e-9)
    starts = np.r_[idx[0], idx[breaks + 1]]
    ends = np.r_[idx[breaks], idx[-1]]
    return [(float(freqs[s]), float(freqs[e])) for s, e in zip(starts, ends)]


def most_significant_band(
    freqs: np.ndarray, significance: np.ndarray, statistic: np.ndarray, level: float, keep: float
) -> tuple[float, float] | None:
    """The run of significant bins around the bin with the largest mean KS statistic, extended
    while each bin stays significant and its statistic at least ``keep`` times the peak's.

    Parameters
    ----------
    freqs, significance, statistic : (n_bins,).
    """
    inside = significance >= level
    if not inside.any():
        return None
    peak = int(np.argmax(np.where(inside, statistic, -np.inf)))
    lo, hi = grow_band(inside & (statistic >= keep * statistic[peak]), peak)
    return float(freqs[lo]), float(freqs[hi])


@dataclass(frozen=True)
class Settings:
    """The analysis's settings: ``n_boot`` sequences per class and round, ``repeats`` rounds
    (KS tests per frequency), ``alpha`` the KS test's level, ``level``, ``keep`` and
    ``merge_hz`` the band definitions (see the module docstring), ``seed`` for every draw."""

    n_boot: int = 100
    repeats: int = 200
    alpha: float = 0.05
    level: float = 0.95
    keep: float = 0.8
    merge_hz: float = 5.0
    seed: int = 0


def analyze_pools(
    nonslip: np.ndarray, slip: np.ndarray, sampling_rate: float, **settings: Any
) -> SpectralResult:
    """The bootstrap spectral analysis of two pools of windows.

    Parameters
    ----------
    nonslip : (n_nonslip, segment) windows of the non-slip class.
    slip : (n_slip, segment) windows of the slip class (same ``segment``).
    sampling_rate : Hz; a sequence holds ``round(sampling_rate)`` samples (1 Hz bins).
    settings : those of :class:`Settings` (an unknown name is a TypeError).
    """
    n_boot, repeats, alpha, level, keep, merge_hz, seed = astuple(Settings(**settings))
    _check(n_boot >= 2, f"n_boot must be an int >= 2, got {n_boot}")
    _check(repeats >= 1, f"repeats must be an int >= 1, got {repeats}")
    for name, value in (("alpha", alpha), ("level", level), ("keep", keep)):
        _check(
            0 < value <= 1 if name != "alpha" else 0 < value < 1,
            f"{name} must be in (0, 1), got {value}",
        )
    _check(
        nonslip.ndim == slip.ndim == 2 and nonslip.shape[1] == slip.shape[1] > 0,
        f"pools must be (n, segment) arrays of one segment length, got {nonslip.shape} and {slip.shape}",
    )
    _check(len(nonslip) > 0 and len(slip) > 0, "both classes need at least one window")
    length = int(round(sampling_rate))
    segment = nonslip.shape[1]
    pieces = -(-length // segment)
    rng = rng_for(seed, "spectral", "spectra")
    # all draws up front, so the chunking below cannot change them
    draws = [rng.integers(len(pool), size=(repeats, n_boot, pieces)) for pool in (nonslip, slip)]

    n_bins = length // 2 + 1
    amps = np.empty((2, repeats, n_boot, n_bins), dtype=np.float32)
    chunk = max(1, CHUNK_BYTES // (2 * n_boot * pieces * segment * 4))
    for start in range(0, repeats, chunk):
        stop = min(start + chunk, repeats)
        for c, pool in enumerate((nonslip, slip)):
            seq = pool[draws[c][start:stop]].reshape(stop - start, n_boot, pieces * segment)[
                ..., :length
            ]
            amps[c, start:stop] = amplitude_spectrum(seq, sampling_rate)[1]
    # bins every sampling_rate / length Hz (1 Hz for integer rates), exact rather than rfftfreq's
    # 1 / (length / rate) steps, which print 425.0000000000001 Hz
    freqs = np.arange(n_bins) * (sampling_rate / length)

    # KS per round and frequency: samples along the last axis
    stat = np.empty((repeats, n_bins))
    pval = np.empty((repeats, n_bins))
    ks_chunk = max(1, CHUNK_BYTES // (2 * n_boot * n_bins * 8 * 3))
    for start in range(0, repeats, ks_chunk):
        sl = slice(start, min(start + ks_chunk, repeats))
        a = np.moveaxis(amps[0, sl], 1, -1)
        b = np.moveaxis(amps[1, sl], 1, -1)
        stat[sl], pval[sl] = ks_2samp_last_axis(a, b)
    significance = (pval < alpha).mean(axis=0)
    statistic = stat.mean(axis=0)

    flat = amps.reshape(2, repeats * n_boot, n_bins)
    lo, hi = np.percentile(flat, [2.5, 97.5], axis=1)
    table = pd.DataFrame(
        {
            "freq_hz": freqs,
            "nonslip_mean": flat[0].mean(axis=0, dtype=np.float64),
            "nonslip_lo": lo[0],
            "nonslip_hi": hi[0],
            "slip_mean": flat[1].mean(axis=0, dtype=np.float64),
            "slip_lo": lo[1],
            "slip_hi": hi[1],
            "ks_statistic": statistic,
            "significance": significance,
        }
    )
    params = dict(
        sampling_rate_hz=float(sampling_rate),
        sequence_samples=length,
        segment_samples=segment,
        n_boot=n_boot,
        repeats=repeats,
        alpha=alpha,
        level=level,
        keep=keep,
        merge_hz=merge_hz,
        seed=seed,
        windows_nonslip=len(nonslip),
        windows_slip=len(slip),
    )
    return SpectralResult(
        table,
        significant_bands(freqs, significance, level, merge_hz),
        most_significant_band(freqs, significance, statistic, level, keep),
        params,
    )


def pools(
    dataset: Dataset,
    unit: tuple[str, str | None],
    segment: int | None,
    seed: int,
    split: str | None = None,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Balanced non-slip and slip windows of one sensor type (all its instances, each balanced
    on its own) or of one instance: ``unit`` is (sensor type, instance or None).

    With ``split`` ("paper" or "grouped"), only the training side of a run with that split and
    ``seed``: the balanced, split windows of ``segment`` samples that
    :class:`slipbench.engine.plan.CellData` gives the runner for a cell at window ``segment`` (default
    :data:`TRAIN_WINDOW`), so that no window a cell at that window tests on is read.

    Returns
    -------
    nonslip : (n_nonslip, segment) float32.
    slip : (n_slip, segment) float32.
    sampling_rate : Hz.
    """
    sensor, instance = unit
    recs = dataset.recordings
    types = list(dict.fromkeys(recs[SENSOR_TYPE]))
    if sensor not in types:
        raise UsageError(f"unknown sensor {sensor!r}; sensors in the dataset: {', '.join(types)}")
    recs = recs[recs[SENSOR_TYPE] == sensor]
    instances = list(dict.fromkeys(recs["sensor_instance"]))
    if instance is not None and instance not in instances:
        raise UsageError(
            f"{sensor} has no instance {instance!r}; its instances: {', '.join(instances)}"
        )
    rates = recs["sampling_rate_hz"].unique()
    if len(rates) > 1:
        raise UsageError(
            f"{sensor}: recordings at several sampling rates ({', '.join(f'{r:g}' for r in rates)} Hz); "
            "the analysis needs one"
        )
    rate = float(rates[0])
    length = int(round(rate))
    segment = (length if split is None else TRAIN_WINDOW) if segment is None else segment
    _check(
        not isinstance(segment, bool)
        and isinstance(segment, (int, np.integer))
        and 1 <= segment <= length,
        f"segment must be an int in [1, {length}] (one second of {sensor}), got {segment}",
    )
    chosen = instances if instance is None else [instance]
    if split is not None:
        return (*_training_side(dataset, sensor, chosen, int(segment), (split, seed)), rate)

    ids = set(recs["recording_id"])
    sig = Signals.from_dataset(
        Dataset(
            recs.reset_index(drop=True),
            dataset.samples,
            {k: v for k, v in dataset.slip_labels.items() if k in ids},
        )
    )
    rng = rng_for(seed, "spectral", "instances")
    parts = []
    for inst in chosen:
        rows = np.flatnonzero(sig.recordings["sensor_instance"].to_numpy() == inst)
        windows = sig.windows(segment, rows)
        _check_strata(sig, rows, windows, segment, f"{sensor} {inst}")
        parts.append(windows.take(balance(windows, rng)))
    x = np.concatenate([p.x for p in parts])
    y = np.concatenate([p.y for p in parts])
    return x[y == 0], x[y == 1], rate


def _training_side(
    dataset: Dataset, sensor: str, instances: list[str], window: int, run: tuple[str, int]
) -> tuple[np.ndarray, np.ndarray]:
    """Non-slip and slip windows, (n, window) float32, of the training side of each instance
    in a run of ``run`` (split, seed):
    the runner's own CellData, on the whole dataset as the runner builds it, so that the
    balancing and the split are the runner's whatever they depend on."""
    split, seed = run
    from slipbench.engine.plan import (
        CellData,  # the planner pulls in the registry; only this path needs it
    )

    if split not in SPLITS:
        raise UsageError(f"unknown split {split!r}; choose one of: {', '.join(SPLITS)}")
    data = CellData(Signals.from_dataset(dataset), split, seed)
    train = []
    for inst in instances:
        try:
            train.append(data.sides((sensor, inst), window)[0])
        except UsageError as exc:  # the runner's reason, said of the windows analysed
            raise UsageError(f"{sensor} {inst}, {split} split at window {window}: {exc}") from exc
    x = np.concatenate([data.signals.values(t, window) for t in train])
    y = np.concatenate([t.y for t in train])
    return x[y == 0], x[y == 1]


def _check_strata(
    sig: Signals, rows: np.ndarray, windows: Windows, segment: int, what: str
) -> None:
    """Refuse a stratum whose every recording is shorter than a segment: balancing would drop it
    silently and change the mix."""
    scenario = sig.recordings["scenario"].to_numpy()[rows]
    rows = rows[scenario != "hold-slip"]  # two states: the scenario labels none of its windows
    scenario_labels = (sig.recordings["scenario"].to_numpy()[rows] == "slip").astype(np.int8)
    per_recording = Windows(
        np.empty((len(rows), 0)),
        rows,
        np.zeros(len(rows), np.int32),
        sig.recordings,
        scenario_labels,
    ).strata()
    missing = sorted(set(per_recording) - set(windows.strata()))
    if missing:
        lengths = sig.offsets[rows + 1] - sig.offsets[rows]
        longest = int(lengths[per_recording == missing[0]].max())
        raise UsageError(
            f"{what}: no recording of {str(missing[0])!r} holds a {segment}-sample segment (longest "
            f"signal: {longest} samples); pass a shorter segment (e.g. --segment {max(1, longest // 2)})"
        )


def analyze(
    dataset: Dataset,
    sensor: str,
    instance: str | None = None,
    *,
    segment: int | None = None,
    split: str | None = None,
    **settings: Any,
) -> SpectralResult:
    """The spectral analysis of one sensor type, or one of its instances, in ``dataset``.

    ``segment``: samples per balanced window (None: one second, i.e. each sequence one
    contiguous stretch of one recording; :data:`TRAIN_WINDOW` with ``split``). ``split``:
    None (every recording) or "paper"/"grouped": only the training side of a run with that
    split and ``seed``, at window ``segment`` (see :func:`pools`). Other parameters as
    :func:`analyze_pools`.
    """
    seed = Settings(**settings).seed
    nonslip, slip, rate = pools(dataset, (sensor, instance), segment, seed, split)
    result = analyze_pools(nonslip, slip, rate, **settings)
    result.params = dict(
        sensor_type=sensor,
        sensor_instance=instance or "all",
        dataset_fingerprint=dataset.fingerprint,
        train_split=split,
        **result.params,
    )
    return result


def _check(ok: bool, message: str) -> None:
    if not ok:
        raise UsageError(message)


# ----------------------------------------------------------------------------- outputs
PAPER_COLORS = {"nonslip": "tab:blue", "slip": "tab:red", "significance": "tab:green"}


def plot(result: SpectralResult, title: str):
    """The paper's figure: mean amplitude (lines) and 95 % band (shaded) per class, non-slip
    blue, slip red; significance green on a second axis; the most significant band hatched.

    Returns a matplotlib Figure (no pyplot state, so it is safe in tests and threads).
    """
    from matplotlib.figure import Figure

    t = result.table
    fig = Figure(figsize=(8, 3.6), layout="constrained")
    ax = fig.add_subplot()
    for cls, label in (("nonslip", "non-slip"), ("slip", "slip")):
        color = PAPER_COLORS[cls]
        ax.fill_between(
            t["freq_hz"], t[f"{cls}_lo"], t[f"{cls}_hi"], color=color, alpha=0.2, linewidth=0
        )
        ax.plot(t["freq_hz"], t[f"{cls}_mean"], color=color, linewidth=1, label=label)
    ax.set_yscale("log")  # amplitudes span decades between 0 Hz and Nyquist
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("amplitude of s_t (the channels' unit, e.g. N)")
    ax.set_xlim(0, t["freq_hz"].iloc[-1])
    if result.best_band:
        ax.axvspan(*result.best_band, color="0.85", zorder=0, label="most significant band")
    sig = ax.twinx()
    sig.plot(
        t["freq_hz"],
        t["significance"],
        color=PAPER_COLORS["significance"],
        linewidth=1,
        label="significance",
    )
    sig.set_ylim(0, 1.05)
    sig.set_ylabel("significance", color=PAPER_COLORS["significance"])
    handles = ax.get_legend_handles_labels()
    more = sig.get_legend_handles_labels()
    ax.legend(
        handles[0] + more[0], handles[1] + more[1], loc="lower left", fontsize=8, framealpha=0.8
    )
    ax.set_title(title, fontsize=10)
    return fig


def stem(sensor: str, instance: str | None) -> str:
    return sensor if instance is None else f"{sensor}-{instance}"


def write(result: SpectralResult, out: Path, name: str) -> list[Path]:
    """Write ``name``.png, .pdf (figure), .csv (per-frequency table) and .json (parameters and
    bands) into ``out``. Each file is written to a temporary name and renamed, so an interrupted
    run leaves no partial file."""
    out.mkdir(parents=True, exist_ok=True)
    p = result.params
    band = (
        f"most significant {result.best_band[0]:g}-{result.best_band[1]:g} Hz"
        if result.best_band
        else "no significant band"
    )
    who = p.get("sensor_instance", "")
    who = "all instances" if who == "all" else who
    title = (
        f"{p.get('sensor_type', '')} ({who}): {p['repeats']} x {p['n_boot']} "
        f"bootstrap sequences per class, KS alpha {p['alpha']:g}; {band}"
    )
    fig = plot(result, title)
    paths = []

    def atomic(suffix: str, save) -> None:
        with writing(out / f"{name}{suffix}"):  # a failed write names the file, not the temporary
            fd, tmp = tempfile.mkstemp(dir=out, prefix=f".{name}", suffix=suffix)
            os.close(fd)
            try:
                save(tmp)
                os.chmod(tmp, 0o644)  # mkstemp's 0600 would keep the report from other readers
                os.replace(tmp, out / f"{name}{suffix}")
            finally:
                if os.path.exists(tmp):
                    os.unlink(tmp)
        paths.append(out / f"{name}{suffix}")

    # fixed metadata keeps the PDF and PNG byte-stable between runs
    atomic(".png", lambda f: fig.savefig(f, format="png", dpi=150, metadata={"Software": None}))
    atomic(
        ".pdf",
        lambda f: fig.savefig(
            f, format="pdf", metadata={"CreationDate": None, "Creator": None, "Producer": None}
        ),
    )
    atomic(".csv", lambda f: result.table.to_csv(f, index=False, float_format="%.6g"))
    atomic(".json", lambda f: Path(f).write_text(json.dumps(result.summary(), indent=2) + "\n"))
    return paths


def provenance(result: SpectralResult) -> str:
    """Which windows the bands were chosen on, and so which runs may use them without having
    chosen on their own test data."""
    p = result.params
    if p.get("train_split") is None:
        return (
            "bands chosen on every recording, test windows included; for a detector's band, "
            "analyse a run's training side (--train-only)"
        )
    return (
        f"bands chosen on the training side only ({p['train_split']} split, seed {p['seed']}, window "
        f"{p['segment_samples']}): free of test data for cells at window {p['segment_samples']} of runs "
        f"with this dataset, split and seed"
    )


def band_param(band: tuple[float, float]) -> str:
    """The band in the form ``slipbench evaluate --param`` reads: ``band=[lo,hi]``."""
    return f"band=[{band[0]:g},{band[1]:g}]"
