"""A fitted scikit-learn estimator as a detector's state: saved through skops, loaded after
skops' trusted-types check, never through pickle."""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest
from sklearn.base import BaseEstimator, TransformerMixin
from sklearn.linear_model import LogisticRegression
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler

from slipbench.base import BaseDetector
from slipbench.data.toy import toy_windows
from slipbench.errors import UsageError
from slipbench.testing import check_detector


def _features(x: np.ndarray) -> np.ndarray:
    return np.column_stack([x.mean(1), x.std(1), np.abs(np.diff(x, axis=1)).mean(1)])


class Logistic(BaseDetector):
    """What a lab writes first: its logistic regression kept whole as fitted state."""

    def __init__(self, C=1.0):
        self.C = C

    def _fit(self, x, y, seed):
        self.model_ = LogisticRegression(C=self.C).fit(_features(x), y)

    def _predict_proba(self, x):
        return self.model_.predict_proba(_features(x))[:, 1]


class Piped(Logistic):
    """A pipeline of scikit-learn's own types beside plain fitted numbers."""

    def _fit(self, x, y, seed):
        self.model_ = make_pipeline(StandardScaler(), LogisticRegression(C=self.C))
        self.model_.fit(_features(x), y)
        self.classes_seen_ = int(len(np.unique(y)))


class _LabScaler(TransformerMixin, BaseEstimator):
    """A transformer of the lab's own: a type skops does not trust by default."""

    def fit(self, x, y=None):
        self.mean_ = x.mean(0)
        return self

    def transform(self, x):
        return x - self.mean_


class OwnType(Logistic):
    def _fit(self, x, y, seed):
        self.model_ = make_pipeline(_LabScaler(), LogisticRegression()).fit(_features(x), y)


@pytest.mark.parametrize("cls", [Logistic, Piped])
def test_a_detector_holding_a_fitted_estimator_passes_every_check(cls):
    check_detector(cls())  # check_save_load among them


def test_the_saved_estimator_loads_without_pickle_and_scores_as_fitted(tmp_path):
    x, y = toy_windows(80, 30)
    fitted = Piped(C=0.5).fit(x, y, seed=0)
    fitted.save(tmp_path / "m.npz")
    with zipfile.ZipFile(tmp_path / "m.npz") as zf:
        meta = json.loads(str(np.load(io.BytesIO(zf.read("__meta__.npy")), allow_pickle=False)))
        blob = np.load(io.BytesIO(zf.read("model_.npy")), allow_pickle=False)
    assert meta["kinds"]["model_"] == "skops" and meta["kinds"]["classes_seen_"] == "scalar"
    assert blob.dtype == np.uint8
    with zipfile.ZipFile(io.BytesIO(blob.tobytes())) as inner:  # skops' own format: no pickle
        assert "schema.json" in inner.namelist()
        assert not any(n.endswith((".pkl", ".pickle")) for n in inner.namelist())
    loaded = BaseDetector.load(tmp_path / "m.npz")
    assert type(loaded.model_[0]) is StandardScaler and loaded.classes_seen_ == 2
    assert np.array_equal(loaded.predict_proba(x), fitted.predict_proba(x))


def test_an_estimator_of_an_untrusted_type_is_refused_when_saved(tmp_path):
    x, y = toy_windows(80, 30)
    with pytest.raises(
        UsageError, match=r"'model_' \(Pipeline\) holds types skops does not trust.*_LabScaler"
    ):
        OwnType().fit(x, y, seed=0).save(tmp_path / "m.npz")
    assert not (tmp_path / "m.npz").exists()


def test_a_file_holding_an_untrusted_type_is_not_loaded(tmp_path, monkeypatch):
    """A file made elsewhere (another tool, an edited one) with a type outside skops' trusted
    set is refused by name before anything in it runs."""
    import skops.io

    x, y = toy_windows(80, 30)
    fitted = OwnType().fit(x, y, seed=0)
    monkeypatch.setattr("slipbench.base._untrusted", lambda data: [])  # bypass the save check
    fitted.save(tmp_path / "m.npz")
    monkeypatch.undo()
    loads = []
    monkeypatch.setattr(skops.io, "loads", lambda *a, **k: loads.append(a))
    with pytest.raises(
        UsageError,
        match=r"m\.npz: fitted attribute 'model_' holds types skops does not trust: .*_LabScaler",
    ):
        BaseDetector.load(tmp_path / "m.npz")
    assert not loads  # refused before skops builds anything


def test_a_damaged_estimator_is_named(tmp_path):
    x, y = toy_windows(80, 30)
    Logistic().fit(x, y, seed=0).save(tmp_path / "ok.npz")
    with np.load(tmp_path / "ok.npz", allow_pickle=False) as f:
        arrays = {k: f[k] for k in f.files}
    arrays["model_"] = np.frombuffer(b"not a zip", np.uint8)
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(UsageError, match="'model_' is not readable skops data"):
        BaseDetector.load(tmp_path / "bad.npz")


def test_other_objects_are_still_refused(tmp_path):
    x, y = toy_windows(80, 30)
    fitted = Logistic().fit(x, y, seed=0)
    fitted.model_ = {"coef": object()}
    with pytest.raises(
        UsageError, match="holds a dict, not an array, number, string or scikit-learn estimator"
    ):
        fitted.save(tmp_path / "m.npz")
