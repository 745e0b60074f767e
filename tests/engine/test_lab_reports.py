"""Reports and checks of datasets shaped like labs': every protocol is named in every report
format and in `dataset check`, a protocol that makes no cell says why, no traceback. The
builders of test_outside_data make the data; `skin` adds one without materials or speeds."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from test_outside_data import _recording, hundred_hz, taxels, vibration

from slipbench.data.read import read_dataset
from slipbench.data.write import write_dataset
from slipbench.engine.registry import protocols


def skin(folder, seed=4, n_trials=6):
    """(d) One 8-taxel skin at 500 Hz, integer counts, no material and no speed: slip trials
    that hold, then slip (per-sample labels), and pressing trials; few trials, so streaming
    rests on few test trials and onsets."""
    rng = np.random.default_rng(seed)
    rows, samples, labels = [], {}, {}
    for k in range(n_trials):
        for scenario in ("slip", "press"):
            n, onset = 1500, int(rng.integers(400, 700))
            x = rng.integers(500, 520, size=(n, 8))
            lab = np.zeros(n, np.int8)
            if scenario == "slip":
                x[onset:] += rng.integers(-40, 40, size=(n - onset, 8))
                lab[onset:] = 1
            rid = f"{scenario}-{k}"
            samples[rid], labels[rid] = x, lab
            rows.append(_recording(rid, ("Skin", "pad"), scenario, x, 500.0))
    return read_dataset(write_dataset(folder / "skin", pd.DataFrame(rows), samples, labels))


SHAPES = {
    "no speeds": (hundred_hz, "scenario"),
    "one unit, hold-slip": (taxels, "majority"),
    "one class": (vibration, "scenario"),
    "no materials": (skin, "scenario"),
}


@pytest.mark.slow
@pytest.mark.parametrize("shape", list(SHAPES))
def test_every_protocol_reports_and_checks_on_lab_shaped_data(tmp_path, cli, shape):
    build, labels = SHAPES[shape]
    data, out = build(tmp_path).path, tmp_path / "results"
    runs = [("holweg", "all")]
    if shape == "no speeds":  # a second detector: stand-ins side by side
        runs.append(("bandpass", "speed-holdout"))
    for detector, protocol in runs:
        code, _, err = cli(
            [
                "evaluate",
                *("--detector", detector, "--protocol", protocol),
                *("--dataset", str(data), "--labels", labels, "--out", str(out), "--quiet"),
            ]
        )
        assert code == 0 and "Traceback" not in err, err
    names = protocols.names()
    rows = pd.read_parquet(out / "results.parquet")
    assert set(rows["protocol"]) == set(names)
    for fmt in ("md", "latex", "html"):
        for extra in ([], ["--intervals", "--paper"]):
            code, text, err = cli(["report", str(out), "--format", fmt, *extra])
            assert code == 0 and "Traceback" not in err, (fmt, err)
            for name in names:
                assert f">{name}<" in text if fmt == "html" else name in text, (fmt, name)
    code, text, err = cli(["dataset", "check", str(data), "--protocol", "all", "--labels", labels])
    assert code == 0 and "Traceback" not in err, err
    for name in names:
        assert f"## {name}" in text, name
    if shape == "no speeds":
        for report in (text, cli(["report", str(out)])[1]):
            assert "none of its 24 slip recordings gives a speed" in report
    if shape == "no materials":  # streaming ran on 3 test trials: flagged in rows and tables
        streamed = rows[(rows["protocol"] == "streaming") & (rows["status"] == "ok")]
        assert len(streamed) and streamed["low_n"].astype(bool).all()
        section = cli(["report", str(out)])[1].split("\n## streaming\n")[1].split("\n## ")[0]
        assert section.count("†") >= 8 and "fewer than 10 onsets" in section
