"""Saved models prove themselves before reuse: a tampered, damaged or misplaced model file is
fitted again with a warning naming it, never reused and never blamed on the detector."""

from __future__ import annotations

import io
import json
import shutil
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from datagen import subset

from slipbench.detectors.holweg import Holweg
from slipbench.engine.runner import Run, evaluate
from slipbench.protocols.window_size import WindowSize
from slipbench.store import models
from slipbench.store.results import ResultsStore

FIGURES = ["key", "status", "accuracy", "tp_rate", "tn_rate", "fitted", "model_key"]


@pytest.fixture(scope="module")
def index(small):
    return subset(
        small,
        small.recordings["sensor_type"].eq("Nano17")
        & small.recordings["sensor_instance"].eq("index"),
    )


def _run(index, folder: Path) -> tuple[pd.DataFrame, list[str]]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rows = evaluate(
            index,
            Run(Holweg(), WindowSize(windows=[50, 100])),
            ResultsStore(folder),
            progress=False,
        )
    return rows, [str(w.message) for w in caught]


def _recomputed(folder: Path) -> None:
    """Drop the stored cells, so that the next run computes them again from the saved models."""
    shutil.rmtree(folder / "cells")
    (folder / "results.parquet").unlink(missing_ok=True)


def _saved(folder: Path) -> list[Path]:
    return sorted((folder / "models").glob("*.npz"))


@pytest.fixture(scope="module")
def first(index, tmp_path_factory):
    folder = tmp_path_factory.mktemp("first")
    rows, _ = _run(index, folder)
    assert (rows["status"] == "ok").all() and len(_saved(folder)) == 2
    return folder, rows[FIGURES].set_index("key").sort_index()


def _copy(first, tmp_path: Path) -> Path:
    shutil.copytree(first[0], tmp_path / "out")
    _recomputed(tmp_path / "out")
    return tmp_path / "out"


def _triple_threshold(path: Path) -> None:
    with np.load(path, allow_pickle=False) as f:
        arrays = {k: f[k] for k in f.files}
    arrays["threshold_"] = arrays["threshold_"] * 3
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    path.write_bytes(buffer.getvalue())


def _flip_bit(path: Path) -> None:
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x10
    path.write_bytes(bytes(data))


def _refit_and_equal(index, folder: Path, first, why: str, model: Path) -> None:
    rows, said = _run(index, folder)
    assert (rows["status"] == "ok").all(), rows["reason"].tolist()
    pd.testing.assert_frame_equal(rows[FIGURES].set_index("key").sort_index(), first[1])
    assert [m for m in said if str(model) in m] == [
        f"saved model {model} {why}; fitting it again"
    ], said
    # fitted again and saved with a proof that holds: the next recompute reuses it quietly
    _recomputed(folder)
    again, said = _run(index, folder)
    assert not [m for m in said if "saved model" in m], said
    pd.testing.assert_frame_equal(again[FIGURES].set_index("key").sort_index(), first[1])


def test_a_reused_model_gives_the_same_rows_without_a_word(index, first, tmp_path):
    folder = _copy(first, tmp_path)
    before = {p: p.stat().st_mtime_ns for p in _saved(folder)}
    rows, said = _run(index, folder)
    assert not [m for m in said if "saved model" in m], said
    pd.testing.assert_frame_equal(rows[FIGURES].set_index("key").sort_index(), first[1])
    assert {p: p.stat().st_mtime_ns for p in _saved(folder)} == before  # loaded, not refitted


def test_a_tampered_model_is_fitted_again(index, first, tmp_path):
    """Holweg's threshold x3 in a saved model: once reused, all accuracies changed, exit 0."""
    folder = _copy(first, tmp_path)
    model = _saved(folder)[0]
    _triple_threshold(model)
    why = "does not match its digest (changed since it was saved)"
    _refit_and_equal(index, folder, first, why, model)


def test_a_model_with_a_flipped_bit_is_fitted_again_not_blamed_on_the_detector(
    index, first, tmp_path
):
    folder = _copy(first, tmp_path)
    model = _saved(folder)[0]
    _flip_bit(model)
    why = "does not match its digest (changed since it was saved)"
    _refit_and_equal(index, folder, first, why, model)


def test_a_model_copied_under_another_key_is_fitted_again(index, first, tmp_path):
    folder = _copy(first, tmp_path)
    a, b = _saved(folder)
    for suffix in ("", ".json"):  # the model and its proof, both copied over b's
        shutil.copyfile(f"{a}{suffix}", f"{b}{suffix}")
    why = f"was fitted for model key {a.stem!r}, not {b.stem!r}"
    _refit_and_equal(index, folder, first, why, b)


def test_a_model_without_a_proof_format_is_fitted_again(index, first, tmp_path):
    """A model saved by an older slipbench (its cost file only) carries no digest."""
    folder = _copy(first, tmp_path)
    model = _saved(folder)[0]
    proof = models.proof_path(model)
    proof.write_text(json.dumps(json.loads(proof.read_text())["cost"]))
    _refit_and_equal(
        index, folder, first, "carries no digest (written by an older slipbench)", model
    )


def test_an_edited_cost_fails_the_digest(first, tmp_path):
    """The cost a reused cell reports is proved too (train_s halved)."""
    folder = _copy(first, tmp_path)
    model = _saved(folder)[0]
    proof = models.proof_path(model)
    record = json.loads(proof.read_text())
    record["cost"]["train_s"] /= 2
    proof.write_text(json.dumps(record))
    with pytest.raises(models.Unproved, match="does not match its digest"):
        models.reuse(Holweg, model)
    assert models.reuse(Holweg, folder / "models" / "absent.npz") is None
