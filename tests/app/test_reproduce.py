"""`reports/reproduce.sh` regenerates what `reports/` shows: run at a small scale with Holweg's
detector, one cell per protocol matches a fresh `slipbench evaluate` of that protocol (the
same cell key, the same figures, and the README printing them in that protocol's section);
and the committed `reports/` was made with the script's own settings."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from slipbench.data.synth import MODEL_VERSION
from slipbench.store.results import read_results

pytestmark = pytest.mark.slow  # reproduce.sh runs every protocol at a small scale: minutes

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "reports" / "reproduce.sh"
PROTOCOLS = (
    "window-size",
    "sampling-rate",
    "material-holdout",
    "speed-holdout",
    "cross-instance",
    "streaming",
)
FIGURES = (
    "accuracy",
    "accuracy_lo",
    "accuracy_hi",
    "tp_rate",
    "tn_rate",
    "median_delay_ms",
    "false_alarms_per_min",
    "detection_rate",
)
SCALE = "0.01"


def _env(**extra: str) -> dict[str, str]:
    bin_dir = str(Path(sys.executable).parent)  # where this environment's `slipbench` lives
    return {
        **os.environ,
        "PATH": bin_dir + os.pathsep + os.environ.get("PATH", ""),
        "PYTHON": sys.executable,
        **extra,
    }


@pytest.fixture(scope="module")
def reproduced(tmp_path_factory):
    root = tmp_path_factory.mktemp("reproduce")
    env = _env(
        DETECTORS="holweg",
        INPUT_DETECTORS="wavelet-svm",
        REDUCTION_SCALE=SCALE,
        REDUCTION_REPEATS="1",
        SCALE=SCALE,
        JOBS="1",
        RESULTS=str(root / "results"),
        REPORTS=str(root / "reports"),
    )
    done = subprocess.run(
        ["bash", str(SCRIPT)], env=env, capture_output=True, text=True, timeout=1200
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return root


def _section(readme: str, protocol: str) -> str:
    start = readme.index(f"### {protocol}: holweg (grouped split)")
    end = readme.find("\n### ", start + 1)
    return readme[start : end if end > 0 else None]


@pytest.mark.parametrize("protocol", PROTOCOLS)
def test_one_cell_per_protocol_matches_a_fresh_run(reproduced, protocol, tmp_path):
    fresh = tmp_path / "fresh"
    options = (
        ["--protocol-param", "decimation=both"] if protocol == "sampling-rate" else []
    )  # as the script runs it
    done = subprocess.run(
        [
            "slipbench",
            "evaluate",
            "--detector",
            "holweg",
            "--protocol",
            protocol,
            *options,
            "--split",
            "grouped",
            "--scale",
            SCALE,
            "--jobs",
            "0",
            "--out",
            str(fresh),
            "--quiet",
        ],
        env=_env(),
        capture_output=True,
        text=True,
        timeout=600,
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    ours = read_results(fresh)
    ours = ours[ours["status"] == "ok"].sort_values("key")
    if protocol == "streaming":  # a stream with no onset detected has no delay to find
        ours = ours[ours["median_delay_ms"].notna()]
    row = ours.iloc[len(ours) // 2]  # one cell, from the middle of the protocol
    theirs = read_results(reproduced / "results").set_index("key")
    assert row["key"] in theirs.index, (
        "the script's cell has another key: other data, settings or code"
    )
    script_row = theirs.loc[row["key"]]
    for name in FIGURES:
        if name in ours and pd.notna(row[name]):
            # a stream's delays are counted on its samples: no machine time, no jitter
            assert script_row[name] == pytest.approx(row[name], abs=0), name
    appendix = (reproduced / "reports" / "appendix.md").read_text()  # each detector's tables
    # Markdown escapes the brackets of an interval (\[ renders as [)
    section = _section(appendix, protocol).replace("\\[", "[").replace("\\]", "]")
    if protocol == "streaming":
        assert f"{script_row['median_delay_ms']:.1f}" in section
    else:
        text = f"{100 * row['accuracy']:.1f} [{100 * row['accuracy_lo']:.1f}, {100 * row['accuracy_hi']:.1f}]"
        assert text in section, (text, json.loads(row["cell"]))


def test_the_script_writes_every_part(reproduced):
    reports = reproduced / "reports"
    readme = (reports / "README.md").read_text()
    for part in (
        "# The paper reproduced, on simulated data",
        "## Leaderboard",
        "## The splits side by side",
        "## What the reproduction cost",
        "appendix.md",
    ):
        assert part in readme, part
    appendix = (reports / "appendix.md").read_text()
    assert "(grouped split)" in appendix and "(paper split)" in appendix
    assert (reports / "tables.tex").read_text().startswith("\\documentclass")
    assert (
        list((reports / "figures").glob("*.png"))
        and (reproduced / "results" / "report.html").is_file()
    )
    assert not list(reports.glob(".*")), "temporary files left behind"
    reduction = (reports / "reduction" / "README.md").read_text()
    assert "## What the reduction keeps: univariate vs channels" in reduction
    assert "wavelet-svm (channels)" in reduction and "seed 0 (1 per cell)" in reduction


def test_the_committed_reports_were_made_with_the_scripts_settings():
    """reports/README.md states the scale the script defaults to, both splits, every built-in
    detector, and the LSTM at max_epochs=100; it and reports/reduction/ were made from the
    simulation's current model (a new model version means regenerating them)."""
    script = SCRIPT.read_text()
    scale = re.search(r"SCALE=\$\{SCALE:-([\d.]+)\}", script)[1]
    detectors = re.search(r"DETECTORS=\$\{DETECTORS:-([^}]+)\}", script)[1].split()
    readme = (ROOT / "reports" / "README.md").read_text()
    assert f"scale {scale}," in readme
    model = f"slipbench.synth model v{MODEL_VERSION},"
    assert model in readme
    assert model in (ROOT / "reports" / "reduction" / "README.md").read_text()
    assert (
        "grouped: whole trials on one side" in readme
        and "paper: the balanced windows shuffled" in readme
    )
    for detector in detectors:
        assert re.search(rf"^\| {re.escape(detector)} +\|", readme, re.M), detector
    assert re.search(r"^\| lstm +\|[^\n]*max\\?_epochs=100;", readme, re.M)
    assert np.isfinite(float(re.search(r"took (\d+) min", readme)[1]))
