"""The reference baseline runs every protocol on both inputs, on the simulation and on the
BioTac SP DoS recordings: no cell fails, and a cell is skipped only with the data's reason."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest
from datagen import subset

from slipbench.data.importers.biotacsp import biotacsp_dos
from slipbench.data.read import read_dataset
from slipbench.engine.plan import Run
from slipbench.engine.registry import detectors, protocols
from slipbench.engine.runner import evaluate
from slipbench.store.results import ResultsStore

SOURCE = Path(__file__).resolve().parents[3] / "shared" / "datasets" / "biotacsp-dos" / "csvs"
# what DoS cannot serve, by protocol: one unit, no slip speeds, no per-sample slip labels
DOS_GAPS = {
    "cross-instance": "one instance",
    "speed-holdout": "no slip speed",
    "streaming": "no per-sample slip labels",
}
NONE_ON_DOS = {"speed-holdout", "streaming"}  # protocols that make no cell there at all


def every_protocol(dataset, store: Path, **options) -> pd.DataFrame:
    """The reference's rows on every registered protocol and every input it reads."""
    reference = next(n for n in detectors.names() if detectors.get(n).reference)
    runs = []
    for name in protocols.names():
        for kind in detectors.get(reference).inputs:
            protocol = protocols.get(name)()
            protocol.set_params(**{k: v for k, v in options.items() if k in protocol.get_params()})
            runs.append(Run(reference, protocol, split=options.get("split", "paper"), input=kind))
    return evaluate(dataset, runs, ResultsStore(store), jobs=1, progress=False)


def check(rows: pd.DataFrame, gaps: dict[str, str]) -> None:
    assert set(rows["input"]) == {"univariate", "channels"}
    assert set(rows["protocol"]) == set(protocols.names())
    assert not rows["status"].isin(["failed", "timeout"]).any(), rows["reason"]
    for (protocol, kind), part in rows.groupby(["protocol", "input"]):
        skipped = part[part["status"] == "skipped"]
        assert skipped["reason"].str.len().gt(0).all()
        if protocol in gaps:
            assert skipped["reason"].str.contains(gaps[protocol]).all(), skipped["reason"]
        else:
            assert (part["status"] == "ok").all(), (protocol, kind, part["reason"])


@pytest.mark.slow  # every protocol twice on the small simulation's Nano17s: about 2 min
def test_every_protocol_and_both_inputs_on_the_simulation(small, tmp_path):
    nano17 = subset(small, small.recordings["sensor_type"].eq("Nano17"))  # 3 units, 6 channels
    check(every_protocol(nano17, tmp_path / "out"), {})


@pytest.mark.slow  # every protocol twice on DoS: 30-40 s on the shared machine
@pytest.mark.skipif(not SOURCE.is_dir(), reason=f"BioTacSP-DoS not found at {SOURCE}")
def test_every_protocol_and_both_inputs_on_dos(tmp_path):
    biotacsp_dos(SOURCE, tmp_path / "dos")
    options = {"windows": ["500ms"], "split": "grouped"}
    rows = every_protocol(read_dataset(tmp_path / "dos"), tmp_path / "out", **options)
    check(rows, DOS_GAPS)
    for _, part in rows[rows["status"] == "ok"].groupby("input"):
        assert set(part["protocol"]) == set(protocols.names()) - NONE_ON_DOS
