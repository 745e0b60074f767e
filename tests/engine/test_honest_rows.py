"""Rows say what stands behind them: the windows of each class on each side, a labelling the data
cannot give refused or skipped (never replaced by the scenario), and a model that did not learn
flagged in its row and in the report."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import toys

from slipbench.base import BaseDetector
from slipbench.data.read import read_dataset
from slipbench.data.transfer import combine
from slipbench.data.write import write_dataset
from slipbench.engine.check import check_dataset
from slipbench.engine.registry import protocols
from slipbench.engine.runner import Run, evaluate
from slipbench.store.results import ResultsStore

RATE = 500.0


def _lab(folder, name, *, labelled, strata=((("steel", 10.0)),), trials=4, press=(400,), seed=0):
    """A one-unit lab dataset ("Vib", "probe") at 500 Hz: ``trials`` slip recordings of 600
    samples per (material, speed) in ``strata`` (slip from sample 200 when ``labelled``: 0
    before), and pressing recordings of the lengths in ``press`` (labelled 0)."""
    rng = np.random.default_rng(seed)
    rows, samples, labels = [], {}, {}
    recordings = [("slip", m, v, 600) for m, v in strata for _ in range(trials)]
    recordings += [("press", "steel", None, n) for n in press]
    for k, (scenario, material, speed, n) in enumerate(recordings):
        x = rng.normal(0, 1.0, (n, 3)) + 100.0
        lab = np.zeros(n, np.int8)
        if scenario == "slip":
            x[200:] += rng.normal(0, 4.0, (n - 200, 3))  # slip shakes the probe
            lab[200:] = 1
        rid = f"{scenario}-{k:02d}"
        samples[rid], labels[rid] = x, lab
        rows.append(
            dict(
                recording_id=rid,
                sensor_type="Vib",
                sensor_instance="probe",
                scenario=scenario,
                material=material,
                speed_mm_s=speed,
                sampling_rate_hz=RATE,
                channels=("a", "b", "c"),
                units=("count",) * 3,
                source="test lab",
                trial=rid,
            )
        )
    return read_dataset(
        write_dataset(folder / name, pd.DataFrame(rows), samples, labels if labelled else None)
    )


def _window(size):
    return protocols.get("window-size")().set_params(windows=[size])


# ----------------------------------------------------------------------------- labelling
def test_labelling_by_samples_is_refused_before_any_work_without_labels(tmp_path, cli):
    path = _lab(tmp_path, "unlabelled", labelled=False).path
    out = tmp_path / "res"
    code, _, err = cli(
        ["evaluate", "--dataset", str(path), "--detector", "holweg", "--protocol", "window-size"]
        + ["--labels", "majority", "--out", str(out), "--quiet"]
    )
    assert code == 2, err
    assert "'majority'" in err and str(path) in err and "no per-sample slip labels" in err
    assert not out.exists()  # nothing half-written
    code, _, err = cli(["dataset", "check", str(path), "--labels", "any"])
    assert code == 2 and "'any'" in err and "no per-sample slip labels" in err
    # the scenario labelling needs no per-sample labels
    assert len(check_dataset(read_dataset(path), [Run("holweg", "window-size")]).cells)


@pytest.mark.slow
@pytest.mark.parametrize("labelled_side", ["train", "test"])
def test_across_datasets_the_side_without_labels_is_skipped_with_the_reason(
    tmp_path, labelled_side
):
    with_labels = _lab(tmp_path, "with", labelled=True)
    without = _lab(tmp_path, "without", labelled=False, seed=1)
    pair = (with_labels, without) if labelled_side == "train" else (without, with_labels)
    ds = combine(*pair)
    rows = evaluate(
        ds,
        Run("holweg", _window(50), "datasets", 0, "last"),
        ResultsStore(tmp_path / "r"),
        progress=False,
    )
    missing = "test" if labelled_side == "train" else "training"
    assert (rows["status"] == "skipped").all()
    assert (
        rows["reason"]
        .str.contains(
            f"the {missing} dataset gives no per-sample slip labels for Vib probe: labelling 'last'"
        )
        .all()
    )
    # by scenario, the same pair runs
    rows = evaluate(
        ds,
        Run("holweg", _window(50), "datasets", 0, "scenario"),
        ResultsStore(tmp_path / "s"),
        progress=False,
    )
    assert (rows["status"] == "ok").all()


def test_sample_labels_never_fall_back_to_the_scenario(tmp_path):
    from slipbench.data.signals import Signals

    ds = combine(_lab(tmp_path, "a", labelled=True), _lab(tmp_path, "b", labelled=False, seed=1))
    sig = Signals.from_dataset(ds)
    on_b = ds.recordings["dataset_side"].eq("test").to_numpy()
    assert sig.labelled.tolist() == (~on_b).tolist()
    w = sig.windows(50, labelling="majority", values=False)
    assert len(w) and not on_b[w.recording].any()  # no window of the unlabelled dataset
    assert on_b[sig.windows(50, values=False).recording].any()  # by scenario: all of them


# ----------------------------------------------------------------------------- balancing
@pytest.mark.slow
def test_a_test_set_with_few_non_slip_windows_keeps_both_classes(tmp_path):
    """Trained on one dataset, tested on another whose 20 slip strata face 8 pressing windows:
    the equal share of slip (8 // 20) used to be 0, leaving a non-slip-only test set."""
    train = _lab(tmp_path, "train", labelled=False, press=(600,) * 4)
    strata = [(m, v) for m in ("wood", "foam", "steel", "cork", "felt") for v in (5.0, 10, 20, 40)]
    test = _lab(tmp_path, "test", labelled=False, strata=strata, trials=1, press=(401,), seed=2)
    rows = evaluate(
        combine(train, test),
        Run("holweg", _window(50), "datasets"),
        ResultsStore(tmp_path / "r"),
        progress=False,
    )
    row = rows.iloc[0]
    assert row["status"] == "ok" and row["reason"] == ""
    assert (row["test_slip_windows"], row["test_nonslip_windows"]) == (20, 8)
    assert np.isfinite(row["tp_rate"]) and np.isfinite(row["tn_rate"])
    assert row["train_slip_windows"] == row["train_nonslip_windows"]  # the paper's mix
    assert row["train_slip_windows"] + row["train_nonslip_windows"] == row["n_train"]
    assert row["test_slip_windows"] + row["test_nonslip_windows"] == row["n_test"]


# ----------------------------------------------------------------------------- did it learn
@pytest.mark.slow
def test_a_detector_at_chance_on_its_training_windows_is_flagged(tmp_path):
    from rendering import render_report

    ds = _lab(tmp_path, "lab", labelled=True, trials=8, press=(600,) * 8)
    runs = [Run(d, _window(50), "grouped", 0, "majority") for d in (toys.Constant(), toys.Coin())]
    runs.append(Run(toys.Energy(), _window(50), "grouped", 0, "majority"))
    rows = evaluate(ds, runs, ResultsStore(tmp_path / "r"), progress=False).set_index("detector")
    assert (rows["status"] == "ok").all()
    assert rows.loc["constant", "train_balanced_accuracy"] == 0.5
    # epochs where the detector reports them (the LSTM does), else left empty
    assert rows.loc["constant", "epochs"] == 1 and np.isnan(rows.loc["energy", "epochs"])
    for toy in ("constant", "coin"):
        row = rows.loc[toy]
        assert row["train_balanced_accuracy_lo"] <= 0.5 <= row["train_balanced_accuracy_hi"]
        assert row["warnings"].startswith(
            f"did not learn: on its own {row['n_train']} training windows its balanced accuracy"
        )
    learner = rows.loc["energy"]
    assert (
        learner["train_balanced_accuracy_lo"] > 0.5 and "did not learn" not in learner["warnings"]
    )
    text = render_report(rows.reset_index(), "md")
    assert "did not learn: on its own" in text and "Did not learn: the 95 % Wilson interval" in text


class _HeldOut(BaseDetector):
    """Holds a fifth of its windows out as a validation part (as TorchDetector does) and keeps
    its scores there: ``validation_y_``, ``validation_scores_``."""

    def _fit(self, x, y, seed):
        held = np.random.default_rng(seed).random(len(y)) < 0.2
        self._learn(x[~held], y[~held], seed)
        self.validation_y_, self.validation_scores_ = y[held], self._predict_proba(x[held])


class Memorizer(_HeldOut):
    """Recalls the label of each window it trained on, flips a seeded coin on any other: well
    above chance on its own training windows, at chance on the windows it held out."""

    def _learn(self, x, y, seed):
        self.seen_, self.seen_y_, self.seed_ = x, y, int(seed)

    def _predict_proba(self, x):
        recalled = {w.tobytes(): float(c) for w, c in zip(self.seen_, self.seen_y_)}
        coin = np.random.default_rng([self.seed_, len(x)]).random(len(x))
        return np.array([recalled.get(w.tobytes(), c) for w, c in zip(x, coin)])


class HeldOutEnergy(_HeldOut):
    """Mean absolute signal above its training windows' median: learns, and shows it on the
    windows it held out."""

    def _learn(self, x, y, seed):
        self.cut_ = float(np.median(np.abs(x).mean(axis=1)))

    def _predict_proba(self, x):
        return (np.abs(x).mean(axis=1) > self.cut_).astype(float)


@pytest.mark.slow
def test_a_model_at_chance_on_its_validation_part_did_not_learn(tmp_path):
    """Fitting its own training windows is not learning: a detector that holds a validation
    part out is judged there too, and a learner is not flagged by it."""
    ds = _lab(tmp_path, "lab", labelled=True, trials=8, press=(600,) * 8)
    runs = [Run(d, _window(50), "grouped", 0, "majority") for d in (Memorizer(), HeldOutEnergy())]
    rows = evaluate(ds, runs, ResultsStore(tmp_path / "r"), progress=False).set_index("detector")
    memo, energy = rows.loc["memorizer"], rows.loc["held-out-energy"]
    assert memo["train_balanced_accuracy_lo"] > 0.5  # the training windows' rule passes it
    assert memo["validation_balanced_accuracy_lo"] <= 0.5 <= memo["validation_balanced_accuracy_hi"]
    assert memo["warnings"].startswith("did not learn: on its ")
    assert "held-out validation windows" in memo["warnings"]
    assert f"training windows score {memo['train_balanced_accuracy']:.2f}" in memo["warnings"]
    assert energy["validation_balanced_accuracy_lo"] > 0.5
    assert "did not learn" not in energy["warnings"]
