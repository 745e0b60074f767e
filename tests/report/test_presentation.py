"""What a protocol's cells are (Layout) apart from how they look (Presentation); both recorded in
every result row and read back from the rows by the report, never from the registry."""

from __future__ import annotations

import dataclasses

import pandas as pd
import pytest
from resultgen import fake_rows

from slipbench.app.selection import recorded_plugins
from slipbench.engine.registry import protocols
from slipbench.protocol import Layout, Presentation, as_record, described, from_record
from slipbench.protocols.window_size import WindowSize
from slipbench.report.outline import layouts
from slipbench.report.presentation import ShownLayout, shown, shown_protocol

BUILT_IN = ["window-size", "sampling-rate", "material-holdout", "speed-holdout", "cross-instance"]


def test_layout_and_presentation_share_no_field():
    what = {f.name for f in dataclasses.fields(Layout)}
    how = {f.name for f in dataclasses.fields(Presentation)}
    assert what == {"rows", "column", "pair", "split", "metrics"} and not what & how
    assert {f.name for f in dataclasses.fields(ShownLayout)} == what | how


@pytest.mark.parametrize("name", [*BUILT_IN, "streaming"])
def test_each_built_in_protocol_passes_its_presentation(name):
    protocol = protocols.get(name)()
    assert isinstance(protocol.presentation, Presentation) and protocol.presentation.caption
    look = shown_protocol(protocol, name)
    assert look.title and look.figure
    assert (look.paper_table is not None) == (name in BUILT_IN)


def test_window_size_in_ms_has_its_own_presentation():
    samples = shown_protocol(WindowSize(), "window-size")
    ms = shown_protocol(WindowSize(windows=["50ms"]), "window-size")
    assert (samples.column, ms.column) == ("window", "window_ms")
    assert (samples.x_label, ms.x_label) == ("window (samples)", "window (ms)")
    assert (samples.paper_table, ms.paper_table) == ("window-size", None)


def test_a_protocol_without_presentation_is_captioned_by_its_id():
    assert shown(Layout(("a",), "b"), None, "my-protocol").caption == "Protocol my-protocol."
    mine = shown(Layout(("a",), "b"), Presentation("Mine.", figure="curve"), "my-protocol")
    assert (mine.caption, mine.figure) == ("Mine.", "curve")


def test_a_layout_names_its_value_column_and_a_paired_figure_its_pair():
    with pytest.raises(ValueError, match="Layout.column must name"):
        Layout(("a",), "")
    with pytest.raises(ValueError, match="Layout.rows must be"):
        Layout((), "b")
    with pytest.raises(ValueError, match="needs Layout.pair"):
        shown(Layout(("a",), "b"), Presentation(figure="with-without"), "p")


@pytest.mark.parametrize("name", BUILT_IN)
def test_a_layout_and_presentation_survive_the_rows(name):
    protocol = protocols.get(name)()
    for value in (protocol.layout, protocol.presentation):
        assert from_record(type(value), as_record(value)) == value
    rows = fake_rows(name)
    assert set(described(protocol)) <= set(rows)
    (layout, note), *_ = layouts(rows).values()
    assert not note and layout == shown_protocol(protocol, name)


def test_a_subclass_of_a_built_in_protocol_looks_like_it():
    cls = protocols.get("material-holdout")

    class MyHoldout(cls):  # a lab's variant, registered under its own id
        pass

    assert shown_protocol(MyHoldout(), "my-holdout") == shown_protocol(cls(), "my-holdout")


def test_the_report_reads_layouts_from_the_rows_not_the_registry():
    """A protocol no registry knows lays out as its rows say; rows that record none are laid
    out from their cell keys, with a note saying why."""
    rows = fake_rows("material-holdout").assign(protocol="a-lab-protocol")
    layout, note = layouts(rows)["a-lab-protocol"]
    assert not note and layout.pair == "training" and layout.figure == "with-without"
    bare = rows.drop(columns=["protocol_layout", "protocol_presentation"])
    layout, note = layouts(bare)["a-lab-protocol"]
    assert note == "Laid out from its cell keys: its rows do not record the protocol's layout."
    assert layout.caption == "Protocol a-lab-protocol." and layout.pair is None
    broken = rows.assign(protocol_layout='{"rows": ["sensor_type"]}')
    assert "cannot be read" in layouts(broken)["a-lab-protocol"][1]


def test_rows_written_before_they_recorded_layouts_get_them_from_their_plugins():
    rows = fake_rows("speed-holdout", "features")
    older = rows.drop(columns=["protocol_layout", "protocol_presentation", "detector_reference"])
    filled = recorded_plugins(older)
    columns = ["protocol_layout", "protocol_presentation", "detector_reference"]
    pd.testing.assert_frame_equal(filled[columns], rows[columns], check_dtype=False)
    unknown = older.assign(protocol="gone", detector="gone")  # no plugin: left as they were
    left = recorded_plugins(unknown)
    assert all(c not in left or left[c].isna().all() for c in columns)


def test_the_report_command_lays_out_older_rows_from_their_plugins(tmp_path, cli):
    """Results written before rows recorded their layouts report as before: the command fills
    in what the rows lack from the registry, and the report lays them out as the protocol's."""
    rows = fake_rows("material-holdout").drop(
        columns=["protocol_layout", "protocol_presentation", "detector_reference"]
    )
    folder = tmp_path / "older"
    folder.mkdir()
    rows.to_parquet(folder / "results.parquet")
    code, out, err = cli(["report", str(folder)])
    assert code == 0, err
    assert "explicit training of indicated materials" in out and "Laid out from" not in out
