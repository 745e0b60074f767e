"""The report's presentation of the built-in protocols, and a plugin's own kept as its default."""

from __future__ import annotations

import dataclasses

import pytest

from slipbench.engine.registry import protocols
from slipbench.protocol import Layout
from slipbench.protocols.window_size import WindowSize
from slipbench.report.presentation import PRESENTATIONS, Presentation, lineage, presented

SHOWN = [f.name for f in dataclasses.fields(Presentation)]


def _declared(name: str, column: str) -> Layout:
    if column == "window_ms":
        return WindowSize(windows=["50ms"]).layout
    return protocols.get(name)().layout


@pytest.mark.parametrize(("name", "column"), list(PRESENTATIONS))
def test_each_presentation_is_of_a_built_in_layout_that_declares_none(name, column):
    declared = _declared(name, column)
    assert declared.column == column
    assert all(getattr(declared, f) == getattr(Presentation(), f) for f in SHOWN), (
        f"{name} declares presentation in its Layout: it belongs in report/presentation.py"
    )
    shown = presented(name, declared)
    assert shown.caption and shown.title
    assert (shown.rows, shown.pair, shown.split, shown.metrics) == (
        declared.rows,
        declared.pair,
        declared.split,
        declared.metrics,
    )


def test_window_size_in_ms_has_its_own_presentation():
    samples = presented("window-size", WindowSize().layout)
    ms = presented("window-size", WindowSize(windows=["50ms"]).layout)
    assert (samples.x_label, ms.x_label) == ("window (samples)", "window (ms)")
    assert (samples.paper_table, ms.paper_table) == ("window-size", None)


def test_a_plugin_keeps_its_presentation_and_positional_layouts_still_work():
    mine = Layout("Mine.", ("sensor_type",), "window", title="Mine", figure="curve")
    assert presented("my-protocol", mine) is mine
    assert presented("my-protocol", Layout(rows=("a",), column="b")).caption == (
        "Protocol my-protocol."
    )


def test_a_layout_names_its_value_column():
    with pytest.raises(ValueError, match="Layout.column must name"):
        Layout("caption", ("a",))
    with pytest.raises(ValueError, match="Layout.rows must be"):
        Layout(column="b")


def test_presentation_is_layout_less_what_the_cells_are():
    layout = {f.name: f.default for f in dataclasses.fields(Layout)}
    assert {f.name: f.default for f in dataclasses.fields(Presentation)} == {
        k: v for k, v in layout.items() if k not in ("rows", "column", "pair", "split", "metrics")
    }


def test_a_subclass_of_a_built_in_protocol_looks_like_it():
    from slipbench.engine.registry import protocols

    cls = protocols.get("material-holdout")

    class MyHoldout(cls):  # a lab's variant, registered under its own id
        pass

    layout = MyHoldout().layout
    shown = presented(lineage("my-holdout", MyHoldout), layout)
    assert shown == presented("material-holdout", layout) and shown.caption
