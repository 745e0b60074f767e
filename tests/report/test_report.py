"""Report layouts pinned by golden files; LaTeX that compiles within the text width; the
paper's numbers; honest headers and marks; plots. (Updating the golden files: tests/goldens.py.)
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import numpy as np
import pandas as pd
import pytest
from goldens import check_golden
from rendering import render_report
from resultgen import all_rows, fake_rows, recorded

from slipbench.app.cli import main
from slipbench.data.synth import MODEL_VERSION
from slipbench.report.blocks import LOW_NOTE
from slipbench.report.document import protocol_table
from slipbench.report.paper import paper_frame


@pytest.mark.slow
def test_markdown_layout_of_every_table():
    check_golden("report.md", render_report(all_rows(), "md", paper=True, intervals=True))


def test_latex_layout_of_every_table():
    check_golden("report.tex", render_report(all_rows(), "latex", standalone=True))


@pytest.mark.slow
def test_latex_structure():
    text = render_report(all_rows(), "latex", paper=True, intervals=True, standalone=True)
    assert (
        text.count(r"\begin{table}")
        == text.count(r"\end{table}")
        == text.count(r"\begin{tabular}{|")
        > 10
    )
    found = re.findall(
        r"\\begin\{tabular\}\{(\|[c|]+)\}\n(.*?)\\end\{tabular\}\n(?:\}%\n\\ifdim[^\n]*\n)?\\label",
        text,
        re.S,
    )
    assert len(found) > 10
    for spec, body in found:
        width = spec.count("c")
        for line in body.splitlines():
            if line.endswith(r"\\") and r"\multicolumn" not in line:
                # nested tabulars (the rate header) hold their own & and \\
                flat = re.sub(r"\\begin\{tabular\}.*?\\end\{tabular\}", "x", line)
                assert flat.count("&") == width - 1, line
    assert "_" not in re.sub(r"\\_|\\label\{[^}]*\}", "", text.split(r"\begin{document}")[1])


def _overfull(tmp_path, text: str) -> list[float]:
    """Compile ``text`` with pdflatex; the widths (pt) of its overfull boxes."""
    tex = tmp_path / "report.tex"
    tex.write_text(text)
    done = subprocess.run(
        ["pdflatex", "-interaction=nonstopmode", "-halt-on-error", tex.name],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stdout[-2000:]
    assert (tmp_path / "report.pdf").stat().st_size > 0
    log = (tmp_path / "report.log").read_text(errors="replace")
    return [float(w) for w in re.findall(r"Overfull \\[hv]box \(([\d.]+)pt too", log)]


@pytest.mark.skipif(shutil.which("pdflatex") is None, reason="no LaTeX engine installed")
def test_latex_compiles_within_the_text_width(tmp_path):
    rows = pd.concat(
        [
            all_rows(),
            fake_rows("material-holdout", "holweg"),
            fake_rows("sampling-rate", "holweg"),
            fake_rows("cross-instance", "bandpass"),
        ],
        ignore_index=True,
    )
    widths = _overfull(
        tmp_path, render_report(rows, "latex", paper=True, intervals=True, standalone=True)
    )
    assert max(widths, default=0) <= 10, f"overfull boxes of {widths} pt"


def test_repeats_show_mean_and_spread():
    rows = fake_rows("sampling-rate", seeds=(0, 1, 2))
    text = protocol_table(rows)
    one = rows[
        (rows["sensor_type"] == "Nano17")
        & (rows["sensor_instance"] == "index")
        & (rows["downsample"] == 32)
    ]
    assert f"{100 * one['accuracy'].mean():.1f} ± {100 * one['accuracy'].std():.1f}" in text
    assert "Mean ± standard deviation across seeds" in text


def test_paper_numbers_are_complete():
    sizes = {
        "window-size": 48,
        "sampling-rate": 48,
        "material-holdout": 80,
        "speed-holdout": 64,
        "cross-instance": 41,
    }
    for name, n in sizes.items():
        assert len(paper_frame(name)) == n, (
            name
        )  # sampling rate: 40 published + 8 full-rate from Table I
    ws = paper_frame("window-size").set_index(["sensor_type", "sensor_instance", "window"])[
        "accuracy"
    ]
    assert ws[("Nano17", "index", 50)] == pytest.approx(0.880) and ws[
        ("BioTacSP", "middle", 200)
    ] == pytest.approx(0.851)
    mat = paper_frame("material-holdout").set_index(
        ["sensor_type", "sensor_instance", "material", "training"]
    )["accuracy"]
    assert mat[("Nano17", "middle", "neoprene", "without")] == pytest.approx(0.434)
    holweg = paper_frame("holweg").set_index("sensor_type")
    assert list(holweg["accuracy"]) == pytest.approx([0.714, 0.809, 0.764])
    assert list(holweg["threshold"]) == [0.0015, 3.5, 25.0]
    rates = paper_frame("rates_window_50").set_index("sensor_type")
    assert rates.loc["OptoForce20", "tn_rate"] == pytest.approx(0.8979)


@pytest.mark.slow
def test_report_command_on_real_results(small_path, tmp_path, capsys):
    out = tmp_path / "results"
    with pytest.raises(SystemExit) as exit_:
        main(
            [
                "evaluate",
                "--detector",
                "holweg",
                "--protocol",
                "window-size",
                "--dataset",
                str(small_path),
                "--out",
                str(out),
                "--quiet",
            ]
        )
        raise SystemExit(0)
    assert (exit_.value.code or 0) == 0
    assert (
        "Classification Accuracy (%) at Window Size" in capsys.readouterr().out
    )  # evaluate's own table
    rows = pd.read_parquet(out / "results.parquet")
    assert {"balanced_accuracy", "auroc_lo", "accuracy_wilson_hi"} <= set(rows.columns)
    with pytest.raises(SystemExit) as exit_:
        main(
            [
                "report",
                str(out),
                "--paper",
                "--intervals",
                "--plots",
                str(tmp_path / "fig"),
                "--out",
                str(tmp_path / "report.md"),
            ]
        )
        raise SystemExit(0)
    assert (exit_.value.code or 0) == 0
    text = (tmp_path / "report.md").read_text()
    # Markdown escapes what a caption holds: "\&" renders as "&"
    assert "Published (Van Wyk \\& Falco, their LSTM)" in text and "holweg (paper)" in text
    assert "Ours minus published" not in text  # holweg is not the paper's model
    assert (
        f"| Data | simulated (slipbench.synth model v{MODEL_VERSION}, scale 0.02, seed 1;"
        in re.sub(r" +", " ", text)
    )
    assert "Smallest test set" in text
    assert {p.name for p in (tmp_path / "fig").iterdir()} == {
        "window-size-holweg.png",
        "window-size-holweg.pdf",
    }
    assert "![window-size, holweg (paper split).](fig/window-size-holweg.png)" in text
    with pytest.raises(SystemExit) as exit_:
        main(["report", str(tmp_path / "nothing")])
    assert exit_.value.code == 2


@pytest.mark.slow
def test_plots_for_every_protocol(tmp_path):
    from rendering import write_plots

    paths = write_plots(all_rows(), tmp_path)
    stems = {p.stem for p in paths}
    assert stems == {
        "window-size-lstm",
        "window-size-holweg",
        "window-size-detectors",
        "sampling-rate-lstm",
        "material-holdout-lstm",
        "speed-holdout-lstm",
        "cross-instance-lstm",
    }
    assert all(p.stat().st_size > 1000 for p in paths)


def test_figures_fit_a_column_with_one_legend_and_units():
    from slipbench.report.outline import outline
    from slipbench.report.plots import figure_specs

    for spec in figure_specs(outline(all_rows()), paper=True):
        fig = spec.draw()
        assert fig.get_size_inches()[0] == pytest.approx(3.5), spec.stem
        assert len(fig.legends) <= 1 and not any(ax.get_legend() for ax in fig.axes), spec.stem
        for ax in fig.axes:
            if ax.get_images() or ax.lines:  # a panel (colour bars hold no image or line)
                labels = [ax.get_ylabel(), *(a.get_xlabel() for a in fig.axes)]
                assert any(labels), spec.stem
        ylabels = {ax.get_ylabel() for ax in fig.axes if ax.lines}
        assert ylabels <= {"accuracy (%)"}, (spec.stem, ylabels)
        xlabels = {ax.get_xlabel() for ax in fig.axes} - {""}
        assert xlabels and all("(" in x or x in ("material", "tested on") for x in xlabels), (
            spec.stem,
            xlabels,
        )


def test_colour_scale_shows_its_true_range():
    from slipbench.report.outline import outline
    from slipbench.report.plots import accuracy_range, figure_specs

    assert accuracy_range(np.array([[62.0, 91.0]])) == (50.0, 100.0)  # chance stays on the scale
    assert accuracy_range(np.array([[31.2, np.nan, 70.0]])) == (
        30.0,
        100.0,
    )  # nothing below 50 clamps
    rows = fake_rows("material-holdout")
    rows.loc[rows.index[0], "accuracy"] = 0.312
    (spec,) = [
        s for s in figure_specs(outline(rows), paper=False) if s.stem == "material-holdout-lstm"
    ]
    fig = spec.draw()
    images = [im for ax in fig.axes for im in ax.get_images()]
    assert len(images) == 3  # with, without, with minus without
    assert images[0].get_clim() == (30.0, 100.0) and images[1].get_clim() == (30.0, 100.0)
    low, high = images[2].get_clim()
    assert -low == high > 0  # the difference panel centred on 0


def test_captions_name_detector_and_protocol():
    text = render_report(all_rows(), "latex")
    captions = re.findall(r"\\caption\{(.*?)\}\n", text)
    window = [
        c for c in captions if c.startswith("Slip state classification at various window sizes")
    ]
    assert len(window) == 2 and len(set(window)) == 2  # holweg's and lstm's no longer identical
    assert any("Detector holweg, protocol window-size" in c for c in window)


def test_few_test_trials_are_marked_in_every_table():
    rows = fake_rows("window-size", "holweg").assign(n_test_trials=40)
    rows.loc[rows["window"] == 5, "n_test_trials"] = 6
    text = render_report(rows, "md")
    body = text.split("\n## window-size\n")[1]
    assert (
        body.count("†") >= 8 and LOW_NOTE in body
    )  # the eight units at window 5, and the footnote
    assert (
        "| Few test trials (†) | 8 finished cells (marked in every table)"
        in text.replace("  ", " ").replace("  ", " ")
        or "8 finished cells (marked in every table)" in text
    )
    flagged = rows.assign(low_n=False)  # the rows' own flag wins over the trial count
    assert "†" not in render_report(flagged, "md").split("\n## window-size\n")[1]


def test_header_says_where_the_data_come_from(tmp_path):
    from slipbench.report.provenance import dataset_source

    folder = tmp_path / "synth-v2-scale0.05-seed3"
    assert dataset_source(str(folder)).startswith(
        "simulated (slipbench.synth model v2, scale 0.05, seed 3"
    )
    assert "not readable here" in dataset_source(str(folder))
    assert dataset_source("") == "a dataset built in memory (no path recorded)"
    real = tmp_path / "lab"
    real.mkdir()
    pd.DataFrame({"source": ["lab A, 2026", None]}).to_parquet(real / "recordings.parquet")
    assert dataset_source(str(real)) == f"recorded: source lab A, 2026 (at {real})"
    assert "not readable here" in dataset_source(str(tmp_path / "gone"))


def test_a_dataset_of_many_sources_is_summed_up_in_the_header(tmp_path):
    """A lab's importer may give each of 1,000 files its own source: the header's data line
    counts them instead of listing them all (it was 72,000 characters, breaking the table)."""
    folder = tmp_path / "lab"
    folder.mkdir()
    files = [f"csvs/n/object{i:04d}.csv" for i in range(1000)]
    pd.DataFrame({"source": files}).to_parquet(folder / "recordings.parquet")
    rows = fake_rows("window-size").assign(dataset_path=str(folder))
    text = render_report(rows, "md", leaderboard_only=True)
    (line,) = [t for t in text.splitlines() if t.startswith("| Data ")]
    from slipbench.report.markdown import md_text

    shown = line.split(" | ")[1].strip(" |")
    assert shown == md_text(
        f"recorded: 1,000 sources, csvs/n/object0000.csv … csvs/n/object0999.csv (at {folder})"
    )
    from slipbench.report.provenance import dataset_source

    dos = [f"BioTacSP-DoS (Zapata-Impata et al. 2019), direction {d}" for d in ("aw", "cw", "e")]
    dos += [f"BioTacSP-DoS (Zapata-Impata et al. 2019), direction {d}" for d in "nstw"]
    pd.DataFrame({"source": dos}).to_parquet(folder / "recordings.parquet")
    assert dataset_source(str(folder)) == (
        "recorded: sources BioTacSP-DoS (Zapata-Impata et al. 2019), direction "
        f"{{aw, cw, e, n, s, t, w}} (at {folder})"
    )


def test_fitted_choices_and_warnings_are_shown():
    rows = fake_rows("window-size", "holweg")
    rows["fitted"] = ['{"band_hz": [0, 80], "threshold": 0.5}'] * 4 + [
        '{"band_hz": [40, 100], "threshold": 0.25}'
    ] * (len(rows) - 4)
    rows["warnings"] = [
        "the fitted band 0-80 Hz starts at 0 Hz: it thresholds drift, not vibration"
    ] * 4 + [""] * (len(rows) - 4)
    text = render_report(rows, "md")
    assert "**What fitting chose: holweg.**" in text and "40–100 (2)" in text
    assert (
        "**Warnings about fitting (4 of 48 finished cells).**" in text and "starts at 0 Hz" in text
    )


def test_findings_of_the_paper_reproduce_on_its_own_numbers():
    """Rows that hold the published numbers give, for each finding, the paper's own value."""
    from slipbench.report.document import layouts, protocol_order
    from slipbench.report.findings import findings_table

    parts = []
    for protocol in (
        "window-size",
        "sampling-rate",
        "material-holdout",
        "speed-holdout",
        "cross-instance",
    ):
        ref = paper_frame(protocol)
        keys = [c for c in ref.columns if c not in ("accuracy", "tp_rate", "tn_rate")]
        rows = ref.assign(
            protocol=protocol,
            detector="lstm",
            split="paper",
            seed=0,
            status="ok",
            decimation="plain",
            antialias=False,
            protocol_params="{}",
            cell=[json.dumps({k: r[k] for k in keys}) for r in ref.to_dict("records")],
            **recorded(protocol, "lstm"),
        )
        parts.append(rows)
    rows = pd.concat(parts, ignore_index=True)
    found = layouts(rows)
    table = findings_table(rows, found, protocol_order(found))
    assert len(table.rows) == 3 + 3 + 2 + 2 + 1
    for (protocol, finding), (paper, ours) in zip(table.rows, table.cells):
        assert paper == ours, (protocol, finding)
    assert (
        table.cells[7][0] == "Neoprene (-9.1)"
    )  # the paper's material finding: neoprene needs its own data


def _paper_rows() -> pd.DataFrame:
    """Result rows that hold the published numbers: the LSTM's five tables, its TP/TN rates at
    window 50 (per sensor, on every finger) and Holweg's accuracy at window 50 (per sensor)."""
    parts = []
    for protocol in (
        "window-size",
        "sampling-rate",
        "material-holdout",
        "speed-holdout",
        "cross-instance",
    ):
        ref = paper_frame(protocol)
        keys = [c for c in ref.columns if c != "accuracy"]
        parts.append(
            ref.assign(
                protocol=protocol,
                detector="lstm",
                split="paper",
                seed=0,
                status="ok",
                decimation="plain",
                antialias=False,
                protocol_params="{}",
                cell=[json.dumps({k: r[k] for k in keys}) for r in ref.to_dict("records")],
                **recorded(protocol, "lstm"),
            )
        )
    rows = pd.concat(parts, ignore_index=True)
    rates = paper_frame("rates_window_50").set_index("sensor_type")
    at50 = (rows["protocol"] == "window-size") & (rows["window"] == 50)
    rows.loc[at50, "tp_rate"] = rows.loc[at50, "sensor_type"].map(rates["tp_rate"])
    rows.loc[at50, "tn_rate"] = rows.loc[at50, "sensor_type"].map(rates["tn_rate"])
    holweg = rows[at50].assign(
        detector="holweg",
        accuracy=lambda f: f["sensor_type"].map(
            paper_frame("holweg").set_index("sensor_type")["accuracy"]
        ),
    )
    rows = pd.concat([rows, holweg], ignore_index=True)
    for m in ("accuracy", "tp_rate", "tn_rate"):  # narrow intervals: 1 point each side
        rows[f"{m}_lo"], rows[f"{m}_hi"] = rows[m] - 0.01, rows[m] + 0.01
    return rows


def test_the_paper_shows_its_own_findings():
    """Every finding's criterion holds on the published numbers, and rows holding them give
    "ours" equal to "paper": the table measures what the paper states."""
    from slipbench.report.document import layouts
    from slipbench.report.findings import paper_findings_table

    rows = _paper_rows()
    table = paper_findings_table(rows, layouts(rows))
    assert len(table.rows) == 9
    for (finding,), (paper, ours, shown, _) in zip(table.rows, table.cells):
        assert shown == "shown", finding
        bare = re.sub(r" \[[^]]*\]|; vs .*|; 5 − .*", "", ours)  # ours without the intervals
        numbers = [re.findall(r"[-+]?\d+\.\d", t) for t in (bare, paper)]
        assert re.sub(r"[-+]?\d+\.\d", "", bare) == re.sub(r"[-+]?\d+\.\d", "", paper), finding
        assert np.allclose(*(np.array(n, dtype=float) for n in numbers), atol=0.11), finding
    assert (
        "82.7 → 61.1 (-21.5)" in table.cells[3][0]
    )  # BioTac SP at 425-850 Hz against 212.5 Hz and below
    assert table.cells[4][0].startswith("5 mm/s")


def test_a_finding_ours_contradict_says_so():
    from slipbench.report.document import layouts
    from slipbench.report.findings import paper_findings_table

    rows = _paper_rows()
    flat = (rows["protocol"] == "sampling-rate") & (rows["sensor_type"] == "BioTacSP")
    rows.loc[flat, "accuracy"] = 0.8  # no collapse at low rates, and no rise either
    rows.loc[rows["detector"] == "holweg", "accuracy"] += 0.3  # Holweg ahead of the LSTM
    table = paper_findings_table(rows, layouts(rows))
    shown = {finding: verdict for (finding,), (_, _, verdict, _) in zip(table.rows, table.cells)}
    # no rise on the BioTac SP: the others' rises are shown, its flat curve is not
    rise = shown["Accuracy rises with the sampling rate (lowest → full rate, points)"]
    assert rise.startswith("partly: 2 shown, 1 ") and rise.endswith(("contradicted", "undecided"))
    # a narrow interval around no drop excludes a collapse of 10 points: contradicted, not "no"
    assert (
        shown["BioTac SP collapses at 212.5 Hz and below (mean at ≥ 425 Hz → at ≤ 212.5 Hz, %)"]
        == "contradicted"
    )
    assert (
        shown[
            "The LSTM is ahead of Holweg by 10-20 points at window 50 (points; mean over sensors)"
        ]
        == "contradicted"  # Holweg ahead: the interval lies below a lead of 10
    )


def test_a_report_of_two_splits_leads_with_grouped_and_sets_paper_beside_it():
    paper = pd.concat(
        [fake_rows("window-size", d) for d in ("holweg", "lstm", "bandpass")], ignore_index=True
    )
    grouped = paper.assign(
        split="grouped", accuracy=paper["accuracy"] - 0.05, key=paper["key"] + "g"
    )
    text = render_report(pd.concat([paper, grouped], ignore_index=True), "md")
    assert text.index("(grouped split)") < text.index("(paper split)")
    assert "The leaderboard ranks the grouped split" in text
    # the leaderboard ranks one split: 48 cells, not 96
    assert "all (48)" in text and "all (96)" not in text
    side = text[text.index("**The grouped split beside the paper split") :]
    for detector in ("holweg", "lstm", "bandpass"):
        assert re.search(
            rf"\|\s*window-size\s*\|\s*{detector}\s*\|\s*48\s*\|[^|]+\|[^|]+\|\s*\+5\.0 \\\[\+5\.0, \+5\.0\\\]",
            side,
        )


def test_findings_on_a_labs_sensors_compare_what_they_can():
    """A lab's own sensor type (not one of the paper's three) with --paper: the findings table
    gives what its rows allow, and none of the paper's sensors' figures for it."""
    from slipbench.report.document import layouts
    from slipbench.report.findings import paper_findings_table

    rows = fake_rows("window-size").assign(sensor_type="Vib")
    rows["cell"] = [
        json.dumps(
            {"sensor_type": "Vib", "sensor_instance": r["sensor_instance"], "window": r["window"]}
        )
        for r in rows.to_dict("records")
    ]
    table = paper_findings_table(rows, layouts(rows))
    cells = dict(zip((f for (f,) in table.rows), table.cells))
    rise = cells["Accuracy rises with the window (window 5 → 200, points)"]
    assert rise[1].startswith("Vib ") and "Nano17" not in rise[1]
    assert cells[
        "The LSTM is ahead of Holweg by 10-20 points at window 50 (points; mean over sensors)"
    ][1:3] == ["—", "—"]
    assert "BioTac SP collapses" not in " ".join(cells)  # no sampling-rate rows
    render_report(rows, "md", paper=True)  # and the whole report renders
