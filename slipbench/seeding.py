"""Every random generator of slipbench, made from the run's seed and a named stream.

One seed drives a run; each consumer draws from its own stream, named by a word and a key, so
that no two consumers share draws (a detector's weight initialisation and the bootstrap's
resamples were once the same stream) and adding a draw to one consumer moves no other. A stream
is ``SeedSequence(seed, spawn_key=(crc32(stream), crc32(key[0]), ...))``: independent of every
other stream by construction, the same on every platform and NumPy version.

The streams in use: ``unit``, ``trial``, ``rec``, ``signature``, ``surface``, ``electrode-unit``,
``electrodes`` (the simulation),
``balance`` (which windows a cell keeps), ``sides`` and ``split`` (trials and windows to train
or test), ``detector`` (what a detector's ``fit`` receives as its seed), ``bootstrap``,
``stream-bootstrap``, ``leaderboard``, ``spectral``, ``toy`` (the test kit's data),
``torch-init``, ``torch-validation``, ``torch-batches`` (a TorchDetector's weights, validation
trials and batch order).
"""

from __future__ import annotations

import zlib

import numpy as np

# The scheme's version, part of every cell key: a change of streams never serves an old result.
STREAM_SCHEME = 1


def _words(stream: str, key: tuple[object, ...]) -> list[int]:
    return [zlib.crc32(str(k).encode()) for k in (stream, *key)]


def rng_for(seed: int, stream: str, *key: object) -> np.random.Generator:
    """The generator of ``stream`` (and ``key``, e.g. a sensor and window) under ``seed``."""
    return np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=_words(stream, key)))


def seed_int(seed: int, stream: str, *key: object) -> int:
    """An int seed (``[0, 2**32)``) of ``stream``, for an API that takes one (scikit-learn's
    ``random_state``, a detector's ``fit(seed=...)``)."""
    state = np.random.SeedSequence(int(seed), spawn_key=_words(stream, key)).generate_state(1)
    return int(state[0])
