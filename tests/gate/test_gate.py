"""The gate's decisions on synthetic tests: verdicts read from intervals, the power each "no regression" states, and
when a comparison is undecided (exit 6) rather than passed or failed."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy.stats import norm

from slipbench.errors import EXIT_REGRESSION, EXIT_UNDECIDED, UsageError
from slipbench.gate.compare import POOLED_ALPHA, Comparison, _pooled_verdicts
from slipbench.gate.gate import (
    MAX_NEEDED,
    Gate,
    needed,
    parse_tolerances,
    resolution,
    scaled_resolution,
    two_sided_p,
)


def test_a_drop_of_tolerance_plus_resolution_is_flagged_with_80_percent_power():
    """The stated formula, checked by simulation: normal changes of standard error 1."""
    se, tol, n_tests = 1.0, 1.0, 6
    drop = tol + resolution(se, np.inf, n_tests, POOLED_ALPHA)
    d = -drop + se * np.random.default_rng(1).standard_normal(20_000)
    p_reg, _ = two_sided_p(-d, np.full_like(d, se), np.full_like(d, np.inf), tol)
    power = np.mean(p_reg <= POOLED_ALPHA / n_tests)  # the family's Bonferroni level
    assert power == pytest.approx(0.8, abs=0.01)
    assert drop == pytest.approx(tol + norm.ppf(1 - POOLED_ALPHA / 12) + norm.ppf(0.8))


def _pooled(**over):
    row = dict(
        protocol="window-size",
        detector="holweg",
        figure="accuracy",
        change=-0.2,
        change_lo=-0.9,
        change_hi=0.5,
        change_se=0.2,
        df=30.0,
        low_n=False,
        seeds=3,
        trials=40,
    )
    return pd.DataFrame([row | over])


def _verdict(retrained=True, **over):
    return _pooled_verdicts(_pooled(**over), Gate(), retrained).iloc[0]


def test_a_precise_test_says_no_regression_and_what_it_would_have_seen():
    r = _verdict()
    assert r["verdict"] == "within margin" and r["resolution"] < 1
    assert r["detectable"] == pytest.approx(1 + r["resolution"])


def test_noise_wider_than_the_tolerance_is_undecided_and_says_what_would_decide():
    r = _verdict(change_se=1.0, change_lo=-4, change_hi=4)
    assert r["verdict"] == "undecided" and "80 % power" in r["undecided_reason"]
    # the fewest that decide: the standard error falls as sqrt(n / m), the df grow with m
    for n, seeds in ((3, True), (40, False)):
        m = r["seeds_needed" if seeds else "trials_needed"]
        at = scaled_resolution(n, 1.0, 30.0, seeds, lambda s, d: resolution(s, d, 1, POOLED_ALPHA))
        assert at(m) <= 1.0 < at(m - 1)


def test_few_seeds_ask_for_what_their_degrees_of_freedom_allow():
    """Three seeds leave two degrees of freedom: the seeds that decide count the df that more
    seeds bring, not hundreds from holding t(0.999, 2) fixed."""
    r = _verdict(change_se=1.1, df=2.0, change_lo=-20, change_hi=20)
    fixed_df = int(np.ceil(3 * (r["resolution"] / 1.0) ** 2))
    assert r["verdict"] == "undecided" and fixed_df > 150
    assert 10 < r["seeds_needed"] < fixed_df / 4
    assert needed(3, 1.0, lambda m: 50.0) == MAX_NEEDED


def test_low_n_and_one_seed_per_side_are_undecided_even_when_flagged():
    assert _verdict(low_n=True, change=-10.0)["verdict"] == "undecided"
    r = _verdict(retrained=False, seeds=1)
    assert r["verdict"] == "undecided" and r["undecided_reason"].startswith("one seed per side")
    assert r["seeds_needed"] == 3


def test_false_alarms_per_minute_rising_is_the_worse_direction():
    def at(change: float) -> dict:
        return dict(change=change, change_se=0.3, change_lo=change - 0.6, change_hi=change + 0.6)

    up = _verdict(figure="false_alarms_per_min", **at(3.0))
    down = _verdict(figure="false_alarms_per_min", **at(-3.0))
    assert (up["verdict"], down["verdict"]) == ("regressed", "improved")
    assert _verdict(figure="tn_rate", **at(-3.0))["verdict"] == "regressed"
    assert up["p"] < POOLED_ALPHA


def test_a_pooled_verdict_reads_the_interval_printed_beside_it():
    """The issue's compare comment: a TN line "regressed" (Holm p 0.023) beside a printed
    interval that held 0. The verdict now reads that interval: a p below alpha with an interval
    reaching past the tolerance is no regression, and the adjusted p agrees with the interval."""
    r = _verdict(figure="tn_rate", change=-2.5, change_se=0.6, change_lo=-4.3, change_hi=0.1)
    assert r["verdict"] != "regressed"
    for change, lo, hi, se in (
        (-2.5, -4.3, -1.2, 0.5),
        (-2.5, -4.3, 0.1, 0.5),
        (0.2, -0.1, 0.5, 0.1),
    ):
        r = _verdict(figure="tn_rate", change=change, change_lo=lo, change_hi=hi, change_se=se)
        assert (r["verdict"] == "regressed") == (hi < -1)
        assert (r["verdict"] == "within margin") == (-1 <= lo and hi <= 1)


def _comparison(cell_verdict, pooled, seeds):
    cells = pd.DataFrame(
        [{"verdict": cell_verdict, "method": "paired over trials", "regressed_figures": ""}]
    )
    empty = pd.DataFrame()
    return Comparison(
        cells,
        empty,
        empty,
        "b",
        "c",
        pooled=pooled,
        min_seeds_base=seeds,
        min_seeds_candidate=seeds,
    )


def test_exit_codes():
    flagged = _pooled_verdicts(_pooled(change=-5.0), Gate(), True)
    assert _comparison("regressed", flagged, 3).exit_code == EXIT_REGRESSION
    # the same on one seed per side: noise alone could do it
    assert _comparison("regressed", flagged, 1).exit_code == EXIT_UNDECIDED == 6
    calm = _pooled_verdicts(_pooled(), Gate(), True)
    assert _comparison("no significant change", calm, 3).exit_code == 0
    noisy = _pooled_verdicts(_pooled(change_se=2.0), Gate(), True)
    assert _comparison("no significant change", noisy, 3).exit_code == EXIT_UNDECIDED
    failed = _comparison("regressed", calm, 1)
    failed.cells["method"] = "status ok → failed"
    assert failed.exit_code == EXIT_REGRESSION  # a cell the candidate no longer finishes


def test_gate_options_are_checked():
    assert Gate.of(["accuracy"], tn_rate=2).tolerances == {"accuracy": 1.0, "tn_rate": 2.0}
    assert Gate.of(["tn_rate"]).figures(stream=False) == ("tn_rate",)
    assert parse_tolerances(["tn_rate=2.5"]) == {"tn_rate": 2.5}
    with pytest.raises(UsageError, match="FIGURE=POINTS"):
        parse_tolerances(["tn_rate=much"])
    with pytest.raises(UsageError, match="a tolerance must be > 0"):
        Gate({"accuracy": 0.0})
    with pytest.raises(UsageError, match="unknown figure auroc"):
        Gate({"auroc": 1.0})


def _stream_cell(**changes):
    """A finished streaming cell with each named figure's change and standard error."""
    row = dict(
        base_status="ok", candidate_status="ok", stream=True, identical=False, low_n=False
    ) | {"method": "unpaired streams", "df": np.inf}
    for name in ("median_delay_ms", "false_alarms_per_min", "detection_rate"):
        d, se = changes.get(name, (0.0, 0.001 if name == "detection_rate" else 0.1))
        row |= {f"d_{name}": d, f"d_{name}_se": se, f"d_{name}_lo": d - 3 * se}
        row[f"d_{name}_hi"] = d + 3 * se
    return row


def test_stream_cells_are_judged_on_each_figure_in_its_direction():
    from slipbench.gate.compare import _judge_cells

    cells = pd.DataFrame(
        [
            _stream_cell(median_delay_ms=(40.0, 3.0)),  # 40 ms later: worse than 10 ms
            _stream_cell(median_delay_ms=(-40.0, 3.0), false_alarms_per_min=(-3.0, 0.3)),
            _stream_cell(median_delay_ms=(-40.0, 3.0), false_alarms_per_min=(3.0, 0.3)),
            _stream_cell(detection_rate=(-0.1, 0.01)),  # 10 points fewer onsets detected
            _stream_cell(),
        ]
    )
    judged = _judge_cells(cells, Gate())
    assert list(judged["verdict"]) == [
        "regressed",
        "improved",
        "regressed",
        "regressed",
        "within margin",
    ]
    assert list(judged["regressed_figures"])[:4] == [
        "median_delay_ms",
        "",
        "false_alarms_per_min",
        "detection_rate",
    ]
    # a tolerance wider than the change forgives it
    assert _judge_cells(cells.iloc[:1].copy(), Gate.of(median_delay_ms=60))["verdict"].iloc[0] != (
        "regressed"
    )


def test_the_command_reads_figures_from_options_or_the_bench_file(tmp_path):
    from slipbench.app.commands.compare import gate_from

    bench = tmp_path / "bench.toml"
    bench.write_text(
        "[gate]\ntn_rate = 2.0\naccuracy = 1.5\n[detectors.holweg]\n[protocols.window-size]\n"
    )
    assert gate_from((), bench, None, 40.0).tolerances == {"tn_rate": 2.0, "accuracy": 1.5}
    # --figure wins over the file; a bare name takes its default; --margin sets the rates'
    gate = gate_from(("tp_rate", "median_delay_ms=20"), bench, 3.0, 40.0)
    assert gate.tolerances == {"tp_rate": 3.0, "median_delay_ms": 20.0}
    assert gate_from(("accuracy=0.5",), None, 3.0, 40.0).tolerances == {"accuracy": 0.5}
    bench.write_text("[gate]\ntn_rate = -1\n[detectors.holweg]\n[protocols.window-size]\n")
    with pytest.raises(UsageError, match="tn_rate must be a tolerance > 0"):
        gate_from((), bench, None, 40.0)
