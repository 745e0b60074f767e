"""The resolved reader (issue 56): what every reader of results rows needs is computed once per
report, and every consumer reads the same from resolved rows as it derived from raw ones."""

from __future__ import annotations

import pandas as pd
import pytest
from resultgen import fake_rows

import slipbench.store.resolved as resolved_module
from slipbench.history.series import series_rows
from slipbench.report.document import build_report
from slipbench.report.outline import outline
from slipbench.stats.contrast import pair_seeds
from slipbench.stats.factors import setting_labels, setting_parts
from slipbench.stats.leaderboard import leaderboard
from slipbench.store.resolved import (
    CELLS,
    ENTRANTS,
    SETTINGS,
    cell_keys,
    cell_labels,
    differing_settings,
    entrant_names,
    factor_values,
    one_class,
    plain_rows,
    resolve,
    rewritten,
)


def _rows() -> pd.DataFrame:
    """Entrants and settings apart: lstm, holweg at two parameter sets, tcn on the channels,
    lstm under two label rules, a cell of one class."""
    holweg = fake_rows("window-size", "holweg")
    banded = holweg.assign(detector_params='{"band": [39, 100]}', key=holweg["key"] + "b")
    tcn = fake_rows("window-size", "tcn").assign(input="channels")
    lstm = fake_rows("window-size", seeds=(0, 1))
    majority = lstm.assign(labels="majority", key=lstm["key"] + "m")
    rows = pd.concat(
        [lstm.assign(labels="any"), holweg.assign(detector_params="{}"), banded, tcn, majority],
        ignore_index=True,
    )
    rows["test_slip_windows"], rows["test_nonslip_windows"] = 40, 40
    rows.loc[3, "test_nonslip_windows"] = 0
    return rows


@pytest.fixture
def made(monkeypatch) -> list[int]:
    """Counts each time the reader computes (not each time resolved rows are taken)."""
    counts: list[int] = []
    derive = resolved_module._derived

    def counted(rows):
        counts.append(len(rows))
        return derive(rows)

    monkeypatch.setattr(resolved_module, "_derived", counted)
    return counts


def test_a_report_resolves_its_rows_once(made):
    rows = _rows()
    blocks = build_report(rows, paper=True)
    assert blocks
    assert made == [len(rows)]  # the outline's, over every row; no step derives them again


def test_resolved_rows_are_taken_as_they_are(made):
    once = resolve(_rows())
    again = resolve(once.rows.iloc[::2])
    assert resolve(once) is once
    assert len(made) == 1
    assert again.rows.columns.equals(once.rows.columns)


def test_resolved_rows_read_as_raw_ones_do():
    raw = _rows()
    rows = resolve(raw).rows
    for column in dict.fromkeys((*ENTRANTS, *SETTINGS, *CELLS)):
        assert factor_values(rows, column).equals(factor_values(raw, column)), column
    assert entrant_names(rows).equals(entrant_names(raw))
    assert set(entrant_names(rows)) >= {"holweg (band=[39, 100])", "tcn (channels)"}
    assert one_class(rows).equals(one_class(raw)) and one_class(rows).sum() == 1
    assert cell_labels(rows).iloc[0].startswith("Nano17")
    assert resolve(rows).cell_labels.equals(cell_labels(raw))
    assert cell_keys(rows).equals(cell_keys(raw))
    assert differing_settings(rows) == differing_settings(raw) == ["labels"]
    assert setting_labels(rows).equals(setting_labels(raw))
    assert [w for w, _ in setting_parts(rows)] == [w for w, _ in setting_parts(raw)]
    part = rows[rows["detector"] == "lstm"]  # a part keeps what was resolved over the whole
    assert factor_values(part, "labels").equals(factor_values(raw.loc[part.index], "labels"))
    assert plain_rows(rows).equals(raw)


def test_consumers_take_resolved_rows():
    raw = _rows()
    rows = resolve(raw).rows
    made = outline(raw)
    assert made.resolved.rows.index.equals(raw.index)
    board, again = leaderboard(rows), leaderboard(raw)
    assert board.scopes[0].ranks.equals(again.scopes[0].ranks)
    assert board.entrants == again.entrants and board.means.equals(again.means)
    assert series_rows(rows)["series_label"].equals(series_rows(raw)["series_label"])
    lstm = rows[rows["detector"] == "lstm"]
    assert (
        pair_seeds(lstm, lstm).cells == pair_seeds(raw.loc[lstm.index], raw.loc[lstm.index]).cells
    )


def test_a_rewritten_column_is_resolved_anew():
    rows = resolve(_rows()).rows
    out = rewritten(rows, {"labels": pd.Series("none", index=rows.index)})
    assert factor_values(out, "labels").eq("none").all()
    assert cell_keys(out).str.contains('"labels": "none"').all()
