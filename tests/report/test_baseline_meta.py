"""The 'vs baseline' column and the section across datasets in whole reports."""

from __future__ import annotations

import pandas as pd
import pytest
from resultgen import fake_rows

from slipbench.report.blocks import Table
from slipbench.report.document import build_report, render
from slipbench.report.leaderboard import NO_BASELINE
from slipbench.report.meta import analyses
from slipbench.report.outline import references
from slipbench.report.plots import forest
from slipbench.report.tables import baseline_table

HOSTILE = "lab|$x$_&<b>"


def rows_of(detector: str, fingerprint: str, shift: float = 0.0) -> pd.DataFrame:
    rows = fake_rows("window-size", detector).head(6)
    out = rows.assign(dataset_fingerprint=fingerprint, key=rows["key"] + fingerprint)
    for name in ("accuracy", "tp_rate", "tn_rate"):
        for col in (name, f"{name}_lo", f"{name}_hi"):
            out[col] = out[col] + shift
    return out


def two_datasets() -> pd.DataFrame:
    base = rows_of("features", "aaaa")
    parts = [base, base.assign(dataset_fingerprint="bbbb", key=base["key"] + "b")]
    for fp, shift in (("aaaa", 0.05), ("bbbb", 0.02)):
        cand = base.assign(
            detector="holweg",
            detector_reference=False,
            dataset_fingerprint=fp,
            key=base["key"] + "h" + fp,
        )
        cand["accuracy"] += shift
        cand["accuracy_lo"] += shift
        cand["accuracy_hi"] += shift
        parts.append(cand)
    return pd.concat(parts, ignore_index=True)


@pytest.mark.slow  # a whole report: 4-9 s on the shared machine
def test_side_by_side_tables_show_the_change_from_the_reference():
    blocks = build_report(two_datasets())
    tables = [b for b in blocks if isinstance(b, Table) and "side by side" in b.caption]
    assert tables
    for t in tables:
        assert t.columns[-1] == "vs baseline (features)"
        texts = dict(zip((r[0] for r in t.rows), (line[-1] for line in t.cells)))
        assert texts["features"] == "reference"
        assert texts["holweg"].startswith(("+5.0 [", "+2.0 ["))
    assert not any(NO_BASELINE in b.notes for b in blocks if isinstance(b, Table))


@pytest.mark.slow  # a whole report: 4-9 s on the shared machine
def test_without_the_reference_the_column_is_absent_and_said_once():
    rows = pd.concat([rows_of("lstm", "aaaa"), rows_of("holweg", "aaaa")], ignore_index=True)
    text = render(build_report(rows), "md", False, {})
    assert "vs baseline (" not in text
    assert text.count("No baseline ran") == 1


@pytest.mark.slow  # a whole report: 4-9 s on the shared machine
def test_the_section_pools_across_datasets_and_draws_a_forest():
    rows = two_datasets()
    metas = analyses(rows, ["features"])
    assert [(m.base, m.cand) for m in metas] == [("features", "holweg")]
    assert m_ok(metas[0])
    assert forest(metas) is not None
    text = render(build_report(rows), "md", False, {})
    assert "## Across datasets" in text and "holweg − features" in text


def m_ok(m) -> bool:
    return m.pooled_over == 2 and m.lo < 0.035 < m.hi


def test_transfer_rows_and_a_single_dataset_give_no_section():
    rows = two_datasets()
    moved = rows.assign(
        sensor_map=rows["dataset_fingerprint"].map({"aaaa": None, "bbbb": '{"x": "y"}'})
    )
    assert analyses(moved, ["features"]) == []


@pytest.mark.slow  # a whole report: 4-9 s on the shared machine
def test_hostile_names_are_escaped_everywhere():
    rows = two_datasets()
    rows["dataset_path"] = rows["dataset_fingerprint"].map(
        {"aaaa": f"/d/{HOSTILE}", "bbbb": "/d/b"}
    )
    rows.loc[rows["detector"] == "holweg", "detector"] = HOSTILE
    blocks = build_report(rows)
    md = render(blocks, "md", False, {})
    assert "lab\\|" in md and "lab|$" not in md
    latex = render(blocks, "latex", False, {})
    assert r"\$x\$\_\&" in latex
    html = render(blocks, "html", False, {})
    assert "<b>" not in html.split("<body>")[-1].replace("<b>Note", "")
    assert forest(analyses(rows, ["features"])) is not None


@pytest.mark.parametrize(
    "detectors, says",
    [
        (["features", "holweg"], "(baseline: features)"),
        (["lstm", "holweg"], "(no baseline ran: none of them is the registered reference)"),
    ],
)
def test_the_window_50_table_names_the_baseline_as_the_leaderboard_does(detectors, says):
    """The baseline is the registered reference, in the window-50 table as in the leaderboard's
    note: Holweg's threshold, a column there, is not called the baseline when no reference ran."""
    rows = pd.concat([fake_rows("window-size", d) for d in detectors], ignore_index=True)
    rows = rows.assign(detector_reference=rows["detector"] == "features")
    table = baseline_table(rows, paper=True, reference=references(rows))
    assert table is not None and says in table.caption, table.caption
    assert table.caption.endswith("with the paper's Holweg threshold and LSTM.")
    assert "Holweg baseline" not in table.caption
