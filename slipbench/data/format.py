"""The :class:`Dataset` type: a validated, canonical dataset in memory, whether read from a folder
(:func:`slipbench.data.read.read_dataset`) or built by a caller; and the sensor units of a
recordings table."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np
import pandas as pd

from slipbench.data.canonical import canonical_dataset
from slipbench.data.fingerprint import content_fingerprint
from slipbench.data.schema import IN_MEMORY, RECORDINGS_FILE, SAMPLES_FILE
from slipbench.vocabulary import sensor_pairs


@dataclass(eq=False)
class Dataset:
    """Recordings metadata plus each recording's samples and labels, validated and canonical.

    Built by :func:`~slipbench.data.read.read_dataset` or in memory; both give the same
    canonical form (:mod:`slipbench.data.canonical`): recordings sorted by ``recording_id``,
    integer samples as float64, labels as int8.

    Attributes
    ----------
    recordings : DataFrame, one row per recording, sorted by ``recording_id``: the columns of
        :data:`~slipbench.data.schema.RECORDINGS_SCHEMA` (``trial`` always present: a recording
        without one is its own trial), ``channels``/``units`` as tuples,
        ``univariate_channels`` (a tuple in the order of ``channels``; () for all), ``n_channels``,
        ``n_samples`` and ``unit_rate_hz`` (the median rate of the recording's unit, see
        :data:`~slipbench.data.schema.RATE_TOLERANCE`).
    samples : dict recording_id -> array of shape (n_samples, n_channels); float32 where the
        file holds float32 (or float16), float64 where it holds float64 or integers.
    slip_labels : dict recording_id -> int8 array of shape (n_samples,): -1 unlabelled, 0 no
        slip, 1 slip. Every recording has one when the file has a ``slip`` column; empty when not.
    path : where the dataset was read from (None if built in memory).
    origin : for a dataset built from others (:func:`slipbench.data.transfer.combine`), what
        they were: plain strings (paths, fingerprints, the sensor map) that every result row
        and report carries; empty otherwise.
    """

    recordings: pd.DataFrame
    samples: dict[str, np.ndarray]
    slip_labels: dict[str, np.ndarray] = field(default_factory=dict)
    path: Path | None = None
    origin: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.path = None if self.path is None else Path(self.path)
        where = (
            (self.path / RECORDINGS_FILE, self.path / SAMPLES_FILE)
            if self.path
            else (IN_MEMORY, IN_MEMORY)
        )
        self.recordings, self.samples, self.slip_labels = canonical_dataset(
            self.recordings, self.samples, self.slip_labels, *where
        )

    @cached_property
    def fingerprint(self) -> str:
        """Content hash: the same recordings give the same 16 hex digits however they were
        stored (row order, Arrow flavours, pyarrow version) or built in memory.

        Computed on first use and cached: change no array of a Dataset after reading it. Costs
        about 1 s for the simulated design at scale 0.2 (12 M samples, 46 M values): 2 x
        BLAKE2b over the bytes of its files (``benchmarks/bench_data.py``).
        """
        return content_fingerprint(self.recordings, self.samples, self.slip_labels)

    def sensors(self) -> list[tuple[str, str]]:
        """(sensor_type, sensor_instance) pairs in order of first appearance."""
        return sensor_pairs(self.recordings)
