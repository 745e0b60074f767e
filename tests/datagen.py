"""Parts of a dataset for tests that need fewer recordings than the shared simulated one."""

from __future__ import annotations

import numpy as np

from slipbench.data.format import Dataset


def subset(ds: Dataset, mask) -> Dataset:
    """The recordings of ``ds`` where ``mask`` holds, with their samples and labels."""
    rec = ds.recordings[np.asarray(mask)].reset_index(drop=True)
    ids = set(rec["recording_id"])
    labels = {k: v for k, v in ds.slip_labels.items() if k in ids}
    return Dataset(
        rec, {k: v for k, v in ds.samples.items() if k in ids}, labels, ds.path
    )  # its fingerprint: from its content
