"""Steps: proposed where the series moves (each point weighted by its interval), confirmed
only beyond the gate's tolerance, named by commit; the seed spread the gate reads."""

from __future__ import annotations

import json

import numpy as np
import pytest
from historygen import run_folder

from slipbench.app.cli import main
from slipbench.gate.gate import Gate, resolution
from slipbench.history.series import HISTORY, seed_spread, series_rows
from slipbench.history.steps import (
    SEGMENT_SEEDS,
    SERIES_ALPHA,
    _runs_needed,
    find_steps,
    propose,
    step_change,
)
from slipbench.stats.contrast import ONE_SEED, SHOWN, UNDECIDED, from_parts
from slipbench.stats.noise import SeedNoise
from slipbench.store.history import Run, add_run, read_history, utc_date
from slipbench.store.results import read_results


def _history(root, shifts, noise=0.005, codes=None):
    """A history whose run i has every figure of every cell moved by shifts[i]."""
    hist = root / "hist"
    for i, shift in enumerate(shifts):
        code = codes[i] if codes else f"code-{i}"
        folder = run_folder(root / f"r{i}", seed=i, shift=shift, noise=noise, code=code)
        day = f"2026-01-{1 + i // 24:02d}T{i % 24:02d}:00:00Z"
        add_run(hist, series_rows(read_results(folder)), Run(f"c{i:02d}", utc_date(day), "m"))
    return hist


def _cli(*args: str) -> tuple[int, str]:
    import io
    from contextlib import redirect_stdout

    buffer = io.StringIO()
    with pytest.raises(SystemExit) as exit_, redirect_stdout(buffer):
        main(list(args))
        raise SystemExit(0)
    return int(exit_.value.code or 0), buffer.getvalue()


@pytest.fixture(scope="module")
def stepped(tmp_path_factory):
    """12 runs; from c06 on every figure 5 points lower (noise 0.5 point)."""
    return _history(tmp_path_factory.mktemp("steps"), [0.0] * 6 + [-0.05] * 6)


def test_a_step_beyond_the_tolerance_is_named_at_its_commit(stepped):
    found = find_steps(read_history(stepped), Gate.of(["accuracy", "tn_rate", "tp_rate"]))
    confirmed = found.confirmed
    assert not confirmed.empty
    assert set(confirmed["commit"]) == {"c06"}
    assert set(confirmed["verdict"]) == {"regressed"}
    assert set(confirmed["previous_commit"]) == {"c05"}
    assert (confirmed["change_hi"] < -1).all()  # beyond the tolerance, in points
    assert confirmed["change"].between(-6.5, -3.5).all()
    # each cell and figure, and each protocol mean
    assert (confirmed["kind"] == "pooled").sum() == 3
    assert set(confirmed["what_changed"]) == {"code"}


def test_steps_exit_1_for_a_regression_newer_than_since(stepped):
    code, text = _cli("history", "steps", "--history", str(stepped), "--since", "c03")
    assert code == 1
    assert "c06" in text and "regressed" in text
    assert _cli("history", "steps", "--history", str(stepped), "--since", "c06")[0] == 0
    assert (
        _cli("history", "steps", "--history", str(stepped), "--since", "2026-01-01T03:30")[0] == 1
    )
    assert _cli("history", "steps", "--history", str(stepped))[0] == 0
    code, text = _cli("history", "steps", "--history", str(stepped), "--since", "nothing")
    assert code == 2


def test_steps_json_lists_every_proposal(stepped):
    code, text = _cli("history", "steps", "--history", str(stepped), "--json")
    doc = json.loads(text)
    assert code == 0 and doc["runs"] == 12
    assert {s["verdict"] for s in doc["steps"]} <= {"regressed", "not confirmed"}
    assert all(s["commit"] == "c06" for s in doc["steps"] if s["verdict"] == "regressed")


@pytest.mark.slow
def test_a_step_inside_the_tolerance_is_not_confirmed(tmp_path):
    hist = _history(tmp_path, [0.0] * 6 + [-0.005] * 6, noise=0.001)
    found = find_steps(read_history(hist), Gate.of(["accuracy", "tn_rate", "tp_rate"]))
    assert not found.steps.empty  # the search sees it
    assert found.confirmed.empty  # the gate does not call half a point a regression


@pytest.mark.slow
def test_no_step_confirmed_in_a_flat_history(tmp_path):
    hist = _history(tmp_path, [0.0] * 10, noise=0.01)
    found = find_steps(read_history(hist), Gate.of(["accuracy", "tn_rate", "tp_rate"]))
    assert found.confirmed.empty
    assert found.series == 3 * (48 + 1)


def test_runs_of_one_code_and_seed_count_once(tmp_path):
    """A later run that kept the same results (same code, same seed: the same cell keys) is
    one result, not a seed more."""
    hist = tmp_path / "hist"
    folder = run_folder(tmp_path / "r", seed=0)
    for i in range(3):
        add_run(
            hist,
            series_rows(read_results(folder)),
            Run(f"c{i}", utc_date(f"2026-01-0{i + 1}"), "m"),
        )
    spread = seed_spread(read_history(hist), "accuracy")
    assert spread == {}  # one result per series: no spread measured


def test_weights_follow_the_intervals():
    value = np.r_[np.zeros(10), 1.0, np.zeros(10)]
    assert propose(value, np.r_[np.full(10, 0.01), 10.0, np.full(10, 0.01)]) == []
    assert propose(value, np.full(21, 0.01)) != []
    shift = np.r_[np.zeros(10), np.ones(10)] + np.random.default_rng(0).normal(0, 0.05, 20)
    assert propose(shift, np.full(20, 0.05)) == [10]


def test_step_change_is_the_contrast_of_the_segments_means():
    """The segments' means, their seed spread pooled over both (a step moves the figure, not
    the bench's noise), as one contrast against the tolerance: the interval it shows is the
    one its state read."""
    b, a = [0.80, 0.82, 0.81], [0.75, 0.76, 0.74]
    before = [{"accuracy": v, "accuracy_se": 0.01, "df": 30.0} for v in b]
    after = [{"accuracy": v, "accuracy_se": 0.01, "df": 30.0} for v in a]
    got = step_change((before, after), "accuracy", 0.95, 0.01)
    pooled = (np.var(b) * 3 + np.var(a) * 3) / 4
    assert got.estimate == pytest.approx(-0.06)
    assert got.se == pytest.approx(np.sqrt(2 * pooled / 3))
    assert got.df == pytest.approx(4)
    assert got.noise == (SEGMENT_SEEDS,)
    same = from_parts(-0.06, [(2 * pooled / 3, 4.0)], 0.95, 0.01)
    assert (got.lo, got.hi) == pytest.approx((same.lo, same.hi))
    assert got.state == SHOWN and got.direction == -1
    # at a level the interval reaches the tolerance: undecided, never shown
    assert step_change((before, after), "accuracy", 1 - 1e-9, 0.01).state == UNDECIDED
    # one seed a side: the rows' test-set noise, and undecided: no retraining noise measured
    alone = step_change((before[:1], after[:1]), "accuracy", 0.95, 0.01)
    assert alone.se == pytest.approx(np.hypot(0.01, 0.01)) and alone.missing == ONE_SEED
    assert alone.state == UNDECIDED


def test_seed_spread_pools_each_code_identity(tmp_path):
    """Two identities, three seeds each: the spread within each, pooled on 2 + 2 df."""
    hist = _history(
        tmp_path,
        [0.0, 0.01, -0.01, -0.2, -0.21, -0.19],
        noise=0.0,
        codes=["a", "a", "a", "b", "b", "b"],
    )
    frame = read_history(hist)
    spread = seed_spread(frame, "accuracy")
    assert len(spread) == 48
    assert all(isinstance(s, SeedNoise) and s.source == HISTORY for s in spread.values())
    assert {s.df for s in spread.values()} == {4}
    expected = np.var([0.0, 0.01, -0.01], ddof=1)  # a shift of -0.2 between codes is not spread
    variances = [s.variance for s in spread.values()]
    assert variances == pytest.approx([expected] * 48, rel=1e-6)
    only_b = seed_spread(frame, "accuracy", identities=["b"])
    assert {s.df for s in only_b.values()} == {2} and set(only_b) == set(spread)
    assert seed_spread(frame, "accuracy", identities=["zzz"]) == {}


def test_an_unconfirmed_step_says_the_seeds_that_would_confirm_it():
    """Four seeds a side whose spread hides a 3-point drop against a 1-point tolerance: the
    seeds a side at which the gate's resolution reaches the change beyond the tolerance."""
    rng = np.random.default_rng(3)
    b, a = 0.80 + 0.02 * rng.standard_normal(4), 0.77 + 0.02 * rng.standard_normal(4)
    sides = tuple([{"tp_rate": v, "tp_rate_se": 0.01, "df": 30.0} for v in s] for s in (b, a))
    change = step_change(sides, "tp_rate", 0.99, 0.01)
    assert change.state != SHOWN
    n = _runs_needed(change, 1, 4)
    beyond = abs(change.estimate) - 0.01
    sigma = change.se / np.sqrt(2 / 4)  # one seed's spread

    def at(m):
        return resolution(sigma * np.sqrt(2 / m), 2 * m - 2, 1, SERIES_ALPHA)

    assert n > 4 and at(n) <= beyond < at(n - 1)
    # within the tolerance, no number of seeds confirms it; confirmed, nothing more is needed
    inside = step_change(sides, "tp_rate", 0.99, 0.5)
    assert _runs_needed(inside, 1, 4) == 0
    shown = step_change(sides, "tp_rate", 0.5, 0.0001)
    assert shown.state == SHOWN and _runs_needed(shown, 1, 4) == 0


def test_a_five_run_history_names_its_step_judged_on_the_runs_intervals(tmp_path):
    """Five runs, every figure 5 points lower from the fourth: too short for the segment
    search, the short route names the step at its commit and says how it was judged."""
    hist = _history(tmp_path, [0.0] * 3 + [-0.05] * 2)
    found = find_steps(read_history(hist), Gate.of(["accuracy", "tn_rate", "tp_rate"]))
    confirmed = found.confirmed
    assert set(confirmed["commit"]) == {"c03"} and set(confirmed["verdict"]) == {"regressed"}
    assert set(confirmed["route"]) == {"short"}
    assert (confirmed["runs_before"] == 3).all() and (confirmed["runs_after"] == 2).all()
    assert (confirmed["kind"] == "pooled").sum() == 3
    code, text = _cli("history", "steps", "--history", str(hist), "--since", "c02")
    assert code == 1
    assert "c03" in text and "judged on the runs' own intervals" in text
    # and why a step may read a change otherwise than compare does
    assert "at its look's level" in text


def test_a_flat_five_run_history_stays_quiet(tmp_path):
    hist = _history(tmp_path, [0.0] * 5, noise=0.01)
    found = find_steps(read_history(hist), Gate.of(["accuracy", "tn_rate", "tp_rate"]))
    assert found.confirmed.empty
    code, text = _cli("history", "steps", "--history", str(hist))
    assert code == 0 and "fewer than the 8 the segment search needs" in text


def test_two_runs_say_how_many_a_step_needs(tmp_path):
    code, text = _cli("history", "steps", "--history", str(_history(tmp_path, [0.0, -0.05])))
    assert code == 0
    assert "a series needs 3 runs for a step to be searched, and the longest holds 2" in text
