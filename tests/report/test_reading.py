"""Reports for reading: the summary and its appendix, the streaming trade-off figure (a panel
per detector, monotone curves on a log axis), names and units as the dataset spells them."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from resultgen import all_rows, fake_rows

from slipbench.report.blocks import Table
from slipbench.report.document import (
    Detail,
    Heading,
    build_report,
    flatten,
    render,
    split_appendix,
)
from slipbench.report.plots import envelope, tradeoff
from slipbench.report.provenance import header_tables, sensor_units
from slipbench.vocabulary import label


def _rows() -> pd.DataFrame:
    return pd.concat([all_rows(), fake_rows("material-holdout", "holweg")], ignore_index=True)


def _own(table: Table) -> bool:
    """A table of one detector alone (its caption names it)."""
    return table.subject.startswith("Detector ") or "averaged across fingers (" in table.caption


@pytest.mark.slow
def test_summary_leaves_each_detectors_tables_to_the_appendix():
    blocks = build_report(_rows(), intervals=True, paper=True)
    summary, appendix = split_appendix(blocks, "appendix.md")
    whole = [b for b in flatten(blocks) if isinstance(b, Table)]
    kept = [b for b in summary if isinstance(b, Table)]
    moved = [b for b in appendix if isinstance(b, Table)]
    assert not any(isinstance(b, Detail) for b in summary + appendix)
    # every table once, in one of the two files; a detector's own ones in the appendix only
    assert sorted(t.label for t in kept + moved) == sorted(t.label for t in whole)
    published = [t for t in moved if t.label.endswith("-paper")]
    assert moved and published and all(_own(t) for t in moved if t not in published)
    assert not any(_own(t) for t in kept)
    # the summary keeps a table of every detector side by side for each protocol they share
    side = [t for t in kept if "every detector side by side" in t.caption]
    assert {"window-size", "material-holdout"} <= {t.subject.split()[1].rstrip(",") for t in side}
    text, rest = render(summary, "md"), render(appendix, "md")
    assert (
        "In the appendix, the published table and each detector's own tables and figures of "
        "this section: [appendix.md, window-size](appendix.md#window-size)"
    ) in text
    assert "(appendix.md#at-window-50-accuracy-and-tptn-rates)" in text
    assert "### window-size: holweg (paper split)" in rest
    assert "### window-size: holweg" not in text
    # the split loses nothing: the whole report holds what the two files hold
    assert len(render(blocks, "md")) < len(text) + len(rest)


@pytest.mark.slow
def test_report_command_writes_summary_and_appendix(tmp_path, cli):
    results = tmp_path / "results.parquet"
    _rows().to_parquet(results)
    out, extra = tmp_path / "r" / "README.md", tmp_path / "r" / "appendix.md"
    code, _, err = cli(
        ["report", str(results), "--paper", "--out", str(out), "--appendix", str(extra)]
    )
    assert code == 0, err
    summary, appendix = out.read_text(), extra.read_text()
    assert (
        "(appendix.md#sampling-rate)" in summary
        and "Detector lstm, protocol sampling-rate" in appendix
    )
    assert "Detector lstm, protocol" not in summary and "[README.md](README.md)" in appendix
    whole = tmp_path / "whole.md"
    assert cli(["report", str(results), "--paper", "--out", str(whole)])[0] == 0
    assert "Detector lstm, protocol sampling-rate" in whole.read_text()  # default: everything
    code, _, err = cli(["report", str(results), "--format", "html", "--appendix", str(extra)])
    assert code == 2 and "--appendix" in err


def _two_splits() -> pd.DataFrame:
    paper = pd.concat(
        [fake_rows(p, d) for p in ("window-size", "sampling-rate") for d in ("holweg", "lstm")],
        ignore_index=True,
    )
    grouped = paper.assign(split="grouped", key=paper["key"] + "g")
    return pd.concat([grouped, paper], ignore_index=True)


def test_a_summary_shows_every_detector_on_its_lead_split_alone():
    """A summary stays short as splits add up: every detector side by side on the split its
    leaderboard ranks; the other split's side by side, the published tables and each
    detector's own go to the appendix, and the link of each section names them."""
    blocks = build_report(_two_splits(), paper=True)
    summary, appendix = split_appendix(blocks, "appendix.md", summary_path="README.md")
    kept = [b.label for b in summary if isinstance(b, Table)]
    moved = [b.label for b in appendix if isinstance(b, Table)]
    whole = [b.label for b in flatten(blocks) if isinstance(b, Table)]
    assert sorted(kept + moved) == sorted(whole)  # nothing lost, nothing twice
    side = [label for label in kept if "-detectors" in label]
    assert side and all("-detectors-grouped" in label for label in side)
    assert any("-detectors-" in label and "grouped" not in label for label in moved)
    assert not any(label.endswith("-paper") for label in kept)
    text, rest = render(summary, "md"), render(appendix, "md")
    assert "### window-size: every detector (paper split)" in rest
    assert "### window-size: published" in rest and "### window-size: published" not in text
    assert (
        "In the appendix, every detector on the other splits, the published table and each "
        "detector's own tables and figures of this section: "
        "[appendix.md, sampling-rate](appendix.md#sampling-rate)."
    ) in text
    assert "[README.md](README.md)" in rest and "the published table" in rest
    # the whole report shows every table where it stood before: the summary holds under half
    assert len(text) < 0.5 * len(render(blocks, "md"))


def _stream_rows(detectors=("holweg", "bandpass", "lstm")) -> pd.DataFrame:
    """Streaming rows whose sweeps saw-tooth (detections fall as the threshold drops, as a
    stream already alarming at an onset detects nothing) and reach 0 false alarms."""
    rows = []
    for d, detector in enumerate(detectors):
        for sensor, instance in (("Nano17", "index"), ("Nano17", "middle"), ("ff", "hd")):
            thresholds = np.linspace(0.05, 0.95, 19)
            fa = np.round(300 * (1 - thresholds) ** 3, 3)
            rate = np.clip(np.sin(6 * thresholds) * 0.4 + thresholds * 0.6 + 0.05 * d, 0, 1)
            curve = pd.DataFrame(
                {
                    "threshold": thresholds,
                    "detection_rate": rate,
                    "median_delay_ms": 20.0,
                    "false_alarms_per_min": fa,
                }
            )
            rows.append(
                {
                    "protocol": "streaming",
                    "detector": detector,
                    "status": "ok",
                    "sensor_type": sensor,
                    "sensor_instance": instance,
                    "tradeoff": curve.to_json(orient="records"),
                    "detection_rate": 0.5,
                    "false_alarms_per_min": 40.0,
                    "op_detection_rate": 0.3,
                    "op_false_alarms_per_min": 0.0,
                }
            )
    return pd.DataFrame(rows)


def test_envelope_is_monotone():
    sweep = pd.DataFrame(json.loads(_stream_rows()["tradeoff"].iloc[0]))
    raw = sweep.sort_values("false_alarms_per_min")["detection_rate"].to_numpy()
    assert (np.diff(raw) < 0).any()  # the sweep saw-tooths ...
    curve = envelope(sweep)
    assert (np.diff(curve["false_alarms_per_min"]) > 0).all()
    assert (np.diff(curve["detection_rate"]) >= 0).all()  # ... its envelope does not
    assert curve["detection_rate"].max() == sweep["detection_rate"].max()


def test_tradeoff_is_one_log_panel_per_detector():
    rows = _stream_rows()
    fig = tradeoff(rows, "streaming, every detector")
    panels = [ax for ax in fig.axes if ax.get_visible()]
    assert [ax.get_title(loc="left") for ax in panels] == ["holweg", "lstm", "bandpass"]
    for ax in panels:
        assert ax.get_xscale() == "log"
        curves = [line for line in ax.lines if line.get_linestyle() == "-"]
        assert len(curves) == 3  # one per unit
        for line in curves:
            x, y = (np.asarray(v, float) for v in line.get_data())
            assert (np.diff(x) > 0).all() and (np.diff(y) >= 0).all()
            assert (x > 0).all()  # 0 false alarms drawn at the axis's left edge
        markers = {line.get_marker() for line in ax.lines if line.get_linestyle() == "None"}
        assert markers == {"o", "x"}  # the detector's own threshold and the operating point
        first = ax.get_xticks()[0]
        assert ax.xaxis.get_major_formatter()(first, 0) == "0" and first < 0.5
    assert len(fig.legends) == 1
    names = [t.get_text() for t in fig.legends[0].get_texts()]
    assert names == ["Nano17", "ff", "threshold 0.5", "operating point"]  # no legend per curve
    assert {ax.get_xlabel() for ax in panels} - {""} == {"false alarms per minute"}
    assert {ax.get_ylabel() for ax in panels} - {""} == {"detection rate (%)"}
    one = tradeoff(rows[rows["detector"] == "lstm"], "lstm")
    assert len([ax for ax in one.axes if ax.get_visible()]) == 1


def test_names_and_units_as_the_dataset_spells_them(tmp_path):
    assert label("sensor_instance", "ff") == "ff" and label("sensor_instance", "hd") == "hd"
    assert label("sensor_instance", "index") == "Index" and label("material", "PVC") == "PVC"
    assert label("material", "neoprene") == "Neoprene" and label("material", "rubber") == "rubber"
    assert label("train_instance", "combined") == "Combined"
    lab = tmp_path / "lab"
    lab.mkdir()
    pd.DataFrame(
        {
            "sensor_type": ["hd", "hd", "Nano17", "skin"],
            "sensor_instance": ["ff", "ff2", "index", "a"],
            "units": [["N", "N"], ["N", "N"], [None, "NA"], [""]],
            "source": ["lab A", "lab A", "lab A", "lab A"],
        }
    ).to_parquet(lab / "recordings.parquet")
    assert sensor_units(str(lab)) == "hd (ff, ff2): N; Nano17 (index): unitless; skin (a): unitless"
    assert sensor_units(str(tmp_path / "gone")) == ""
    # two results folders of one dataset, reached by two paths: its source once
    rows = fake_rows("window-size", "holweg")
    rows = pd.concat(
        [
            rows.assign(dataset_path=str(lab), dataset_fingerprint="abc"),
            rows.assign(dataset_path=str(lab) + "/", dataset_fingerprint="abc"),
        ],
        ignore_index=True,
    )
    run = header_tables(rows)[0]
    what = dict(zip((r[0] for r in run.rows), (c[0] for c in run.cells)))
    assert what["Data"].count("lab A") == 1 and what["Dataset fingerprint"] == "abc"
    assert what["Sensors (units)"].count("hd (ff, ff2): N") == 1
    text = render([run], "md")
    assert "NA" not in text and "Ff" not in text and "Hd" not in text


def test_latex_group_header_wraps_to_its_columns_width():
    """A header wider than the value columns under it would widen the last column alone (the
    window-size table's "200" was as wide as three others): it wraps to their width."""
    from slipbench.report.latex import to_latex

    group = "Classification Accuracy (%) at Window Size"
    narrow = Table("T.", ["Unit"], group, ["5", "10"], [("a",)], [["88.0", "90.1"]], "t")
    header = next(line for line in to_latex(narrow).splitlines() if r"\bfseries" in line)
    lines = header.split(r"\begin{tabular}{@{}c@{}}")[1].split(r"\end{tabular}")[0].split(r"\\")
    assert lines == ["Classification", r"Accuracy (\%) at", "Window Size"]
    wide = [f"{w} samples of the window" for w in (5, 10)]
    roomy = Table("T.", ["Unit"], group, wide, [("a",)], [["88.0", "90.1"]], "t")
    assert r"\bfseries Classification Accuracy (\%) at Window Size}" in to_latex(roomy)


def test_latex_page_tables_stay_under_their_headings_and_within_the_page():
    from slipbench.report.latex import LONG_TABLE_LINES, latex_lines, to_latex

    def table(n: int) -> Table:
        rows = [(f"unit {i}",) for i in range(n)]
        return Table(
            "Tall.", ["Unit"], "", ["accuracy"], rows, [["88.0 [86.9, 89.1]"]] * n, "tab:t"
        )

    tall, short = table(40), table(5)
    assert latex_lines(tall) > LONG_TABLE_LINES >= latex_lines(short)
    long = to_latex(tall, page=True)
    assert r"\begin{longtable}" in long and r"\endhead" in long and r"\begin{table}" not in long
    placed = to_latex(short, page=True)
    assert placed.startswith(r"\begin{table}[H]") and r"\resizebox{\linewidth}" in placed
    # a fragment for another document keeps its floats as they were
    assert to_latex(tall).startswith(r"\begin{table}[!htbp]") and "longtable" not in to_latex(tall)
    text = render([Heading("one", 2), Heading("its table", 3), tall], "latex", standalone=True)
    assert text.index(r"\slipneed{") < text.index(r"\subsection*{its table}")
    assert r"\usepackage{longtable}" in text and r"\usepackage{float}" in text
