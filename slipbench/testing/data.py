"""What the conformance checks run on: toy windows of each input kind and a small simulated
dataset, and the check that a call is refused with a clear message."""

from __future__ import annotations

import functools

import numpy as np

from slipbench.base import INPUT_SHAPES
from slipbench.data.format import Dataset
from slipbench.data.toy import toy_windows
from slipbench.seeding import rng_for

LENGTHS = (5, 50, 200)
CHANNELS = 3  # channels of the toy windows of channels: not 1, and no window length


def toy_channel_windows(
    n: int, length: int, channels: int = CHANNELS, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Balanced windows of channels (n, length, channels) float32 and labels (n,): every
    channel is noise of its own scale; in slip windows the first carries a 60 Hz burst (at 1 kHz)
    and the second more noise, as one electrode or axis would; the others carry nothing."""
    rng = rng_for(seed, "toy-channels")
    y = np.arange(n) % 2
    x = rng.normal(0, 1, (n, length, channels)) * (1.0 + np.arange(channels) / 2)
    t = np.arange(length) / 1000.0
    burst = 3 * np.sin(2 * np.pi * 60 * t + rng.uniform(0, 2 * np.pi, (n, 1)))
    x[:, :, 0] += y[:, None] * burst
    if channels > 1:
        x[:, :, 1] *= np.where(y, 2.0, 1.0)[:, None]
    return x.astype(np.float32), y


def toy(kind: str, n: int, length: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Toy windows of an input kind: ``toy_windows`` for "univariate", ``toy_channel_windows``
    for "channels"."""
    if kind not in INPUT_SHAPES:
        raise ValueError(f"no input kind {kind!r}; known: {', '.join(INPUT_SHAPES)}")
    return (toy_windows if kind == "univariate" else toy_channel_windows)(n, length, seed=seed)


def assert_refused(kind: type[Exception], words: str, call, what: str) -> None:
    try:
        call()
    except kind as exc:
        assert words.lower() in str(exc).lower(), (
            f"{what}: the error should mention {words!r}, got: {exc}"
        )
        return
    except Exception as exc:  # noqa: BLE001 - the wrong kind of error is the failure reported
        raise AssertionError(
            f"{what}: expected {kind.__name__}, got {type(exc).__name__}: {exc}"
        ) from exc
    raise AssertionError(f"{what}: expected {kind.__name__}, nothing was raised")


@functools.cache
def toy_dataset() -> Dataset:
    """A small simulated dataset (every sensor, material and speed; about 0.6 M samples), read
    once per process: what protocol checks plan their cells on. It is the default dataset at
    scale 0.01, simulated once into slipbench's cache, not into a temporary folder per process."""
    from slipbench.data.defaults import default_dataset

    return default_dataset(scale=0.01, seed=0)
