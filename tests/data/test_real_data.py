"""Real third-party recordings (BioTacSP-DoS), read from the shared folder beside the project,
never copied into it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from slipbench.app.info import info
from slipbench.data.importers import biotacsp_dos
from slipbench.data.read import read_dataset
from slipbench.detectors.holweg import Holweg
from slipbench.engine.runner import Run, evaluate
from slipbench.protocols.window_size import WindowSize
from slipbench.store.results import ResultsStore

SOURCE = Path(__file__).resolve().parents[3] / "shared" / "datasets" / "biotacsp-dos" / "csvs"
pytestmark = pytest.mark.skipif(not SOURCE.is_dir(), reason=f"BioTacSP-DoS not found at {SOURCE}")


@pytest.fixture(scope="module")
def dos(tmp_path_factory):
    return read_dataset(biotacsp_dos(SOURCE, tmp_path_factory.mktemp("dos") / "dos"))


def test_import_keeps_every_recording(dos):
    assert dos.fingerprint == "aac611fa5f8ae950"  # what `dataset fetch biotacsp-dos` must give
    rec = dos.recordings
    assert len(rec) == 306
    assert (rec["scenario"] == "press").sum() == len(list((SOURCE / "t").glob("*.csv")))
    assert set(rec["material"]) == {
        "bottle",
        "brush",
        "bubbles",
        "cardboard",
        "case",
        "hd",
        "pen",
        "plate",
        "screw",
        "sponge",
        "striped",
    }
    first = sorted((SOURCE / "w").glob("*.csv"))[0]
    raw = np.loadtxt(first, delimiter=",", skiprows=1, dtype=np.float32)
    np.testing.assert_array_equal(dos.samples[f"w/{first.stem}"], raw)
    assert info(dos)["samples"].sum() == sum(len(s) for s in dos.samples.values())


@pytest.mark.slow
def test_documented_mapping_gives_the_same_dataset(dos, tmp_path, cli):
    """docs/reference/datasets.md's biotacsp-dos.toml through `dataset import csv` is `dataset import biotacsp-dos`."""
    import re

    docs = (Path(__file__).resolve().parents[2] / "docs" / "reference" / "datasets.md").read_text()
    (block,) = [b for b in re.findall(r"```toml\n(.*?)```", docs, flags=re.S) if "BioTacSP" in b]
    (tmp_path / "biotacsp-dos.toml").write_text(block)
    code, out, err = cli(
        [
            "dataset",
            "import",
            "csv",
            str(SOURCE),
            str(tmp_path / "csv"),
            "--config",
            str(tmp_path / "biotacsp-dos.toml"),
        ]
    )
    assert code == 0, err
    code, out, err = cli(["dataset", "validate", str(tmp_path / "csv")])
    assert code == 0 and f"fingerprint {dos.fingerprint}" in out, out + err
    assert "306 recordings in 306 trials" in out


@pytest.mark.slow
def test_holweg_on_real_slip_data_beats_chance(dos, tmp_path):
    """Balanced slip against touch on a real BioTac SP, grouped split: every recording on one side."""
    rows = evaluate(
        dos, Run(Holweg(), WindowSize(), split="grouped"), ResultsStore(tmp_path), progress=False
    )
    assert (rows["status"] == "ok").all()
    at50 = rows[rows["window"] == 50].iloc[0]
    assert at50["accuracy_lo"] > 0.5, at50[["accuracy", "accuracy_lo", "accuracy_hi"]].to_dict()


@pytest.mark.slow
def test_the_lstm_at_its_defaults_learns_on_a_real_biotac(dos, tmp_path):
    """The paper's LSTM on raw BioTac SP counts (DoS, 500 ms, grouped, seeds 0-4): it learned
    nothing at slipbench 0.1.0's input range (docs/studies/lstm-study.md); at its defaults every seed
    learns, and the mean balanced accuracy reaches 70 %."""
    from slipbench.detectors.lstm import LSTM

    runs = [Run(LSTM(), WindowSize(windows=["500ms"]), "grouped", seed) for seed in range(5)]
    rows = evaluate(dos, runs, ResultsStore(tmp_path), jobs=0, progress=False)
    assert (rows["status"] == "ok").all() and len(rows) == 5
    assert not rows["warnings"].fillna("").str.contains("did not learn").any(), rows["warnings"]
    assert rows["balanced_accuracy"].mean() >= 0.70, rows["balanced_accuracy"].tolist()
