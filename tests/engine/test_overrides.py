"""A detector that runs another setting than the one asked says so: the engine makes each
declared override a warning of the row, and the report's parameter table shows what ran."""

from __future__ import annotations

import json

from labshapes import slow_imu

from slipbench.engine.plan import Run
from slipbench.engine.runner import evaluate
from slipbench.report.provenance import fitted_tables, fitting_warnings, header_tables
from slipbench.store.columns import overridden
from slipbench.store.results import ResultsStore


def test_overridden_says_what_ran_beside_what_was_asked():
    assert (
        overridden("band", [0.6, 2.16], [50.0, 400.0], "above Nyquist 2.4 Hz")
        == "band=[0.6, 2.16] (asked [50, 400]: above Nyquist 2.4 Hz)"
    )


def test_bandpass_on_a_slow_imu_warns_and_shows_the_band_that_ran(tmp_path):
    from slipbench.protocols.window_size import WindowSize

    ds = slow_imu(tmp_path)  # 4.8 Hz: Nyquist 2.4 Hz, far below 50-400 Hz
    run = Run("bandpass", WindowSize(windows=[8]), "grouped", 0, labels="any")
    rows = evaluate(ds, [run], ResultsStore(tmp_path / "o"), progress=False)
    assert (rows["status"] == "ok").all(), rows["reason"].tolist()
    said = "band=[0.6, 2.16] (asked [50, 400]: above Nyquist 2.4 Hz, replaced by [Nyquist / 4, 0.9 Nyquist])"
    assert (rows["warnings"] == f"ran {said}").all()
    fitted = json.loads(rows["fitted"].iloc[0])
    assert fitted["overrides"]["band"]["ran"] == [0.6, 2.16]
    tables = {t.label: t for t in header_tables(rows)}
    assert tables["tab:detectors"].cells[0][0] == f"{said}; order=4"
    # the fitted table keeps its own columns; the override is in the warnings table
    fitted_table, warned = fitted_tables(rows)
    assert "overrides" not in fitted_table.columns and fitted_table.cells[0][1] == "0.6–2.2 (1)"
    assert warned.cells[0][0] == f"ran {said}"
    # and evaluate's closing lines say it, as the report's warnings table does
    assert fitting_warnings(rows) == [f"bandpass: ran {said} (in 1 of 1 finished cells: IMU Index)"]


def test_evaluate_closes_with_the_fallback_as_a_warning(tmp_path, cli):
    ds = slow_imu(tmp_path)
    argv = ["evaluate", "--detector", "bandpass", "--protocol", "window-size", "--quiet"]
    argv += ["--protocol-param", "windows=[8]", "--labels", "any", "--split", "grouped"]
    code, out, err = cli([*argv, "--dataset", str(ds.path), "--out", str(tmp_path / "o")])
    assert code == 0, err
    assert "warning: bandpass: ran band=[0.6, 2.16] (asked [50, 400]: above Nyquist 2.4 Hz" in err


def test_a_warning_in_several_wordings_counts_the_others():
    import pandas as pd

    rows = pd.DataFrame(
        {
            "status": ["ok"] * 3,
            "detector": ["holweg"] * 3,
            "sensor_type": ["Pad"] * 3,
            "sensor_instance": ["left"] * 3,
            "warnings": ["band 0-4 Hz", "band 0-4 Hz", "band 0-2 Hz"],
        }
    )
    assert fitting_warnings(rows) == [
        "holweg: band 0-4 Hz (and 1 other value) (in 3 of 3 finished cells: Pad left)"
    ]
