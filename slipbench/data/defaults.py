"""The embedded default dataset: simulated on first use into the user's cache, then reused.

Light to import (the simulator and the reader are imported when used): a newcomer's first
command says that it simulates before it imports what the simulation and the detectors need."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from platformdirs import user_cache_dir

from slipbench.data.synth_model import MODEL_VERSION
from slipbench.errors import DataError, EnvironmentFault, environment_fault

if TYPE_CHECKING:
    from slipbench.data.format import Dataset

DEFAULT_SCALE = 0.05
#: what to do when the cache cannot be written: the newcomer's first command simulates into it
DEFAULT_DATASET_HINT = (
    "the simulated default dataset is cached there: set SLIPBENCH_CACHE (or, on Linux, "
    "XDG_CACHE_HOME) to a writable folder, or pass a dataset folder with --dataset"
)


def cache_dir() -> Path:
    """``$SLIPBENCH_CACHE`` if set, else the platform's user cache folder for slipbench."""
    return Path(os.environ.get("SLIPBENCH_CACHE") or user_cache_dir("slipbench"))


def default_dataset_path(scale: float = DEFAULT_SCALE, seed: int = 0) -> Path:
    """Where the simulated dataset at ``scale`` and ``seed`` is cached (it may not be yet)."""
    return cache_dir() / f"synth-v{MODEL_VERSION}-scale{scale:g}-seed{seed}"


def first_use(scale: float = DEFAULT_SCALE, seed: int = 0) -> str | None:
    """The line that says the dataset at ``scale`` and ``seed`` is about to be simulated, where
    it is not cached yet; None where it is."""
    path = default_dataset_path(scale, seed)
    if path.is_dir():
        return None
    return (
        f"simulating the default dataset (first use; scale {scale:g}, seed {seed}) into {path} ..."
    )


def synthesize(path: Path, scale: float, seed: int) -> None:
    """:func:`slipbench.data.synth.synthesize`, imported when a dataset is simulated."""
    from slipbench.data.synth import synthesize as simulate

    simulate(path, scale, seed)


def default_dataset(
    scale: float = DEFAULT_SCALE, seed: int = 0, echo: Callable[[str], None] | None = None
) -> Dataset:
    """The simulated dataset at ``scale`` and ``seed``, generated once per cache."""
    from slipbench.data.read import read_dataset

    path = default_dataset_path(scale, seed)
    if not path.is_dir():
        if echo and (line := first_use(scale, seed)):
            echo(line)
        try:
            synthesize(path, scale, seed)
        except DataError:
            if not path.is_dir():  # lost a race with another process: theirs is as good
                raise
        except EnvironmentFault as exc:
            raise EnvironmentFault(exc.path, exc.cause, exc.action, DEFAULT_DATASET_HINT) from None
        except OSError as exc:  # raised before a file was opened, e.g. making the folder
            fault = environment_fault(exc, path)  # anything else is re-raised as it is
            raise EnvironmentFault(
                fault.path, fault.cause, fault.action, DEFAULT_DATASET_HINT
            ) from None
    return read_dataset(path)
