"""Series named for people: the cell by its short label (as the pull-request comment names it),
never as its JSON key, in `history steps` and in histories recorded before labels were short."""

from __future__ import annotations

import io
import json
from contextlib import redirect_stdout

import pandas as pd
import pytest
from historygen import run_folder

from slipbench.app.cli import main
from slipbench.history.series import series_rows, shown_labels
from slipbench.store.history import Run, add_run, utc_date
from slipbench.store.results import read_results
from slipbench.vocabulary import cell_label

KEY = '{"sensor_type": "Nano17", "test_instance": "little", "train_instance": "middle"}'


def _cli(*args: str) -> tuple[int, str]:
    buffer = io.StringIO()
    with pytest.raises(SystemExit) as exit_, redirect_stdout(buffer):
        main(list(args))
        raise SystemExit(0)
    return int(exit_.value.code or 0), buffer.getvalue()


def test_a_series_label_names_its_cell_as_the_comment_does(tmp_path):
    rows = series_rows(read_results(run_folder(tmp_path / "r", seed=0)))
    assert not rows["series_label"].str.contains('{"', regex=False).any()
    some = rows.iloc[0]
    assert some["series_label"].startswith(f"window-size · holweg · {cell_label(some['cell'])}")


def test_a_label_recorded_with_its_cell_as_json_is_shown_short():
    """Histories added before cells had short labels keep their labels on disk; pages and
    steps show them short, the same label for the same text."""
    stored = pd.Series([f"cross-instance · holweg · {KEY} · grouped", "a · b · all cells", None])
    assert list(shown_labels(stored)) == [
        "cross-instance · holweg · Nano17 Middle → Little · grouped",
        "a · b · all cells",
        "",
    ]


def test_history_steps_names_no_cell_in_json(tmp_path):
    hist = tmp_path / "hist"
    for i, shift in enumerate([0.0] * 5 + [-0.05] * 5):
        folder = run_folder(tmp_path / f"r{i}", seed=i, shift=shift, code=f"code-{i}")
        rows = series_rows(read_results(folder))
        add_run(hist, rows, Run(f"c{i:02d}", utc_date(f"2026-01-01T{i:02d}:00:00Z"), "m"))
    code, text = _cli("history", "steps", "--history", str(hist))
    assert code == 0 and "regressed" in text and '{"' not in text, text[:2000]
    code, text = _cli("history", "steps", "--history", str(hist), "--json")
    steps = json.loads(text)["steps"]
    assert steps and not [s["series_label"] for s in steps if '{"' in s["series_label"]]


def test_a_setting_at_its_default_renames_no_series(tmp_path):
    """The balance names a series (the schema gives it a setting's role) but, at its default,
    stays out of the series' digest: runs before the option keep their series, and a run
    balanced across materials is a series of its own."""
    rows = read_results(run_folder(tmp_path / "r", seed=0))
    before = series_rows(rows.drop(columns=["balance"], errors="ignore"))["series"]
    within = series_rows(rows.assign(balance="within"))["series"]
    across = series_rows(rows.assign(balance="across"))["series"]
    assert list(within) == list(before)
    assert not set(across) & set(before)
