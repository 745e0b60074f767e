"""Reports of rows that labs' data give: a protocol that made no cell renders its reason in
every format, a layout by detector sets detectors side by side, marks and captions come from the
cells (streaming counts, one-class test sets, the window the rows used)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from rendering import render_report
from resultgen import fake_rows

from slipbench.protocol import NO_CELL, Layout
from slipbench.report.blocks import LOW_MARK, LOW_NOTE, STREAM_LOW_NOTE
from slipbench.report.document import protocol_table
from slipbench.report.presentation import shown, shown_protocol
from slipbench.report.tables import build_table, caption_of, low_n, side_by_side

REASON = (
    "protocol 'speed-holdout' makes no cell on this dataset: none of its 24 slip recordings "
    "gives a speed (speed_mm_s is empty): there is no slip speed to hold out"
)


def _stand_in(protocol: str, detector: str, reason: str = REASON) -> dict:
    """A stand-in row as the runner writes it for a protocol that makes no cell."""
    return {
        "key": f"none-{protocol}-{detector}",
        "protocol": protocol,
        "protocol_params": json.dumps({"window": 50}),
        "detector": detector,
        "split": "paper",
        "seed": 0,
        "cell": NO_CELL,
        "cells": "none",
        "window": 1,
        "status": "skipped",
        "reason": reason,
        "dataset_fingerprint": "f00d",
    }


def _lab_rows() -> pd.DataFrame:
    """Two detectors' window-size rows, and speed-holdout stand-ins for both."""
    return pd.concat(
        [
            fake_rows("window-size", "holweg"),
            fake_rows("window-size", "bandpass"),
            pd.DataFrame([_stand_in("speed-holdout", d) for d in ("holweg", "bandpass")]),
        ],
        ignore_index=True,
    )


@pytest.mark.parametrize(
    "fmt, standalone", [("md", False), ("latex", False), ("latex", True), ("html", False)]
)
def test_a_protocol_without_cells_says_why_in_every_format(fmt, standalone):
    text = render_report(_lab_rows(), fmt, standalone=standalone, intervals=True)
    assert "speed-holdout" in text and "none of its 24 slip recordings gives a speed" in text
    assert "Detectors: holweg, bandpass" in text
    assert "Protocol speed-holdout." not in text  # no table laid out from the stand-in's key
    assert "Laid out from its cell keys" not in text


def test_stand_ins_beside_cells_of_another_dataset_say_which_dataset():
    rows = pd.concat(
        [
            fake_rows("speed-holdout", "holweg"),
            pd.DataFrame([_stand_in("speed-holdout", "holweg") | {"dataset_fingerprint": "beef"}]),
        ],
        ignore_index=True,
    ).assign(dataset_path=lambda r: np.where(r["dataset_fingerprint"] == "beef", "lab", "sim"))
    text = render_report(rows, "md")
    section = text.split("\n## speed-holdout\n")[1]
    assert "On dataset lab: protocol 'speed-holdout' makes no cell" in section
    assert "explicit training of indicated speeds" in section  # the other dataset's table


def test_evaluate_prints_the_reason_for_a_protocol_without_cells():
    rows = pd.DataFrame([_stand_in("speed-holdout", "holweg")])
    assert protocol_table(rows).startswith("No table: " + REASON)


def test_a_layout_by_detector_sets_the_detectors_side_by_side():
    """A layout from cell keys with one key puts the detectors in its columns (the crash
    "Grouper for 'detector' not 1-dimensional" with two detectors)."""
    rows = pd.DataFrame(
        [
            {"detector": d, "level": lvl, "status": "ok", "accuracy": a}
            for d, a in (("holweg", 0.7), ("bandpass", 0.9))
            for lvl in ("a", "b")
        ]
    )
    layout = shown(Layout(("level",), "detector"), None, "p")
    table = side_by_side(rows, layout, ["holweg", "bandpass"])
    assert table is not None and table.columns == ["bandpass", "holweg"]
    assert table.cells == [["90.0", "70.0"], ["90.0", "70.0"]]


def _stream_rows(trials: int, onsets: int) -> pd.DataFrame:
    row = {
        "protocol": "streaming",
        "detector": "holweg",
        "sensor_type": "Skin",
        "sensor_instance": "pad",
        "status": "ok",
        "n_test_trials": trials,
        "n_onsets": onsets,
    }
    for m in ("detection_rate", "median_delay_ms", "p95_delay_ms", "false_alarms_per_min"):
        row |= {m: 0.0, f"{m}_lo": 0.0, f"{m}_hi": 0.0}
    return pd.DataFrame([row])


def test_streaming_cells_on_few_trials_or_onsets_are_marked():
    from slipbench.protocols.streaming import Streaming

    LAYOUT = shown_protocol(Streaming(), "streaming")

    assert low_n(_stream_rows(3, 40)).all() and low_n(_stream_rows(40, 3)).all()
    assert not low_n(_stream_rows(40, 40)).any()
    table = build_table(_stream_rows(3, 40), LAYOUT, intervals=True)
    assert table.cells[0][-1] == f"0.00 [0.00, 0.00]{LOW_MARK}"
    assert table.cells[0][0] == f"0.0 [0.0, 0.0]{LOW_MARK}"
    assert STREAM_LOW_NOTE in table.notes and LOW_NOTE not in table.notes
    assert LOW_MARK not in str(build_table(_stream_rows(40, 40), LAYOUT).cells)


def test_a_one_class_test_set_of_many_trials_is_not_marked():
    rows = fake_rows("window-size", "holweg").assign(
        n_test_trials=1000,
        n_test_clusters_slip=1000,
        n_test_clusters_nonslip=0,
        low_n=True,  # as rows written before the fix say
    )
    assert not low_n(rows).any()
    assert LOW_MARK not in render_report(rows, "md").split("\n## window-size\n")[1]
    few = rows.assign(n_test_clusters_slip=4)
    assert low_n(few).all()


def test_the_caption_names_the_window_the_rows_used():
    rows = fake_rows("sampling-rate").assign(window=100)
    text = render_report(rows, "md", paper=True)
    ours = [
        line
        for line in text.splitlines()
        if "Detector lstm, protocol sampling-rate" in line and "downsampled" in line
    ]
    assert ours and all("window 100 downsampled" in line for line in ours)
    published = [line for line in text.splitlines() if line.startswith("**Published")]
    assert any("window 200 downsampled" in line for line in published)
    per_sensor = rows.assign(window=np.where(rows["sensor_type"] == "BioTacSP", 170, 200))
    assert (
        caption_of("window {window} downsampled", per_sensor)
        == "window 200 (Nano17, OptoForce20), 170 (Biotac SP) downsampled"
    )
    assert caption_of("window {nothing}", rows) == "window {nothing}"


def test_an_interval_that_is_not_estimable_is_marked_not_low_n():
    """The issue's cell: enough trials of each class (not low n), but one class holds a single
    trial of its own stratum: its interval is the whole range, [0, 100]. The tables mark it
    with what it is, in Markdown and LaTeX, and not as low n."""
    from slipbench.report.blocks import UNESTIMABLE_MARK, UNESTIMABLE_NOTE
    from slipbench.report.latex import escape
    from slipbench.report.tables import summarize, unestimable

    rows = fake_rows("window-size", "holweg").assign(
        n_test_clusters_slip=30, n_test_clusters_nonslip=30, ci_note=""
    )
    first = rows.index[0]
    rows.loc[first, ["accuracy_lo", "accuracy_hi"]] = [0.0, 1.0]
    rows.loc[first, "ci_note"] = (
        "accuracy, tn_rate: a class holds a single cluster, so nothing measures how its "
        "clusters vary; the interval given is the figure's whole range"
    )
    assert unestimable(rows, "accuracy").tolist() == [True] + [False] * (len(rows) - 1)
    assert not unestimable(rows, "tp_rate").any()  # the note names the figures it holds
    assert summarize(rows, ["cell"])["unestimable"].sum() == 1
    from slipbench.protocols.window_size import WindowSize

    table = build_table(rows, shown_protocol(WindowSize(), "window-size"), intervals=True)
    marked = [c for line in table.cells for c in line if UNESTIMABLE_MARK in c]
    assert len(marked) == 1 and marked[0].endswith(f" [0.0, 100.0]{UNESTIMABLE_MARK}")
    assert UNESTIMABLE_NOTE in table.notes and LOW_MARK not in str(table.cells)
    assert escape(UNESTIMABLE_MARK) == r"\S{}"
