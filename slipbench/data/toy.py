"""Toy windows: a small, balanced, seeded two-class problem (non-slip is noise, slip adds a
60 Hz burst) for checks and timings that need windows a detector can learn but no dataset."""

from __future__ import annotations

import numpy as np

from slipbench.seeding import rng_for


def toy_windows(n: int, length: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Balanced windows: non-slip is low noise, slip adds a 60 Hz burst (at 1 kHz) and more noise."""
    rng = rng_for(seed, "toy")
    y = np.arange(n) % 2
    t = np.arange(length) / 1000.0
    x = rng.normal(0, 1, (n, length)) * np.where(y, 2.0, 1.0)[:, None]
    x += y[:, None] * 3 * np.sin(2 * np.pi * 60 * t + rng.uniform(0, 2 * np.pi, (n, 1)))
    return x.astype(np.float32), y
