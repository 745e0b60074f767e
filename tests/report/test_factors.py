"""No figure averages two values of a factor (issue 33): every field of a cell's key is listed
in slipbench.stats.factors, and each factor in turn, run with two values into one folder, gives
tables, figures, leaderboards, findings and a compare that keep the values apart."""

from __future__ import annotations

import re

import pandas as pd
import pytest
from resultgen import fake_rows

from slipbench.engine import plan
from slipbench.engine.plan import Run, keys
from slipbench.gate.compare import compare
from slipbench.protocol import Cell, Part
from slipbench.report.compare import comment_markdown
from slipbench.report.document import ReportOptions, _protocol_blocks, build_report, render
from slipbench.report.outline import outline
from slipbench.report.plots import FigureSpec
from slipbench.stats.factors import (
    ENTRANTS,
    KEY_FIELDS,
    SETTINGS,
    factor_values,
    named_entrants,
    one_class,
)
from slipbench.stats.leaderboard import leaderboard

# two values of every factor a figure must not pool (the seed aside)
TWO_VALUES = {
    "detector_params": ('{"band": null, "keep": 0.8}', '{"band": null, "keep": 0.5}'),
    "input": ("univariate", "channels"),
    "normalize": ("none", "unit"),
    "dataset_fingerprint": ("f00d", "beef"),
    "train_dataset_fingerprint": ("aaaa1111", "bbbb2222"),
    "test_dataset_fingerprint": ("cccc3333", "dddd4444"),
    "sensor_map": ('{"Vib:a": "Nano17:index"}', '{"Vib:b": "Nano17:index"}'),
    "split": ("paper", "grouped"),
    "labels": ("scenario", "majority"),
    "balance": ("within", "across"),
    "protocol_params": ('{"windows": [5, 10, 25, 50, 100, 200]}', '{"windows": [50, 100, 200]}'),
    "interval_method": ("satterthwaite", "scale-choice"),
    "slipbench_version": ("0.1.0", "0.2.0"),
}
# each value's accuracy in every cell (lstm's 4 points more): any mean of the two is a sentinel
LEVELS = (0.213, 0.681)
SHIFT = {"holweg": 0.0, "lstm": 0.04}
OFFSETS = {"": 0.0, "_lo": -0.021, "_hi": 0.019}


def _pooled_texts() -> set[str]:
    """What a figure averaging the two values prints, whatever rate or bound it is."""
    out = set()
    for shift in SHIFT.values():
        for rate in (0.0, 0.02, -0.02):
            for offset in OFFSETS.values():
                mean = sum(LEVELS) / 2 + shift + rate + offset
                out.add(f"{100 * mean:.1f}")
    return out


def two_value_rows(factor: str) -> pd.DataFrame:
    """Window-size rows of holweg and the LSTM, seeds 0 and 1, once with each value of
    ``factor``: every figure of a value the same in every cell and seed."""
    parts = []
    for value, level in zip(TWO_VALUES[factor], LEVELS):
        for detector, shift in SHIFT.items():
            rows = fake_rows("window-size", detector, seeds=(0, 1))
            rows["key"] = rows["key"] + f"-{value}"
            for rate, step in (("accuracy", 0.0), ("tp_rate", 0.02), ("tn_rate", -0.02)):
                for bound, offset in OFFSETS.items():
                    rows[rate + bound] = level + shift + step + offset
            rows[factor] = value
            parts.append(rows)
    return pd.concat(parts, ignore_index=True)


def test_every_key_field_is_a_listed_factor(monkeypatch):
    """Every field engine.plan.keys hashes is in KEY_FIELDS: a new field without a role and
    the row columns that record it fails here (and so cannot be pooled unnoticed)."""
    seen: list[dict] = []
    monkeypatch.setattr(plan, "cell_key", lambda fields: seen.append(fields) or "0" * 20)
    part = Part((("Nano17", "index"),), "train")
    test = Part((("Nano17", "index"),), "test")
    for run in (
        Run("holweg", "window-size", split="grouped", normalize="unit", balance="across"),
        Run("tcn", "window-size", input="channels"),
    ):
        for cell in (
            Cell({"window": 50}, part, test, 50, downsample=2, decimation="lag", antialias=True),
            Cell({"window": 50}, part, test, 50, stream={"hop": 10, "max_delay_ms": 200.0}),
        ):
            keys(run, cell, "f00d")
    fields = {name for found in seen for name in found}
    assert fields - set(KEY_FIELDS) == set(), "a key field with no role in stats/factors.py"
    recorded = {c for role, columns in KEY_FIELDS.values() for c in columns if role != "seed"}
    assert set(TWO_VALUES) | {"detector"} == set(ENTRANTS) | set(SETTINGS)
    assert set(ENTRANTS) | set(SETTINGS) <= recorded | {"interval_method", "slipbench_version"}


def _numbers(text: str) -> set[str]:
    return set(re.findall(r"(?<![\d.])\d+\.\d(?!\d)", text))


def _one_value_each(frame: pd.DataFrame, factor: str) -> bool:
    """A figure's rows hold one value of ``factor`` (per entrant, for what names entrants)."""
    values = factor_values(frame, factor)
    if factor in ENTRANTS:
        return bool(values.groupby(frame["detector"]).nunique().le(1).all())
    return values.nunique() == 1


@pytest.mark.slow  # 12 whole reports and compares: about 2 minutes on a busy 2-core machine
@pytest.mark.parametrize("factor", sorted(TWO_VALUES))
def test_no_figure_pools_two_values_of_a_factor(factor, tmp_path):
    rows = two_value_rows(factor)
    blocks = build_report(rows, paper=True, with_figures=True)
    text = render([b for b in blocks if not isinstance(b, FigureSpec)], "md")
    shown = _numbers(text)
    assert not shown & _pooled_texts(), f"{factor}: a figure averages its two values"
    assert {"21.3", "68.1"} <= shown  # each value's own figures are there
    for spec in (b for b in blocks if isinstance(b, FigureSpec)):
        for frame in (a for a in getattr(spec.draw, "args", ()) if isinstance(a, pd.DataFrame)):
            assert _one_value_each(frame, factor), spec.stem
    # compare keeps them apart too, on both sides
    base, cand = tmp_path / "base.parquet", tmp_path / "cand.parquet"
    rows.to_parquet(base)
    moved = rows.assign(accuracy=rows["accuracy"] + 0.01, key=rows["key"] + "-c")
    moved.to_parquet(cand)
    comment = comment_markdown(compare(base, cand), max_rows=1000)
    assert not _numbers(comment) & _pooled_texts(), f"{factor}: compare pools its two values"
    assert "21.3 → 22.3" in comment and "68.1 → 69.1" in comment
    if factor in SETTINGS and factor != "split":  # the split is a pairing column already
        assert "cells pair on them too" in comment


@pytest.mark.parametrize("factor", ["normalize", "labels"])
def test_a_protocols_tables_keep_two_values_apart(factor):
    """The fast tier's share of the test above: an entrant and a setting, one protocol's
    tables (each detector's and every detector side by side) on four units."""
    rows = two_value_rows(factor)
    rows = named_entrants(rows[rows["sensor_type"].eq("Nano17") & rows["window"].isin([5, 50])])
    (section,) = outline(rows).sections
    blocks = _protocol_blocks(section, ReportOptions(), [], [])
    text = render(blocks, "md")
    assert not _numbers(text) & _pooled_texts() and {"21.3", "68.1"} <= _numbers(text)
    named = "Normalize unit." if factor == "normalize" else "Labels majority."
    assert ("holweg (normalize=unit)" in text) == (factor == "normalize")
    assert (named in text) == (factor == "labels")


def test_the_leaderboard_keeps_settings_apart_and_one_class_cells_out():
    rows = two_value_rows("labels")
    rows = rows[rows["sensor_type"].eq("Nano17") & rows["window"].isin([5, 50])]
    board = leaderboard(rows)
    # a block per cell and labelling: 6 cells (2 windows x 3 fingers), two labellings
    assert board.scopes[0].n_cells == 2 * 6
    assert board.means.loc["lstm", "accuracy"] == pytest.approx(sum(LEVELS) / 2 + 0.04)
    lone = rows.assign(constant_slip_accuracy=1.0)
    assert one_class(lone).all()
    lone_board = leaderboard(lone)
    assert lone_board.n_one_class == len(lone) and lone_board.scopes[0].n_cells == 0
