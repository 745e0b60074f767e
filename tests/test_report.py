"""Report layouts pinned by golden files; LaTeX that compiles; the paper's numbers; plots.

Regenerate the golden files after an intended layout change with
``SLIPBENCH_UPDATE_GOLDEN=1 pytest -q tests/test_report.py`` and review the diff.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import pandas as pd
import pytest
from resultgen import all_rows, fake_rows

from slipbench.cli import main
from slipbench.paper import paper_frame
from slipbench.registry import protocols
from slipbench.report import protocol_table, render_report

GOLDEN = Path(__file__).parent / "golden"


def check_golden(name: str, text: str) -> None:
    path = GOLDEN / name
    if os.environ.get("SLIPBENCH_UPDATE_GOLDEN"):
        path.write_text(text)
    assert text == path.read_text(), f"{name} changed; see the module docstring to update it"


def test_markdown_layout_of_every_table():
    check_golden("report.md", render_report(all_rows(), "md", paper=True, intervals=True))


def test_latex_layout_of_every_table():
    check_golden("report.tex", render_report(all_rows(), "latex", standalone=True))


def test_latex_structure():
    text = render_report(all_rows(), "latex", paper=True, intervals=True, standalone=True)
    assert text.count(r"\begin{table}") == text.count(r"\end{table}") == text.count(r"\begin{tabular}{|") > 10
    for spec, body in re.findall(r"\\begin\{tabular\}\{(\|[c|]+)\}\n(.*?)\\end\{tabular\}\n\\label", text, re.S):
        width = spec.count("c")
        for line in body.splitlines():
            if line.endswith(r"\\") and r"\multicolumn" not in line:
                # nested tabulars (the rate header) hold their own & and \\
                flat = re.sub(r"\\begin\{tabular\}.*?\\end\{tabular\}", "x", line)
                assert flat.count("&") == width - 1, line
    assert "_" not in re.sub(r"\\_|\\label\{[^}]*\}", "", text.split(r"\begin{document}")[1])


@pytest.mark.skipif(shutil.which("pdflatex") is None, reason="no LaTeX engine installed")
def test_latex_compiles(tmp_path):
    tex = tmp_path / "report.tex"
    tex.write_text(render_report(all_rows(), "latex", paper=True, intervals=True, standalone=True))
    done = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", tex.name],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout[-2000:]
    assert (tmp_path / "report.pdf").stat().st_size > 0


def test_repeats_show_mean_and_spread():
    rows = fake_rows("sampling-rate", seeds=(0, 1, 2))
    text = protocol_table(rows, protocols.get("sampling-rate")().layout)
    one = rows[(rows["sensor_type"] == "Nano17") & (rows["sensor_instance"] == "index") & (rows["downsample"] == 32)]
    assert f"{100 * one['accuracy'].mean():.1f} ± {100 * one['accuracy'].std():.1f}" in text
    assert "Mean ± standard deviation across seeds" in text


def test_paper_numbers_are_complete():
    sizes = {"window-size": 48, "sampling-rate": 48, "material-holdout": 80, "speed-holdout": 64, "cross-instance": 41}
    for name, n in sizes.items():
        assert len(paper_frame(name)) == n, name  # sampling rate: 40 published + 8 full-rate from Table I
    ws = paper_frame("window-size").set_index(["sensor_type", "sensor_instance", "window"])["accuracy"]
    assert ws[("Nano17", "index", 50)] == pytest.approx(0.880) and ws[("BioTacSP", "middle", 200)] == pytest.approx(0.851)
    mat = paper_frame("material-holdout").set_index(["sensor_type", "sensor_instance", "material", "training"])["accuracy"]
    assert mat[("Nano17", "middle", "neoprene", "without")] == pytest.approx(0.434)
    holweg = paper_frame("holweg").set_index("sensor_type")
    assert list(holweg["accuracy"]) == pytest.approx([0.714, 0.809, 0.764])
    assert list(holweg["threshold"]) == [0.0015, 3.5, 25.0]
    rates = paper_frame("rates_window_50").set_index("sensor_type")
    assert rates.loc["OptoForce20", "tn_rate"] == pytest.approx(0.8979)


def test_report_command_on_real_results(small_path, tmp_path, capsys):
    out = tmp_path / "results"
    with pytest.raises(SystemExit) as exit_:
        main(["evaluate", "--detector", "holweg", "--protocol", "window-size", "--dataset", str(small_path),
              "--out", str(out), "--quiet"])
        raise SystemExit(0)
    assert (exit_.value.code or 0) == 0
    assert "Classification Accuracy (%) at Window Size" in capsys.readouterr().out  # evaluate's own table
    rows = pd.read_parquet(out / "results.parquet")
    assert {"balanced_accuracy", "auroc_lo", "accuracy_wilson_hi"} <= set(rows.columns)
    with pytest.raises(SystemExit) as exit_:
        main(["report", str(out), "--paper", "--intervals", "--plots", str(tmp_path / "fig"),
              "--out", str(tmp_path / "report.md")])
        raise SystemExit(0)
    assert (exit_.value.code or 0) == 0
    text = (tmp_path / "report.md").read_text()
    assert "Published (Van Wyk & Falco, LSTM)" in text and "holweg (paper)" in text
    assert {p.name for p in (tmp_path / "fig").iterdir()} == {"window-size-holweg.png", "window-size-holweg.pdf"}
    with pytest.raises(SystemExit) as exit_:
        main(["report", str(tmp_path / "nothing")])
    assert exit_.value.code == 2


def test_plots_for_every_protocol(tmp_path):
    from slipbench.plots import write_plots

    paths = write_plots(all_rows(), tmp_path)
    stems = {p.stem for p in paths}
    assert stems == {"window-size-lstm", "window-size-holweg", "sampling-rate-lstm", "material-holdout-lstm",
                     "speed-holdout-lstm", "cross-instance-lstm"}
    assert all(p.stat().st_size > 1000 for p in paths)
