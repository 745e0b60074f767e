"""A bench planned for its gate: the calibration beside a bench file, the plan it gives, a
[gate] tolerance the bench cannot decide refused when its runs are planned (with what would
decide it), and a calibration that no longer holds named and not used."""

from __future__ import annotations

import math
import re
import textwrap
from pathlib import Path

import pytest
import toys

from slipbench.app.benchfile import load_benchmark, plan_runs
from slipbench.app.calibrate import detector_identities, digest, settings, status
from slipbench.app.gateplan import plan_gate, refusal
from slipbench.errors import DataError, UsageError
from slipbench.gate.calibration import (
    CALIBRATION as CALIBRATED,
)
from slipbench.gate.calibration import (
    Calibration,
    DetectorCalibration,
    Noise,
    ProtocolNoise,
    calibration_path,
    read_calibration,
)
from slipbench.gate.power import nominal_levels

BENCH = """\
[benchmark]
out = "res"
[dataset]
path = "{data}"
[run]
split = "grouped"
repeats = 3
[gate]
accuracy = {accuracy}
tn_rate = 3.0
budget = 12
[detectors.holweg]
keep = {keep}
[protocols.window-size]
windows = [50]
"""


def _bench(tmp_path: Path, data, accuracy=1.5, keep=0.8) -> Path:
    path = tmp_path / "bench.toml"
    path.write_text(BENCH.format(data=data, accuracy=accuracy, keep=keep))
    return path


def _noise(paired_sd: float, apart_sd: float, trial_sd: float = 0.0) -> Noise:
    """Noise of a protocol's mean, its standard deviations given in points a seed (``trial_sd``:
    over test trials, 0 where a test is about the seeds' noise alone)."""
    return Noise(
        20, 8, 0.8, (apart_sd / 100) ** 2, 19.0, (paired_sd / 100) ** 2, 20.0, (trial_sd / 100) ** 2
    )


def _calibrate_by_hand(
    path: Path, paired_sd=0.3, apart_sd=1.0, deterministic=False, trial_sd=0.0
) -> None:
    """A calibration of the bench at ``path`` as `slipbench calibrate` would key it, with
    the given noise (no cell runs)."""
    bench = load_benchmark(path)
    runs = plan_runs(bench, check_gate=False)
    now = settings(bench, runs)
    params, code = detector_identities(runs)["holweg"]
    noise = _noise(paired_sd, apart_sd, trial_sd)
    cal = Calibration(
        settings=now,
        digest=digest(now),
        seeds=tuple(range(20)),
        dataset_fingerprint="0" * 16,
        created="2026-01-01T00:00:00+00:00",
        slipbench_version="test",
        wall_seconds_per_seed=15.0,
        machine={"processors": 2, "jobs": 2, "load_average": [0.5, 0.7]},
        detectors={
            "holweg": DetectorCalibration(
                params,
                code,
                deterministic,
                2.0,
                {"window-size": ProtocolNoise({"accuracy": noise, "tn_rate": noise}, {})},
            )
        },
    )
    calibration_path(path).write_text(cal.to_json())


def _plan(path: Path):
    bench = load_benchmark(path)
    runs = plan_runs(bench, check_gate=False)
    return bench, plan_gate(bench, runs, status(bench, runs))


def test_a_decidable_bench_is_planned_and_passes(tmp_path, small_path):
    path = _bench(tmp_path, small_path)
    _calibrate_by_hand(path)
    lines: list[str] = []
    plan_runs(load_benchmark(path), echo=lines.append)  # not refused, nothing to say
    assert lines == []
    bench, plan = _plan(path)
    assert plan.undecided == [] and refusal(plan, bench) is None
    assert plan.design.tests == 2 and plan.design.budget == 12 and plan.design.seeds == 3
    text = "\n".join(plan.lines())
    assert "3 seeds a side, up to 12 in looks of 3 (3, 6, 9, 12); 2 pooled tests" in text
    levels = nominal_levels(plan.design)  # 0.025 / 4 a side, spent over the four looks
    assert levels[0] < 1e-6 < levels[-1] < plan.design.level == pytest.approx(0.025 / 4)
    assert "one-sided levels " + ", ".join(f"{p:.2g}" for p in levels) in text
    assert "about 45 s at 3 seeds, 3 min at the budget" in text  # 15 s a seed, measured
    acc = next(t for t in plan.tests if t.figure == "accuracy")
    assert acc.same is not None and acc.same.decides and acc.same.sd == pytest.approx(0.3)
    assert acc.apart is not None and acc.apart.sd == pytest.approx(math.sqrt(2) * 1.0)
    assert "holweg, window-size, accuracy (tolerance 1.5 points): same seeds: flags" in text


def test_a_tolerance_the_bench_cannot_decide_is_refused_with_what_would(tmp_path, small_path, cli):
    path = _bench(tmp_path, small_path, accuracy=0.1)
    _calibrate_by_hand(path, paired_sd=1.0)
    with pytest.raises(UsageError) as caught:
        plan_runs(load_benchmark(path))
    message = str(caught.value)
    assert (
        "bench.toml, line 9, [gate] accuracy: a tolerance of 0.1 points that this bench" in message
    )
    assert "a budget of" not in message  # ten looks would not do
    bench, plan = _plan(path)
    (test,) = plan.undecided
    wanted = float(re.findall(r"a tolerance of ([\d.]+) points", message)[-1])
    assert wanted >= test.same.at_budget  # the tolerance it names decides, rounded up
    path.write_text(path.read_text().replace("accuracy = 0.1", f"accuracy = {wanted}"))
    _calibrate_by_hand(path, paired_sd=1.0)
    plan_runs(load_benchmark(path))  # decided: not refused
    bad = _bench(tmp_path, small_path, accuracy=0.1)
    _calibrate_by_hand(bad, paired_sd=1.0)
    code, _, err = cli(["run", str(bad), "--quiet"])  # refused before any cell: nothing written
    assert code == 2 and "[gate] accuracy" in err and not (tmp_path / "res").exists()


def test_a_budget_that_would_decide_is_named(tmp_path, small_path):
    path = _bench(tmp_path, small_path, accuracy=1.0)
    _calibrate_by_hand(path, paired_sd=1.1)
    with pytest.raises(UsageError, match=r"a budget of (1[5-9]|2\d|30) seeds a side, a tol"):
        plan_runs(load_benchmark(path))


def test_a_detector_that_draws_nothing_still_carries_its_test_trials_noise(tmp_path, small_path):
    """Its twin equals its run (paired noise 0), but a drop of twice the tolerance leaves
    test-set noise (2 points a seed over trials, the accuracy at 80 %): a tolerance of 0.1
    points is refused, one the trials can resolve is planned, and the plan says which
    noise remains."""
    path = _bench(tmp_path, small_path, accuracy=0.1)
    _calibrate_by_hand(path, paired_sd=0.0, deterministic=True, trial_sd=2.0)
    with pytest.raises(UsageError, match=r"cannot decide: with its calibrated noise \(0\.22"):
        plan_runs(load_benchmark(path))
    path.write_text(path.read_text().replace("accuracy = 0.1", "accuracy = 1.5"))
    _calibrate_by_hand(path, paired_sd=0.0, deterministic=True, trial_sd=2.0)
    plan_runs(load_benchmark(path))
    _, plan = _plan(path)
    text = "\n".join(plan.lines())
    assert "retraining adds no noise), its test trials' noise remains: flags a drop of" in text
    (test,) = [t for t in plan.tests if t.figure == "accuracy"]
    assert test.same.sd == pytest.approx(2.0 * (2 * 0.015 / (0.8 * 0.2)) ** 0.5)


def test_a_stale_calibration_is_named_and_not_used(tmp_path, small_path):
    path = _bench(tmp_path, small_path, accuracy=0.1)
    _calibrate_by_hand(path, paired_sd=1.0)
    path.write_text(path.read_text().replace("keep = 0.8", "keep = 0.7"))
    lines: list[str] = []
    plan_runs(load_benchmark(path), echo=lines.append)  # not refused: nothing known now
    assert lines == [
        "bench.calibration.json is stale for holweg: its parameters changed since it was "
        "calibrated; the gate falls back to the pull request's own seeds until `slipbench "
        "calibrate` measures it again"
    ]
    _, plan = _plan(path)
    assert all(t.same is None and "parameters changed" in t.why for t in plan.tests)
    path.write_text(path.read_text().replace("windows = [50]", "windows = [100]"))
    lines.clear()
    plan_runs(load_benchmark(path), echo=lines.append)
    assert "the bench's settings changed" in lines[0]


def test_a_file_that_is_not_a_calibration_is_refused(tmp_path, small_path, cli):
    path = _bench(tmp_path, small_path)
    calibration_path(path).write_text("{broken")
    with pytest.raises(DataError, match="bench.calibration.json: not a slipbench calibration"):
        plan_runs(load_benchmark(path))
    code, _, err = cli(["run", str(path), "--quiet"])
    assert code == 2 and "not a slipbench calibration" in err


def test_calibrate_refuses_a_bench_of_both_inputs_before_any_work(tmp_path, small_path, cli):
    path = _bench(tmp_path, small_path)
    path.write_text(
        path.read_text().replace('split = "grouped"', 'split = "grouped"\ninput = "both"')
    )
    code, _, err = cli(["calibrate", str(path), "--seeds", "3"])
    assert code == 2 and 'input = "both"' in err and not (tmp_path / "res").exists()


def test_without_a_calibration_nothing_is_refused_and_the_plan_says_so(tmp_path, small_path):
    path = _bench(tmp_path, small_path, accuracy=0.01)
    lines: list[str] = []
    plan_runs(load_benchmark(path), echo=lines.append)
    assert lines == []
    _, plan = _plan(path)
    assert plan.seconds_per_seed is None
    assert all(t.same is None and t.why == "no calibration" for t in plan.tests)
    assert "no calibration (bench.calibration.json)" in "\n".join(plan.lines())


@pytest.mark.slow
def test_calibrate_measures_a_bench_and_resumes(tmp_path, small_path, cli):
    """`slipbench calibrate` on a retrained detector (Coin: scores from its fit's seed) and a
    deterministic one (holweg): the file holds both, holweg's twin equals its run, Coin's
    does not; its plan is printed; a second call reads every cell from the first."""
    plugins = tmp_path / "plugins" / "detectors"
    plugins.mkdir(parents=True)
    (plugins / "coin.py").write_text(toys.source(toys.Coin))
    path = tmp_path / "bench.toml"
    path.write_text(
        textwrap.dedent(
            f"""\
            [benchmark]
            out = "res"
            [dataset]
            path = "{small_path}"
            [run]
            split = "grouped"
            repeats = 2
            jobs = 1
            plugins = ["plugins"]
            [gate]
            accuracy = 1.0
            budget = 4
            [detectors.holweg]
            [detectors.coin]
            [protocols.window-size]
            windows = [50]
            """
        )
    )
    code, out, err = cli(["calibrate", str(path), "--seeds", "4", "--quiet"])
    assert code == 0, err
    cal = read_calibration(calibration_path(path))
    assert cal.seeds == (0, 1, 2, 3) and set(cal.detectors) == {"holweg", "coin"}
    holweg, coin = cal.detectors["holweg"], cal.detectors["coin"]
    assert holweg.deterministic and not coin.deterministic
    assert holweg.protocols["window-size"].figures["accuracy"].paired_var == 0
    assert coin.protocols["window-size"].figures["accuracy"].paired_var > 0
    assert len(coin.protocols["window-size"].cells) == 8  # every unit at window 50
    assert math.isfinite(cal.wall_seconds_per_seed) and cal.machine["jobs"] == 1
    assert "gate: 2 seeds a side, up to 4 in looks of 2 (2, 4)" in out
    assert "coin, window-size, accuracy (tolerance 1 points)" in out
    assert (tmp_path / "res" / "calibration" / "twins" / "results.parquet").exists()
    before = calibration_path(path).read_text()
    code, out, err = cli(["calibrate", str(path), "--seeds", "4", "--quiet"])
    assert code == 0, err
    again = read_calibration(calibration_path(path))
    assert math.isnan(again.wall_seconds_per_seed)  # every cell cached: nothing timed
    assert again.detectors["coin"] == cal.detectors["coin"] and before != ""
    # --if-stale (the workflow's push to main): a calibration that holds is left as it is
    kept = calibration_path(path).read_text()
    code, out, err = cli(["calibrate", str(path), "--seeds", "4", "--quiet", "--if-stale"])
    assert code == 0, err
    assert "holds for every detector of bench.toml: nothing to measure" in out
    assert calibration_path(path).read_text() == kept


def test_compare_takes_the_calibration_only_where_it_holds_for_base(tmp_path, small_path):
    """`compare --bench` checks the calibration against the calibration_key BASE's run
    recorded: where it holds, its noise answers (paired or apart); where BASE ran other
    parameters, one line says so and it answers nothing; without a record, a note."""
    from slipbench.app.benchfile import record
    from slipbench.app.commands.compare import _calibration
    from slipbench.stats.noise import SeedNoise

    path = _bench(tmp_path, small_path)
    _calibrate_by_hand(path, paired_sd=0.3, apart_sd=1.0)
    bench = load_benchmark(path)
    record(bench, tmp_path / "base", plan_runs(bench, check_gate=False))
    sources, notes = _calibration(path, tmp_path / "base")
    assert notes == [] and len(sources) == 1
    at = ("holweg", "window-size", "accuracy", None)
    assert sources[0].seed_noise(*at, True) == SeedNoise(0.3**2 / 1e4, 20.0, CALIBRATED)
    assert sources[0].seed_noise(*at, False) == SeedNoise(1.0 / 1e4, 19.0, CALIBRATED)

    (tmp_path / "x").mkdir()
    other = load_benchmark(_bench(tmp_path / "x", small_path, keep=0.7))
    record(other, tmp_path / "old", plan_runs(other, check_gate=False))
    sources, notes = _calibration(path, tmp_path / "old")
    assert sources[0].seed_noise(*at, True) is None
    assert notes == [
        "bench.calibration.json is stale for holweg: its parameters changed since it was "
        "calibrated; the gate falls back to the pull request's own seeds until `slipbench "
        "calibrate` measures it again"
    ]
    (tmp_path / "bare").mkdir()
    sources, notes = _calibration(path, tmp_path / "bare")
    assert sources == [] and "BASE holds no record of a benchmark run's code" in notes[0]
    (tmp_path / "bare" / "benchmark.json").write_text("[")
    with pytest.raises(DataError, match="bare/benchmark.json: not a benchmark run's record"):
        _calibration(path, tmp_path / "bare")
