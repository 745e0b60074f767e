"""A fitted scikit-learn estimator as a detector's state: saved through skops, loaded after
skops' trusted-types check, never through pickle."""

from __future__ import annotations

import importlib
import io
import json
import zipfile

import numpy as np
import pytest
from sklearn.base import BaseEstimator, TransformerMixin
from sklearn.base import clone as sk_clone
from sklearn.ensemble import (
    AdaBoostClassifier,
    ExtraTreesClassifier,
    GradientBoostingClassifier,
    HistGradientBoostingClassifier,
    RandomForestClassifier,
    VotingClassifier,
)
from sklearn.linear_model import LogisticRegression
from sklearn.neighbors import KNeighborsClassifier
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import MinMaxScaler, RobustScaler, StandardScaler
from sklearn.tree import DecisionTreeClassifier

from slipbench.base import SKLEARN_STATE_TYPES, BaseDetector
from slipbench.data.toy import toy_windows
from slipbench.errors import UsageError
from slipbench.testing import check_detector, check_save_load


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


class Held(BaseDetector):
    """A detector whose state is a fitted scikit-learn model of one of :data:`FAMILIES`."""

    def __init__(self, family="random-forest"):
        self.family = family

    def _fit(self, x, y, seed):
        self.model_ = sk_clone(FAMILIES[self.family]).fit(_features(x), y)

    def _predict_proba(self, x):
        return self.model_.predict_proba(_features(x))[:, 1]


#: scikit-learn's families a lab reaches for, each fitted as a detector's state
FAMILIES = {
    "decision-tree": DecisionTreeClassifier(random_state=0),
    "random-forest": RandomForestClassifier(5, random_state=0),
    "extra-trees": ExtraTreesClassifier(5, random_state=0),
    "gradient-boosting": GradientBoostingClassifier(n_estimators=5, random_state=0),
    "hist-gradient-boosting": HistGradientBoostingClassifier(max_iter=5, random_state=0),
    "adaboost": AdaBoostClassifier(n_estimators=3, random_state=0),
    "knn": KNeighborsClassifier(5),
    "knn-ball-tree-manhattan": KNeighborsClassifier(5, algorithm="ball_tree", metric="manhattan"),
    "knn-minkowski-3": KNeighborsClassifier(5, p=3),
    "scaled-pipeline": make_pipeline(
        StandardScaler(), MinMaxScaler(), RobustScaler(), LogisticRegression()
    ),
    "voting": VotingClassifier(
        [("tree", DecisionTreeClassifier(random_state=0)), ("knn", KNeighborsClassifier())],
        voting="soft",
    ),
}


@pytest.mark.parametrize("cls", [Logistic, Piped])
def test_a_detector_holding_a_fitted_estimator_passes_every_check(cls):
    check_detector(cls())  # check_save_load among them


def test_every_listed_scikit_learn_type_exists_in_the_installed_scikit_learn():
    """A name that moved in a new scikit-learn would trust nothing and refuse its models."""
    for name in SKLEARN_STATE_TYPES:
        module, _, attr = name.rpartition(".")
        assert isinstance(getattr(importlib.import_module(module), attr), type), name


@pytest.mark.parametrize("family", ["random-forest", "hist-gradient-boosting", "knn"])
def test_trees_boosting_and_neighbours_as_state_pass_the_conformance_save_load(family):
    check_save_load(Held(family))


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_each_family_reloads_with_identical_scores(tmp_path, family):
    x, y = toy_windows(80, 30)
    fitted = Held(family).fit(x, y, seed=0)
    fitted.save(tmp_path / "m.npz")
    loaded = BaseDetector.load(tmp_path / "m.npz")
    assert type(loaded.model_) is type(FAMILIES[family])
    assert np.array_equal(loaded.predict_proba(x), fitted.predict_proba(x))


def test_a_scikit_learn_type_not_listed_is_refused_with_advice(tmp_path, monkeypatch):
    """A type of scikit-learn's own that the list leaves out (a new one, or one whose module
    moved) is named with what to do, not blamed on the lab."""
    monkeypatch.setattr("slipbench.base.SKLEARN_STATE_TYPES", ())
    x, y = toy_windows(80, 30)
    with pytest.raises(
        UsageError,
        match=r"'model_' \(RandomForestClassifier\) holds types skops does not trust.*"
        r"sklearn\.tree\._tree\.Tree; these are scikit-learn types slipbench does not list "
        r"as safe state \(slipbench\.base\.SKLEARN_STATE_TYPES\); use a model made of",
    ):
        Held("random-forest").fit(x, y, seed=0).save(tmp_path / "m.npz")


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
        UsageError,
        match=r"'model_' \(Pipeline\) holds types skops does not trust.*_LabScaler; these are "
        r"types that are not scikit-learn's own; keep their fitted arrays as attributes",
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


@pytest.mark.parametrize("together", [False, True])
def test_a_model_that_cannot_be_saved_warns_in_its_rows(tmp_path, together):
    """Such a model is used in the run that fitted it, and its rows say that every later run
    fits it again (a run used to say nothing and leave no model)."""
    from slipbench.engine.fitting import Job, Lockstep, TestSet, perform

    x, y = toy_windows(80, 30)
    test = TestSet(x, y, np.arange(len(y)) % 8)
    job = Job(OwnType(), 0, 1000.0, x, y, [test], model_path=str(tmp_path / "m.npz"))
    (result,) = perform(Lockstep([job]) if together else job)
    assert result.fields["status"] == "ok"
    assert (
        "model not saved, so every run fits it again: cannot save OwnType: fitted attribute "
        "'model_' (Pipeline) holds types skops does not trust"
    ) in result.fields["warnings"]
    assert not (tmp_path / "m.npz").exists()


def test_a_model_of_listed_types_is_saved_without_warning(tmp_path):
    from slipbench.engine.fitting import Job, TestSet, perform

    x, y = toy_windows(80, 30)
    test = TestSet(x, y, np.arange(len(y)) % 8)
    job = Job(Held("random-forest"), 0, 1000.0, x, y, [test], model_path=str(tmp_path / "m.npz"))
    (result,) = perform(job)
    assert result.fields["status"] == "ok" and "not saved" not in result.fields["warnings"]
    assert (tmp_path / "m.npz").exists()
