"""The report's "What the reduction keeps": there only where a detector ran with both inputs,
read by its intervals, with its per-cell tables in the appendix, unpaired cells listed, and one
figure."""

from __future__ import annotations

import re

import pytest
from resultgen import all_rows, inputs_folder

from slipbench.report.blocks import Table
from slipbench.report.document import Heading, build_report, render, split_appendix, write_figures
from slipbench.report.plots import FigureSpec
from slipbench.report.reduction import REDUCTION_TITLE


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    """A report of tcn run with both inputs (channels better on Nano17, equal on the BioTac
    SP, three seeds) and its blocks."""
    folder, rows = inputs_folder(tmp_path_factory.mktemp("inputs"), seeds=(0, 1, 2))
    blocks = build_report(rows, with_figures=True, predictions=[folder])
    return rows, blocks


def _section(text: str) -> str:
    return text[text.index(f"## {REDUCTION_TITLE}") :]


def test_the_section_reads_each_sensor_by_its_interval(report):
    _, blocks = report
    text = _section(render(blocks, "md"))
    nano = re.search(r"On the Nano17, with tcn, (.*?)\.\n", text)
    biotac = re.search(r"On the Biotac SP, with tcn, (.*?)\.\n", text)
    assert nano and nano[1].startswith("the channels beat the univariate signal in window-size")
    assert biotac and biotac[1].startswith(
        "no difference beyond the margin is resolved in window-size"
    )
    lo, hi = map(float, re.search(r"\\\[([-+\d.]+), ([-+\d.]+)\\\] points", nano[1]).groups())
    assert 0 < lo < hi
    lo, hi = map(float, re.search(r"\\\[([-+\d.]+), ([-+\d.]+)\\\] points", biotac[1]).groups())
    assert lo < 0 < hi
    # the data and settings it stands on
    assert "14 paired cells in 1 protocol and 2 sensor types, seeds 0, 1, 2 (3 per cell)" in text
    assert "test trials per cell 12 with slip and 12 without" in text
    assert "2 pooled intervals hold together at 95 % (97.5 % each, Bonferroni)" in text
    assert "retraining noise is not inside" not in text  # three seeds: it is


def test_unpaired_cells_are_listed_with_their_reasons(report):
    _, blocks = report
    text = _section(render(blocks, "md"))
    assert "no univariate twin: the univariate run holds no such cell" in text
    assert "channels skipped (units differ in channels)" in text
    assert "Nano17 Index window 200" in text and "Biotac SP Index window 200" in text


def test_per_cell_tables_go_to_the_appendix(report):
    _, blocks = report
    summary, appendix = split_appendix(blocks, "appendix.md")
    short, rest = render(summary, "md"), render(appendix, "md")
    assert "tcn: channels − univariate, cell by cell." not in short
    assert "tcn: channels − univariate, cell by cell." in rest
    assert "Not compared, cell by cell." in rest
    # the pooled tables, readings and the count of unpaired cells stay in the summary
    assert "Nano17: channels − univariate, mean over each protocol's cells." in short
    assert "On the Nano17, with tcn" in short and "Not compared: cells" in short
    assert f"(appendix.md#{REDUCTION_TITLE.lower().replace(':', '').replace(' ', '-')})" in short
    cells = [b for b in blocks if isinstance(b, Table) and b.label.startswith("tab:reduction-")]
    assert {t.label for t in cells} >= {"tab:reduction-Nano17", "tab:reduction-BioTacSP"}


@pytest.mark.slow
def test_the_figure_shows_each_sensor_with_a_zero_line(report, tmp_path):
    _, blocks = report
    (spec,) = [b for b in blocks if isinstance(b, FigureSpec) and b.stem == "reduction"]
    fig = spec.draw()
    assert fig.get_size_inches()[0] == pytest.approx(3.5)
    panels = [ax for ax in fig.axes if ax.lines]
    assert [ax.get_title(loc="left") for ax in panels] == ["Nano17", "Biotac SP"]
    assert panels[-1].get_xlabel() == "channels − univariate, accuracy (points)"
    for ax in panels:  # a vertical line at 0
        assert any(list(line.get_xdata()) == [0, 0] for line in ax.lines)
    assert len(fig.legends) == 1
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert labels == ["channels better", "undecided", "a cell"]
    paths = write_figures(blocks, tmp_path)["reduction"]
    assert all(p.stat().st_size > 1000 for p in paths)


def test_every_format_renders_the_section(report):
    _, blocks = report
    latex = render(blocks, "latex", standalone=True)
    assert r"\section*{What the reduction keeps: univariate vs channels}" in latex
    assert "\\label{tab:reduction-Nano17}" in latex and "−" not in latex
    page = render(blocks, "html")
    assert f">{REDUCTION_TITLE}</h2>" in page and 'id="fig-reduction"' in page


@pytest.mark.slow
def test_no_section_without_both_inputs():
    blocks = build_report(all_rows(), with_figures=True)
    assert not any(isinstance(b, Heading) and b.text == REDUCTION_TITLE for b in blocks)
    assert not any(isinstance(b, FigureSpec) and b.stem == "reduction" for b in blocks)


def test_the_two_inputs_are_two_entrants_never_two_seeds(report):
    """Outside this section, tcn on channels competes as its own entrant: the leaderboard and
    the tables name it, and no mean over seeds mixes the two inputs of a cell."""
    _, blocks = report
    text = render(blocks, "md")
    before = text[: text.index(f"## {REDUCTION_TITLE}")]
    board = before[before.index("## Leaderboard") :]
    assert "tcn (channels)" in board and re.search(r"\btcn\b(?! \(channels\))", board)


def test_one_seed_of_both_inputs_is_not_averaged_as_two_seeds(tmp_path):
    folder, rows = inputs_folder(tmp_path, seeds=(0,))
    text = render(build_report(rows, predictions=[folder]), "md")
    assert "across seeds" not in text[: text.index(f"## {REDUCTION_TITLE}")]


def test_figure_files_of_a_channels_entrant_have_link_safe_names():
    """A Markdown link stops at a space: figure files of ``tcn (channels)`` must have none."""
    from slipbench.report.plots import file_stem

    assert file_stem("window-size-tcn (channels)-grouped") == "window-size-tcn-channels-grouped"
    assert file_stem("sampling-rate-holweg-lag-True") == "sampling-rate-holweg-lag-True"
