"""Where a TorchDetector trains when its ``device`` is ``auto``: the faster of the CPU and a
CUDA GPU for its network and batch, never "a GPU exists".

Without CUDA the answer is the CPU and costs nothing. With CUDA, a few training steps of the
detector's own network on batches of its shape are timed on each device the first time a key
is seen, and the answer is kept in the user cache folder, one small JSON file per key. The key
holds everything the timing depends on: torch's version, the GPU's name, the CPU threads, the
detector's class and parameters (the network and the batch size), the window length and the
input channels. A deleted file is measured again; a cached answer never changes a model's
numbers beyond the two devices' float rounding (seeded training runs on either).
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from platformdirs import user_cache_dir

from slipbench.atomic import atomic_file, make_folder
from slipbench.errors import EnvironmentFault

#: timed steps per device, after as many warm-up steps (the first CUDA step loads kernels)
STEPS = 5


def cache_dir() -> Path:
    """Measured device choices: under ``$SLIPBENCH_CACHE`` as the default dataset is (the wing
    rule keeps :func:`slipbench.data.defaults.cache_dir` out of reach here)."""
    root = Path(os.environ.get("SLIPBENCH_CACHE") or user_cache_dir("slipbench"))
    return root / "torch-devices"


def choose(
    asked: str, key: dict[str, Any], step_seconds: Callable[[str], float]
) -> tuple[str, str]:
    """(device, why): ``"cpu"`` or ``"cuda"`` and the reason a row shows.

    ``asked`` is the detector's ``device``; ``key`` says what a timing depends on (see the
    module docstring); ``step_seconds(device)`` times one training step there (called only for
    ``auto`` with CUDA present, and only when no cached answer has ``key``).
    """
    import torch

    if asked != "auto":
        return asked, "asked"
    if not torch.cuda.is_available():
        return "cpu", "auto: no CUDA device"
    key = {**key, "torch": torch.__version__, "gpu": torch.cuda.get_device_name()}
    path = cache_dir() / f"{_digest(key)}.json"
    try:
        seconds = json.loads(path.read_text())["seconds"]
        where = f"measured on first use, cached in {path}"
    except (OSError, ValueError, KeyError):
        seconds = {d: step_seconds(d) for d in ("cpu", "cuda")}
        where = "measured now"
        try:
            with atomic_file(make_folder(path.parent) / path.name) as f:
                f.write(json.dumps({"key": key, "seconds": seconds}, sort_keys=True).encode())
        except (
            OSError,
            EnvironmentFault,
        ):  # a read-only cache: measured again next time, the choice is the same
            where = "measured now (the cache folder is not writable)"
    device = min(seconds, key=seconds.get)
    other = "cpu" if device == "cuda" else "cuda"
    return device, (
        f"auto: {device} {seconds[device] * 1e3:.3g} ms per training step against "
        f"{seconds[other] * 1e3:.3g} ms on {other}, {where}"
    )


def _digest(key: dict[str, Any]) -> str:
    return hashlib.sha256(json.dumps(key, sort_keys=True, default=str).encode()).hexdigest()[:16]
