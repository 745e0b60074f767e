"""The xela-proactive card and importer: Xela uSkin recordings of imanlab/proactive-slip-control,
read from the shared folder beside the project (never copied into it), fetched over loopback."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from publisher import serve

from slipbench.data.card import builtin_cards, sha256_of
from slipbench.data.importers import xela_proactive
from slipbench.data.read import read_dataset, read_description
from slipbench.data.schema import RATE_TOLERANCE
from slipbench.errors import DataError

SOURCE = Path(__file__).resolve().parents[3] / "shared" / "datasets" / "xela-proactive" / "data_set"
needs_xela = pytest.mark.skipif(not SOURCE.is_dir(), reason=f"xela-proactive not found at {SOURCE}")
FINGERPRINT = "f507924e6b30be5b"  # `dataset fetch xela-proactive` of the commit the card pins
TRIALS = 7
FILES = 5  # per trial: two pads, labels, meta data, robot state


@pytest.fixture(scope="module")
def xela(tmp_path_factory):
    if not SOURCE.is_dir():
        pytest.skip(f"xela-proactive not found at {SOURCE}")
    return read_dataset(xela_proactive(SOURCE, tmp_path_factory.mktemp("xela") / "xela"))


def test_the_card_pins_the_commit_and_lists_what_the_importer_reads():
    card = builtin_cards()["xela-proactive"]
    assert card.importer == "xela-proactive" and card.license == "MIT"
    assert card.base_url.endswith("/73c84b02e382040ca4ab8de1b37d836b8f511d40/data_set/")
    assert "imanlab/proactive-slip-control" in card.citation
    names = {f.path.split("/")[1] for f in card.files}
    assert names == {
        "meta_data.csv",
        "robot_state.csv",  # the rows' own clock, against which the stated rate is checked
        "slip_label.csv",
        "xela_sensor1.csv",
        "xela_sensor2.csv",
    }
    assert len(card.files) == FILES * TRIALS


@needs_xela
def test_the_cards_hashes_are_those_of_the_shared_files():
    for f in builtin_cards()["xela-proactive"].files:
        assert sha256_of(SOURCE / f.path) == f.sha256, f.path
        assert (SOURCE / f.path).stat().st_size == f.size, f.path


def test_import_gives_two_pads_per_trial_with_both_classes(xela):
    rec = xela.recordings
    assert len(rec) == 2 * TRIALS and rec["trial"].nunique() == TRIALS
    assert set(rec["n_channels"]) == {48} and set(rec["sensor_instance"]) == {"pad1", "pad2"}
    assert set(rec["scenario"]) == {"hold-slip"} and set(rec["material"]) == {"box"}
    assert rec["speed_mm_s"].isna().all()
    labels = np.concatenate(list(xela.slip_labels.values()))
    assert (labels == 1).sum() > 0 and (labels == 0).sum() > 0
    first = sorted(SOURCE.glob("data_sample_*"))[0]
    raw = pd.read_csv(first / "xela_sensor2.csv")
    row = rec.set_index("recording_id").loc[f"{first.name}/pad2"]
    assert list(row["channels"]) == list(raw.columns)
    np.testing.assert_array_equal(xela.samples[f"{first.name}/pad2"], raw.to_numpy(np.float64))
    rate = pd.read_csv(first / "meta_data.csv")["frequency_hz"].iloc[0]
    assert row["sampling_rate_hz"] == rate
    rates = rec["sampling_rate_hz"]  # each trial its own rate, one unit: within the tolerance
    assert rates.max() <= rates.min() * (1 + RATE_TOLERANCE)


def test_a_failed_grasp_is_unlabelled(xela):
    folder = sorted(SOURCE.glob("data_sample_*"))[4]
    table = pd.read_csv(folder / "slip_label.csv")
    assert table["fail"].sum() > 0  # this trial loses the box
    labels = xela.slip_labels[f"{folder.name}/pad1"]
    expected = np.where(table["fail"] == 1, -1, table["slip"]).astype(np.int8)
    np.testing.assert_array_equal(labels, expected)


@needs_xela
def test_validate_passes_on_the_converted_set(cli, xela, tmp_path):
    out = xela_proactive(SOURCE, tmp_path / "x")
    code, text, err = cli(["dataset", "validate", str(out)])
    assert code == 0, err
    assert "14 recordings in 7 trials" in text and FINGERPRINT in text


@needs_xela
def test_fetch_over_loopback_gives_the_imported_dataset(cli, xela, tmp_path, monkeypatch):
    monkeypatch.setenv("SLIPBENCH_CACHE", str(tmp_path / "cache"))
    with serve(SOURCE.parent) as (url, requested):
        argv = ["dataset", "fetch", "xela-proactive", "--url", f"{url}/data_set"]
        code, _, err = cli([*argv, "--out", str(tmp_path / "x")])
    assert code == 0, err
    assert len(requested) == FILES * TRIALS  # the card's files only (no marker file)
    assert read_dataset(tmp_path / "x").fingerprint == xela.fingerprint == FINGERPRINT
    assert '"card": "xela-proactive"' in read_description(tmp_path / "x")["slipbench.source"]


@needs_xela
def test_a_pad_file_with_a_column_missing_is_refused(tmp_path):
    copy = tmp_path / "data_set"
    trial = sorted(SOURCE.glob("data_sample_*"))[0]
    shutil.copytree(trial, copy / trial.name)
    pad = copy / trial.name / "xela_sensor1.csv"
    pad.chmod(0o644)
    pd.read_csv(pad).iloc[:, :47].to_csv(pad, index=False)
    with pytest.raises(DataError, match=r"xela_sensor1\.csv: 47 columns; a uSkin pad has 48"):
        xela_proactive(copy, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_dataset_import_offers_every_importer(cli):
    from slipbench.app.commands.dataset import IMPORT_KINDS
    from slipbench.data.importers import IMPORTERS

    assert IMPORT_KINDS == ["csv", *IMPORTERS]  # xela-proactive beside biotacsp-dos
    code, out, _ = cli(["dataset", "import", "--help"])
    assert code == 0 and "xela-proactive" in out


@needs_xela
def test_dataset_import_reads_the_shared_copy(cli, tmp_path):
    code, out, err = cli(["dataset", "import", "xela-proactive", str(SOURCE), str(tmp_path / "x")])
    assert code == 0, err
    assert out.startswith(f"wrote {tmp_path / 'x'}")
    assert read_dataset(tmp_path / "x").fingerprint == FINGERPRINT


def _one_trial(tmp_path: Path) -> Path:
    """A writable copy of the first trial, in a data_set folder of its own."""
    trial = sorted(SOURCE.glob("data_sample_*"))[0]
    shutil.copytree(trial, tmp_path / "data_set" / trial.name)
    for f in (tmp_path / "data_set" / trial.name).iterdir():
        f.chmod(0o644)
    return tmp_path / "data_set" / trial.name


@needs_xela
def test_the_rows_clock_bears_out_the_stated_rate_and_its_steps_are_said(cli, tmp_path):
    """59.75 Hz stated; robot_state.csv's per-row time gives 59.6-59.8 Hz over each trial's
    rows (the start and stop times of meta_data.csv span 2 s more, hence 36-45 Hz over them)."""
    out = xela_proactive(SOURCE, tmp_path / "x")
    timing = json.loads(read_description(out)["slipbench.timing"])
    assert timing["files"] == TRIALS and "stated_off" not in timing and timing["gaps"] == 0
    code, text, err = cli(["dataset", "validate", str(out)])
    assert code == 0, err
    assert (
        "warning: uneven steps: in 2 of 7 files 5-95 % of the rows are 12-21 ms apart "
        "(median 17 ms)" in text
    )
    assert "stated rate" not in text


@needs_xela
def test_a_clock_that_disagrees_with_the_stated_rate_is_said(cli, tmp_path):
    folder = _one_trial(tmp_path)
    state = pd.read_csv(folder / "robot_state.csv")
    state["time"] *= 1.4  # rows over their times: 59.75 / 1.4 = 42.7 Hz
    state.to_csv(folder / "robot_state.csv", index=False)
    out = xela_proactive(folder.parent, tmp_path / "x")
    code, text, err = cli(["dataset", "info", str(out)])
    assert code == 0, err
    assert (
        "warning: stated rate: 1 of 1 files state 59.75 Hz, but their rows over their "
        "time columns come to 42.65 Hz; the stated rate is used" in text
    )
    state.iloc[:-1].to_csv(folder / "robot_state.csv", index=False)
    with pytest.raises(DataError, match=r"robot_state.csv: 403 rows, but the pads' files hold 404"):
        xela_proactive(folder.parent, tmp_path / "y")
