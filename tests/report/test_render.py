"""One renderer per format behind one interface: each format a module whose RENDERER renders
every kind of block, and the formats the commands offer are those renderers."""

from __future__ import annotations

import click
import pytest

from slipbench.app.cli import cli
from slipbench.report.blocks import Heading, Link, Table, Text
from slipbench.report.render import FORMATS, Drawn, Renderer, renderer

TABLE = Table("Caption <x>.", ["Unit"], "Group", ["50"], [("a|b",)], [["88.0 [86.9, 89.1]"]], "t")


@pytest.mark.parametrize("fmt", FORMATS)
def test_each_format_renders_every_block_through_the_interface(fmt):
    out = renderer(fmt, standalone=True)
    assert isinstance(out, Renderer) and out.name == fmt and out.suffix
    parts = [
        out.heading(Heading("Report", 1)),
        out.heading(Heading("A section", 2)),
        out.paragraph(Text("See ", Link("the appendix", "appendix.md#a"), ".")),
        out.table(TABLE),
        out.figure(Drawn("fig", "A figure.", {}, lambda: None)),  # nothing to show
    ]
    assert all(parts[:4]) and parts[4] == ""
    text = out.document([p for p in parts if p])
    assert "A section" in text and "88.0" in text and "the appendix" in text


def test_a_format_shows_a_drawn_figure_its_own_way():
    drawn = Drawn("fig", "A figure.", {".png": "plots/fig.png", ".pdf": "plots/fig.pdf"}, bytes)
    assert "![A figure.](plots/fig.png)" in renderer("md").figure(drawn)
    assert r"\includegraphics" in renderer("latex").figure(drawn)
    assert '<figure id="fig-fig"><img src="data:image/png;base64,' in renderer("html").figure(drawn)


def test_an_unknown_format_is_refused_and_the_commands_offer_the_renderers():
    with pytest.raises(ValueError, match="unknown report format 'pdf'"):
        renderer("pdf")
    command = cli.get_command(click.Context(cli), "report")  # the group loads it when asked
    assert command is not None
    option = next(p for p in command.params if p.name == "fmt")
    assert isinstance(option.type, click.Choice) and list(option.type.choices) == list(FORMATS)
