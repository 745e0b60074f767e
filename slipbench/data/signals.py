"""From recordings to labelled windows: univariate reduction, windowing, downsampling,
balancing and splitting. Pure numpy (plus scikit-learn's splitters)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from slipbench.data.channels import channel_orders
from slipbench.data.format import Dataset
from slipbench.data.schema import UNIVARIATE_CHANNELS
from slipbench.errors import UsageError
from slipbench.seeding import rng_for, seed_int

SPLITS = (
    "paper",
    "grouped",
    "datasets",
)  # datasets: train on one dataset, test on another (slipbench.data.transfer)
# How a window gets its class: from its recording's scenario (the paper), or from the per-sample
# ``slip`` labels: the majority of its samples, any slip sample, or its last sample.
LABELLINGS = ("scenario", "majority", "any", "last")
# How the signal is scaled before windows are cut (see Signals.normalized): not at all (the
# paper), per recording, or per sensor unit.
NORMALIZATIONS = ("none", "recording", "unit")
# How balancing strata treat materials (see Windows.strata): the paper's, each material its own
# stratum; or materials pooled, for data whose "materials" are single objects or trials.
BALANCINGS = ("within", "across")
MAD_TO_SD = 1.4826  # the median absolute deviation of a normal distribution x this = its sd
MEAN_AD_TO_SD = 1.2533  # the same for the mean absolute deviation


def robust_scale(s: np.ndarray) -> tuple[float, float]:
    """Centre and scale of a signal: its median, and 1.4826 x its median absolute deviation
    (the standard deviation where s is normal noise).

    Median and MAD rather than mean and sd: s has heavy tails (impacts, the bursts of slip), and
    the share of slip in a set of recordings would move a standard deviation with it; the MAD
    follows the sensor's noise and gain (its counts per unit of force), which is what differs
    between two sensors measuring the same slip. Where more than half of s equals its median
    (integer counts at rest), the MAD is 0 and 1.2533 x the mean absolute deviation from the
    median stands in; a constant s (all at its median) gets scale 1 (it is 0 after centring
    whatever the scale). Computed in float64.
    """
    x = np.asarray(s, dtype=np.float64)
    if not len(x):
        return 0.0, 1.0
    centre = float(np.median(x))
    dev = np.abs(x - centre)
    scale = MAD_TO_SD * float(np.median(dev))
    if scale <= 0:
        scale = MEAN_AD_TO_SD * float(dev.mean())
    return centre, scale if scale > 0 else 1.0


def channel_scales(x: np.ndarray) -> np.ndarray:
    """(n_channels, 2) float64: the :func:`robust_scale` centre and scale of each channel of
    windows ``x`` (n_windows, window, n_channels), over all their readings: the training
    side's statistics, by which :func:`standardized` scales every window and stream of a task.
    Robust for the reason the signal's scale is: slip's bursts must not set a channel's unit."""
    return np.array([robust_scale(x[..., c]) for c in range(x.shape[-1])], dtype=np.float64)


def standardized(x: np.ndarray, scales: np.ndarray) -> np.ndarray:
    """``x`` (..., n_channels) centred and scaled per channel by ``scales``
    (:func:`channel_scales`), float32; each channel computed in float64 (an electrode resting
    at thousands of counts would lose its small changes in float32 before the centre is
    removed), one at a time so that memory holds one channel in float64, not the windows."""
    out = np.empty(np.shape(x), np.float32)
    for c, (centre, scale) in enumerate(scales):
        out[..., c] = (np.asarray(x[..., c], dtype=np.float64) - centre) / scale
    return out


def has_sample_labels(dataset: Dataset) -> np.ndarray:
    """(n_recordings,) bool, in the order of ``dataset.recordings``: True where the dataset gives
    the recording per-sample slip labels, at least one of its samples labelled (a dataset with a
    ``slip`` column holds labels for every recording, -1 where the column is empty)."""
    return np.array(
        [
            r in dataset.slip_labels and bool((dataset.slip_labels[r] >= 0).any())
            for r in dataset.recordings["recording_id"]
        ],
        dtype=bool,
    )


def univariate(a: np.ndarray, baseline: int = 0) -> np.ndarray:
    """The paper's eq. (1): s_t = ||a_t|| - ||a_{t-1}||.

    ||a_t|| depends on each channel's offset: a channel resting at 3000 counts weighs its
    changes by its share of the norm, so two units with different offsets give different s for
    the same contact. ``baseline`` removes that dependence.

    Parameters
    ----------
    a : (n_samples, n_channels) samples of one recording.
    baseline : 0 (the paper: raw values), or N > 0: subtract each channel's mean over the
        recording's first N samples (all of them if it is shorter) before the norm.

    Returns
    -------
    (n_samples - 1,) float32. Norms are taken in float64 so that a large static load does not
    swallow the small changes that carry the slip signal.
    """
    if (
        isinstance(baseline, (bool, np.bool_))
        or not isinstance(baseline, (int, np.integer))
        or baseline < 0
    ):
        raise UsageError(
            f"baseline must be an int >= 0 (samples averaged at the start; 0: none), got {baseline!r}"
        )
    a = np.asarray(a, dtype=np.float64)
    if baseline:
        a = a - a[:baseline].mean(axis=0)
    return np.diff(np.linalg.norm(a, axis=1)).astype(np.float32)


def _univariate_samples(
    a: np.ndarray, channels: tuple[str, ...], named: tuple[str, ...]
) -> np.ndarray:
    """The columns of ``a`` that the reduction uses: those ``named`` (canonical: () is all)."""
    if not named:
        return a
    return a[:, [i for i, c in enumerate(channels) if c in named]]


@dataclass
class Signals:
    """The univariate signal of every recording, concatenated, with its per-sample labels.

    Attributes
    ----------
    buffer : (total,) float32, the recordings' signals one after another.
    offsets : (n_recordings + 1,) int64, recording r occupies buffer[offsets[r]:offsets[r + 1]].
    recordings : the dataset's metadata, row r describing recording r.
    labels : (total,) int8 label of each value of s: that of its later sample (s_t spans
        samples t-1 and t): 1 slip, 0 no slip, -1 unlabelled. Where the dataset has no
        per-sample labels, a recording's scenario labels all its samples (hold-slip: -1), for
        the scenario labelling only: see ``labelled``.
    labelled : (n_recordings,) bool, True where the dataset gives the recording per-sample
        labels (at least one sample labelled); None: all of them. Labelling by samples
        (``majority``, ``any``, ``last``) leaves out every window of the other recordings, so
        that no window is silently labelled by its scenario under their name.
    channels : per recording, its raw readings a_0 ... a_n (n_r + 1, n_channels): the
        dataset's arrays (a copy where :func:`channel_orders` reorders a recording's columns
        to match the others' by name and unit); None for signals made without them. Sample t of the signal
        spans readings t and t + 1, so reading t + 1 stands under it: the windows of the
        ``channels`` input (:meth:`channel_values`) are cut from ``channels[r][1:]``.
    """

    buffer: np.ndarray
    offsets: np.ndarray
    recordings: pd.DataFrame
    labels: np.ndarray | None = None
    labelled: np.ndarray | None = None
    channels: list[np.ndarray] | None = None

    @classmethod
    def from_dataset(cls, dataset: Dataset, baseline: int = 0) -> Signals:
        """s of every recording, from the channels its ``univariate_channels`` names (all where
        it names none). ``baseline``: see :func:`univariate`."""
        rec = dataset.recordings
        ids = rec["recording_id"]
        parts = [
            univariate(_univariate_samples(dataset.samples[r], channels, named), baseline)
            for r, channels, named in zip(ids, rec["channels"], rec[UNIVARIATE_CHANNELS.name])
        ]
        offsets = np.r_[0, np.cumsum([len(p) for p in parts])].astype(np.int64)
        by_scenario = {"slip": 1, "press": 0, "free-space": 0}
        labels = [
            dataset.slip_labels[r][1:]
            if r in dataset.slip_labels
            else np.full(len(p), by_scenario.get(sc, -1), np.int8)
            for r, sc, p in zip(ids, dataset.recordings["scenario"], parts)
        ]
        return cls(
            np.concatenate(parts),
            offsets,
            dataset.recordings.reset_index(drop=True),
            np.concatenate(labels).astype(np.int8),
            has_sample_labels(dataset),
            [
                dataset.samples[r] if order is None else dataset.samples[r][:, order]
                for r, order in zip(ids, channel_orders(rec))
            ],
        )

    @classmethod
    def from_layout(cls, recordings: pd.DataFrame) -> Signals:
        """The shape of a dataset's signals without its samples, for planning: the canonical
        ``recordings`` (with ``n_samples``) give the offsets; ``buffer`` is empty (no window can
        be cut). Samples are labelled by scenario, and a hold-slip recording holds for its first
        half and slips in its second: a stand-in onset where a simulated one lies somewhere
        inside, so that the cells that stream it, or label windows by samples, are planned
        with about their windows."""
        lengths = recordings["n_samples"].to_numpy(np.int64) - 1  # s_t spans two samples
        by_scenario = {"slip": 1, "press": 0, "free-space": 0}
        labels = [
            np.repeat(np.array([0, 1], np.int8), [n // 2, n - n // 2])
            if scenario == "hold-slip"
            else np.full(n, by_scenario.get(scenario, -1), np.int8)
            for scenario, n in zip(recordings["scenario"], lengths)
        ]
        return cls(
            np.empty(0, np.float32),
            np.r_[0, np.cumsum(lengths)].astype(np.int64),
            recordings.reset_index(drop=True),
            np.concatenate(labels),
            np.ones(len(recordings), bool),
        )

    def antialiased(self, factor: int, order: int = 4) -> Signals:
        """The signal of a sensor whose norm passes an anti-aliasing filter before it is sampled
        ``factor`` times slower, still at the full rate: :meth:`Windows.downsample` then
        decimates it (``plain`` or ``lag``) as it would the raw signal.

        Each recording's norm ||a_t|| goes through a causal Butterworth low-pass of ``order`` at
        0.8 x the new Nyquist frequency (rate / (2 ``factor``)), as a sensor's analogue filter
        would, at rest on the recording's first reading. The filter is linear and
        time-invariant, so differencing its output equals filtering the difference: the
        result is ``sosfilt`` of each recording's s, computed on s (float64) because the
        norm's running sum would carry a large offset through the filter for nothing.

        Returns
        -------
        Signals with the same offsets and recordings; buffer (total,) float32.
        """
        if isinstance(factor, bool) or not isinstance(factor, (int, np.integer)) or factor < 2:
            raise UsageError(
                f"an anti-aliasing filter needs a downsampling factor >= 2, got {factor!r}"
            )
        from scipy import signal  # here: planning a run (or a cached one) needs no filter

        out = np.empty_like(self.buffer)
        rates = self.recordings["sampling_rate_hz"].to_numpy(dtype=float)
        for r, (lo, hi) in enumerate(zip(self.offsets[:-1], self.offsets[1:])):
            sos = signal.butter(order, 0.8 * rates[r] / (2 * factor), fs=rates[r], output="sos")
            out[lo:hi] = signal.sosfilt(sos, self.buffer[lo:hi].astype(np.float64))
        return replace(self, buffer=out)

    def normalized(self, groups: np.ndarray, reference: np.ndarray) -> tuple[Signals, np.ndarray]:
        """The signal centred and scaled per group: (s - centre) / scale, with the
        :func:`robust_scale` of the samples of the group's ``reference`` recordings (all of the
        group's recordings where none is a reference).

        Parameters
        ----------
        groups : (n_recordings,) int, the group of each recording (one recording, one unit).
        reference : (n_recordings,) bool, the recordings whose samples give the statistics.

        Returns
        -------
        The Signals (same offsets, recordings and labels; buffer float32) and an
        (n_recordings, 2) float64 array of the centre and scale each recording got.
        """
        groups, reference = np.asarray(groups), np.asarray(reference, bool)
        out = np.empty_like(self.buffer)
        stats = np.empty((len(groups), 2))
        o = self.offsets
        for g in np.unique(groups):
            members = np.flatnonzero(groups == g)
            chosen = members[reference[members]]
            if not len(chosen):
                chosen = members
            centre, scale = robust_scale(
                np.concatenate([self.buffer[o[r] : o[r + 1]] for r in chosen])
            )
            stats[members] = centre, scale
            for r in members:
                out[o[r] : o[r + 1]] = (
                    self.buffer[o[r] : o[r + 1]].astype(np.float64) - centre
                ) / scale
        return replace(self, buffer=out), stats

    def windows(
        self,
        window: int,
        rows: np.ndarray | None = None,
        values: bool = True,
        labelling: str = "scenario",
    ) -> Windows:
        """Cut non-overlapping windows of ``window`` samples from each recording in ``rows``,
        labelled as ``labelling`` says (one of :data:`LABELLINGS`).

        The tail of a recording shorter than a window is dropped; windows never span two
        recordings. A window that cannot be labelled is left out: by scenario, one of a
        hold-slip recording (it holds two states); by samples, one touching an unlabelled
        sample or of a recording without per-sample labels. ``majority`` calls a window slip when at least half its samples slip. With
        ``values=False`` only the windows' positions are computed (``x`` is None): enough to
        balance and split, and cut later by :meth:`values`.
        """
        rows = np.arange(len(self.recordings)) if rows is None else np.asarray(rows)
        lengths = (self.offsets[rows + 1] - self.offsets[rows]) // window
        n = int(lengths.sum())
        rec = np.repeat(rows, lengths).astype(np.int32)
        # index of each window inside its recording: 0, 1, ..., lengths[r] - 1
        local = (np.arange(n) - np.repeat(np.cumsum(lengths) - lengths, lengths)).astype(np.int32)
        labels = self._window_labels(rec, local, window, labelling)
        keep = labels >= 0
        w = Windows(None, rec[keep], local[keep], self.recordings, labels[keep])
        return (
            Windows(self.values(w, window), w.recording, w.index, w.recordings, w.labels)
            if values
            else w
        )

    def _window_labels(
        self, rec: np.ndarray, local: np.ndarray, window: int, labelling: str
    ) -> np.ndarray:
        """(n_windows,) int8: 1 slip, 0 no slip, -1 cannot be labelled."""
        if labelling not in LABELLINGS:
            raise UsageError(
                f"unknown labelling {labelling!r}; choose one of: {', '.join(LABELLINGS)}"
            )
        if labelling == "scenario":
            scenario = self.recordings["scenario"].to_numpy()[rec]
            return np.select([scenario == "slip", scenario == "hold-slip"], [1, -1], 0).astype(
                np.int8
            )
        starts = self.offsets[rec] + local.astype(np.int64) * window
        per_sample = np.lib.stride_tricks.sliding_window_view(self.sample_labels(), window)[starts]
        unlabelled = (per_sample < 0).any(axis=1)
        if self.labelled is not None:  # the scenario stands in for missing labels: not here
            unlabelled |= ~self.labelled[rec]
        if labelling == "majority":
            out = (2 * (per_sample == 1).sum(axis=1) >= window).astype(np.int8)
        elif labelling == "any":
            out = (per_sample == 1).any(axis=1).astype(np.int8)
        else:
            out = per_sample[:, -1].astype(np.int8)
        out[unlabelled] = -1
        return out

    def sample_labels(self) -> np.ndarray:
        """``labels``; UsageError for signals made without them (labelling by samples and
        streaming need them; :meth:`from_dataset` always gives them)."""
        if self.labels is None:
            raise UsageError("these signals carry no per-sample labels")
        return self.labels

    def values(self, windows: Windows, window: int) -> np.ndarray:
        """The samples of windows given by position: (n_windows, window) float32."""
        starts = self.offsets[windows.recording] + windows.index.astype(np.int64) * window
        return np.lib.stride_tricks.sliding_window_view(self.buffer, window)[starts]

    def channel_values(
        self, windows: Windows, window: int, channels: list[np.ndarray] | None = None
    ) -> np.ndarray:
        """The raw channels of windows given by position: (n_windows, window, n_channels)
        float32, the readings under the samples of s that :meth:`values` cuts. ``channels``:
        other per-recording channels to cut from (the low-passed ones of
        :meth:`antialiased_channels`); by default :attr:`channels`.

        UsageError where the windows' recordings differ in their number of channels (the
        planner skips such cells first, naming each unit's channels).
        """
        source = self.channels if channels is None else channels
        if source is None:
            raise UsageError("these signals were made without their channels")
        rows = np.unique(windows.recording)
        counts = {int(source[r].shape[1]) for r in rows}
        if len(counts) > 1:
            raise UsageError(
                f"windows of recordings with {sorted(counts)} channels cannot form one array"
            )
        out = np.empty((len(windows), window, counts.pop() if counts else 0), np.float32)
        starts = windows.index.astype(np.int64) * window
        for r in rows:
            mine = np.flatnonzero(windows.recording == r)
            out[mine] = np.lib.stride_tricks.sliding_window_view(source[r][1:], window, axis=0)[
                starts[mine]
            ].transpose(0, 2, 1)
        return out

    def antialiased_channels(self, factor: int, order: int = 4) -> list[np.ndarray]:
        """Each recording's channels through the low-pass of :meth:`antialiased` (the same
        filter, at rest on the recording's first reading), float32, for a sensor ``factor``
        times slower; :meth:`Windows.downsample` then takes its readings."""
        if self.channels is None:
            raise UsageError("these signals were made without their channels")
        from scipy import signal

        rates = self.recordings["sampling_rate_hz"].to_numpy(dtype=float)
        out = []
        for r, a in enumerate(self.channels):
            sos = signal.butter(order, 0.8 * rates[r] / (2 * factor), fs=rates[r], output="sos")
            a = np.asarray(a, dtype=np.float64)
            zi = signal.sosfilt_zi(sos)[:, :, None] * a[:1]  # at rest on the first reading
            out.append(signal.sosfilt(sos, a, axis=0, zi=zi)[0].astype(np.float32))
        return out


@dataclass
class Windows:
    """Labelled windows.

    Attributes
    ----------
    x : (n_windows, window_length) float32 of the univariate signal, or (n_windows,
        window_length, n_channels) of the raw channels; None for windows known by position only.
    recording : (n_windows,) row of each window's recording in ``recordings``.
    index : (n_windows,) position of the window inside its recording.
    recordings : the dataset's metadata.
    labels : (n_windows,) int8, 1 slip, 0 no slip (see :meth:`Signals.windows`).
    """

    x: np.ndarray | None
    recording: np.ndarray
    index: np.ndarray
    recordings: pd.DataFrame
    labels: np.ndarray
    # per balancing, the strata names and each window's code (:meth:`strata`), kept through
    # :meth:`take`: a cell's test windows are a take of its sensor's, whose strata planning made
    _strata: dict[str, tuple[np.ndarray, np.ndarray]] = field(
        default_factory=dict, repr=False, compare=False
    )

    def __len__(self) -> int:
        return len(self.recording)

    def take(self, rows: np.ndarray) -> Windows:
        x = None if self.x is None else self.x[rows]
        strata = {k: (names, codes[rows]) for k, (names, codes) in self._strata.items()}
        return Windows(
            x, self.recording[rows], self.index[rows], self.recordings, self.labels[rows], strata
        )

    def with_x(self, x: np.ndarray | None) -> Windows:
        """The same windows holding ``x`` (their samples, cut or decimated)."""
        return Windows(x, self.recording, self.index, self.recordings, self.labels, self._strata)

    def column(self, name: str) -> np.ndarray:
        """A recordings column (scenario, material, speed_mm_s, ...) per window."""
        return self.recordings[name].to_numpy()[self.recording]

    @property
    def y(self) -> np.ndarray:
        """(n_windows,) int8: 1 slip, 0 no slip."""
        return self.labels

    def strata(self, balancing: str = "within") -> np.ndarray:
        """The balancing stratum of each window (section II.D of the paper): slip per material
        and speed, pressing per material, free-space per speed; and, with labels from the
        samples, contact held without slip ("hold", per material) for non-slip windows of slip
        and hold-slip recordings. ``balancing="across"`` pools the materials: slip per speed,
        pressing and held contact one stratum each."""
        # a window's stratum is that of its (recording, label) pair: the strings are built
        # once per pair, not per window (they led the main process's windowing)
        if balancing not in self._strata:
            label = np.select([self.labels == 0, self.labels == 1], [0, 1], 2)
            pairs, inverse = np.unique(
                self.recording.astype(np.int64) * 3 + label, return_inverse=True
            )
            labels = np.array([0, 1, -1])[pairs % 3]
            self._strata[balancing] = (
                _strata(self.recordings, pairs // 3, labels, balancing),
                inverse.ravel().astype(np.int32),
            )
        names, codes = self._strata[balancing]
        return names[codes]

    def downsample(self, factor: int, decimation: str = "plain") -> Windows:
        """The windows as a sensor sampled ``factor`` times slower would see them.

        A window of n samples of s_t = ||a_t|| - ||a_{t-1}|| spans the readings a_p ... a_{p+n};
        a sensor ``factor`` = k times slower reads a_p, a_{p+k}, ..., a_{p+mk} of them, m = n // k
        (the samples after the last whole block are dropped, so every decimation keeps m).
        Sample j of the result is taken from block j, s[p+jk] ... s[p+jk+k-1]:

        - ``"plain"``: its first sample, ||a_{p+jk+1}|| - ||a_{p+jk}||: every k-th sample of the
          full-rate difference (the paper's "omitting every other sensor reading" read as
          omitting samples of s);
        - ``"lag"``: the block's sum, ||a_{p+(j+1)k}|| - ||a_{p+jk}||: the lag-one difference of
          the slower sensor, which never reaches outside the window.

        Windows of raw channels keep the readings each difference ends on (see below).

        Returns
        -------
        Windows with x of shape (n_windows, n // factor) float32 (with channels,
        (n_windows, n // factor, n_channels)).
        """
        if self.x is None:
            raise UsageError("windows known by position only have no samples to downsample")
        m = self.x.shape[1] // factor
        if m < 1:
            raise UsageError(
                f"windows of {self.x.shape[1]} samples downsampled by {factor} leave no sample"
            )
        if self.x.ndim == 3 and decimation in ("plain", "lag"):
            # raw channels: the readings themselves. Row i holds a_{p+1+i}; "plain" keeps
            # a_{p+jk+1} (row jk), "lag" a_{p+(j+1)k} (row (j+1)k - 1), the readings each
            # decimation's difference ends on.
            first = 0 if decimation == "plain" else factor - 1
            x = self.x[:, first : m * factor : factor]
        elif decimation == "plain":
            x = self.x[:, : m * factor : factor]
        elif decimation == "lag":
            # float64 accumulation: the sum adds no rounding to that of the float32 samples
            x = (
                self.x[:, : m * factor]
                .reshape(len(self.x), m, factor)
                .sum(axis=2, dtype=np.float64)
            )
        else:
            raise UsageError(f"unknown decimation {decimation!r}; choose plain or lag")
        return self.with_x(np.ascontiguousarray(x, dtype=np.float32))


def _strata(
    rec: pd.DataFrame, recording: np.ndarray, labels: np.ndarray, balancing: str
) -> np.ndarray:
    """:meth:`Windows.strata` of windows of ``recording`` (rows of ``rec``) labelled ``labels``."""
    scenario = rec["scenario"].to_numpy(dtype=str)[recording]
    material = rec["material"].fillna("").to_numpy(dtype=str)[recording]
    if balancing == "across":
        material = np.full(len(material), "")
    speed = np.char.mod("%g", rec["speed_mm_s"].to_numpy(dtype=float, na_value=np.nan))[recording]
    held = (labels == 0) & np.isin(scenario, ("slip", "hold-slip"))
    category = np.where(labels == 1, "slip", np.where(held, "hold", scenario))
    material = np.where(category == "free-space", "", material)
    speed = np.where(np.isin(category, ("press", "hold")), "", speed)
    return np.char.add(np.char.add(np.char.add(category, "|"), material), np.char.add("|", speed))


def _shares(strata: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The paper's allocation over ``strata`` (see :func:`balance`): the stratum names, each
    window's stratum (code), the windows each stratum holds and the windows it keeps."""
    names, codes, counts = np.unique(strata, return_inverse=True, return_counts=True)
    category = np.array([n.split("|", 1)[0] for n in names])
    # the largest equal share each kind can give to every one of its strata
    capacity = {c: counts[category == c].min() * (category == c).sum() for c in np.unique(category)}
    nonslip = sorted(c for c in capacity if c != "slip")
    if "slip" not in capacity or not nonslip:
        present = ", ".join(sorted(capacity)) or "none"
        raise UsageError(f"balancing needs slip and non-slip windows; kinds present: {present}")
    per_nonslip = min(capacity[c] for c in nonslip)
    per_class = min(capacity["slip"], per_nonslip * len(nonslip))
    target = {"slip": per_class, **{c: per_class // len(nonslip) for c in nonslip}}
    # at least one window: a floor share of 0 would drop the stratum (and maybe its class)
    shares = np.array(
        [max(1, target[c] // (category == c).sum()) for c in category], dtype=np.int64
    )
    return names, codes, counts, shares


def balance(windows: Windows, rng: np.random.Generator, balancing: str = "within") -> np.ndarray:
    """Rows that give the paper's mix: half slip, half non-slip; slip equal per stratum;
    non-slip split equally between pressing, free-space (and held contact, with labels from the
    samples), equal per stratum inside each.

    Kinds a dataset lacks drop out of the proportions (a dataset without free-space data
    balances slip against pressing alone). Inside a stratum, windows are drawn at random.
    ``balancing``: one of :data:`BALANCINGS` (:meth:`Windows.strata`).

    Each kind's share is the paper's equal floor share, ``target // n_strata`` per stratum. Where
    that is 0 (a kind has more strata than the other class has windows to match: thousands of
    slip windows in 40 strata against 26 non-slip windows), every stratum of the kind keeps one
    window instead, so no stratum, and no class present, is ever dropped; the two classes are
    then unequal, and the counts each side keeps are recorded in every result row. Where every
    share is at least 1 the allocation, and so the drawn rows, are the paper's.
    """
    _names, codes, _counts, shares = _shares(windows.strata(balancing))
    keep = [
        rng.choice(np.flatnonzero(codes == code), size=share, replace=False)
        for code, share in enumerate(shares)
    ]
    return np.sort(np.concatenate(keep))


def balanced_counts(windows: Windows, balancing: str = "within") -> dict[int, int]:
    """{1: slip, 0: non-slip} windows :func:`balance` keeps of ``windows`` (no draw needed)."""
    names, _codes, _counts, shares = _shares(windows.strata(balancing))
    slip = np.array([n.startswith("slip|") for n in names])
    return {1: int(shares[slip].sum()), 0: int(shares[~slip].sum())}


#: what a stratum of each kind is, per balancing
STRATUM_OF = {
    "within": {
        "slip": "material and speed",
        "press": "material",
        "hold": "material",
        "free-space": "speed",
    },
    "across": {"slip": "speed", "press": "one", "hold": "one", "free-space": "speed"},
}


def _stratum(name: str) -> str:
    """``"slip|obj-3|25"`` -> ``"obj-3, 25 mm/s"``."""
    _, material, speed = name.split("|")
    parts = [material] if material else []
    parts += [f"{speed} mm/s"] if speed and speed != "nan" else []
    return ", ".join(parts) or "all"


def _windows(n: int) -> str:
    return f"{n} window" if n == 1 else f"{n} windows"


def balance_limits(windows: Windows, balancing: str = "within") -> str:
    """Why :func:`balance` keeps what it keeps of ``windows``, as a clause for a warning. A kind
    is kept equal over its strata, so its smallest stratum sets what every other keeps; the
    classes are then matched, so the kind that gives fewer limits the other class too."""
    names, _codes, counts, _shares_ = _shares(windows.strata(balancing))
    category = np.array([n.split("|", 1)[0] for n in names])
    capacity, smallest = {}, {}
    for kind in np.unique(category):
        mine = np.flatnonzero(category == kind)
        at = mine[np.argmin(counts[mine])]
        capacity[kind] = int(counts[at]) * len(mine)
        what = STRATUM_OF.get(balancing, {}).get(kind, "stratum")
        smallest[kind] = (
            f"{kind} is kept equal over its {len(mine)} strata (per {what}) and the smallest "
            f"({_stratum(names[at])}) holds {_windows(int(counts[at]))}"
            if len(mine) > 1
            else f"{kind} has {_windows(int(counts[at]))}"
        )
    nonslip = sorted(c for c in capacity if c != "slip")
    short = min(nonslip, key=lambda c: capacity[c])
    if capacity["slip"] <= capacity[short] * len(nonslip):
        return f"{smallest['slip']}, and non-slip is matched to it"
    split = f", non-slip split equally over {', '.join(nonslip)}" if len(nonslip) > 1 else ""
    return f"{smallest[short]}{split}, and slip is matched to it"


def trial_sides(recordings: pd.DataFrame, seed: int) -> np.ndarray:
    """(n_recordings,) 0 (train) or 1 (test) per recording, one side per trial for every unit.

    Trials (the ``trial`` column; a recording is its own trial where there is none) are
    assigned within strata of scenario, material and speed: shuffled with the seed, then dealt
    to the two sides in turn, each stratum starting on a side drawn from the seed. Recordings
    that share a trial (the fingers of one grasp) therefore land on the same side in every
    unit's split, so no model is tested on a trial whose twin trained it.
    """
    rng = rng_for(seed, "sides")
    trials = recordings["trial"] if "trial" in recordings else recordings["recording_id"]
    key = [
        f"{sc}|{m}|{v:g}"
        for sc, m, v in zip(
            recordings["scenario"],
            recordings["material"].fillna(""),
            recordings["speed_mm_s"].to_numpy(dtype=float, na_value=np.nan),
        )
    ]
    first = pd.DataFrame({"trial": trials.to_numpy(), "stratum": key}).drop_duplicates("trial")
    side: dict = {}
    for _, group in first.groupby("stratum", sort=True):
        order = group["trial"].to_numpy()[rng.permutation(len(group))]
        start = int(rng.integers(2))
        side.update({t: (start + i) % 2 for i, t in enumerate(order)})
    return trials.map(side).to_numpy(dtype=np.int8)


def split(
    windows: Windows,
    how: str,
    seed: int,
    sides: np.ndarray | None = None,
    balancing: str = "within",
) -> tuple[np.ndarray, np.ndarray]:
    """Train and test rows.

    ``paper``: shuffle windows and halve them, stratified by balancing stratum so both halves
    keep the paper's mix (by class alone where a stratum has a single window). ``grouped``:
    each window goes to its recording's side in ``sides`` (:func:`trial_sides`): whole trials
    on one side, the same for every unit.
    """
    rows = np.arange(len(windows))
    if how == "paper":
        from sklearn.model_selection import train_test_split  # its import alone costs ~1 s

        strata = windows.strata(balancing)
        if np.unique(strata, return_counts=True)[1].min() < 2:
            strata = windows.y
        if np.unique(strata, return_counts=True)[1].min() < 2:
            raise UsageError("the paper split needs at least two windows of each class")
        train, test = train_test_split(
            rows, test_size=0.5, stratify=strata, random_state=seed_int(seed, "split")
        )
    elif how == "grouped":
        if sides is None:
            sides = trial_sides(windows.recordings, seed)
        on_test = sides[windows.recording] == 1
        train, test = rows[~on_test], rows[on_test]
    else:
        raise UsageError(f"unknown split {how!r}; choose one of: {', '.join(SPLITS)}")
    return np.sort(train), np.sort(test)
