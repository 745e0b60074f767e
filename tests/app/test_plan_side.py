"""The gate's cost of a side (`run FILE --plan`) counts what a `slipbench run` of the file
does besides its models: the process's start, reading the dataset and writing the reports,
as `slipbench calibrate` measured them; a calibration written before they were measured is
read, and its cost says it counts the models only."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from slipbench.app.gateplan import budget_seconds, side_seconds
from slipbench.gate.calibration import Calibration, calibration_path, read_calibration
from slipbench.gate.power import Design

SIDE = {"start_s": 2.0, "read_s": 3.0, "reports_s": 6.0, "report_seeds": 3.0}


def test_a_side_counts_its_start_read_models_and_reports():
    assert side_seconds(3, 10.0, SIDE) == (2.0 + 3.0 + 30.0 + 6.0, True)
    # reports timed on 3 seeds' rows, scaled to the side's seeds
    assert side_seconds(6, 10.0, SIDE) == (2.0 + 3.0 + 60.0 + 12.0, True)


@pytest.mark.parametrize("missing", ["start_s", "read_s", "reports_s", "report_seeds"])
def test_a_side_without_every_part_measured_counts_its_models_only(missing):
    part = {k: v for k, v in SIDE.items() if k != missing}
    assert side_seconds(3, 10.0, part) == (30.0, False)
    assert side_seconds(3, 10.0, {**SIDE, missing: float("nan")}) == (30.0, False)


def test_each_look_up_to_the_budget_is_a_run_that_starts_reads_and_reports_again():
    design = Design(3, 12, 2, 0.025)  # looks at 3, 6, 9, 12 seeds: four runs of 3 seeds
    assert budget_seconds(design, 10.0, SIDE) == pytest.approx(4 * 41.0)
    uneven = Design(3, 7, 2, 0.025)  # looks at 3, 6, 7: runs of 3, 3 and 1 seeds
    assert budget_seconds(uneven, 10.0, SIDE) == pytest.approx(2 * 41.0 + 2 + 3 + 10 + 2)
    assert budget_seconds(design, 10.0, {}) == pytest.approx(120.0)


def _calibration_file(tmp_path: Path, side: dict | None) -> Path:
    cal = Calibration(
        settings={},
        digest="0",
        seeds=(0, 1),
        dataset_fingerprint="0" * 16,
        created="2026-01-01T00:00:00+00:00",
        slipbench_version="test",
        wall_seconds_per_seed=10.0,
        machine={"processors": 2, "jobs": 2, "load_average": [0.5, 0.7]},
        side=side or {},
    )
    data = json.loads(cal.to_json())
    if side is None:
        del data["side"]  # as a calibration written before the side's parts were measured
    path = tmp_path / "old.calibration.json"
    path.write_text(json.dumps(data))
    return path


def test_a_calibration_keeps_a_sides_parts_and_an_older_one_reads_without_them(tmp_path):
    assert read_calibration(_calibration_file(tmp_path, SIDE)).side == SIDE
    assert read_calibration(_calibration_file(tmp_path, None)).side == {}


def test_the_plan_says_what_its_cost_of_a_side_counts():
    from slipbench.app.gateplan import _cost_line

    machine = {"processors": 2, "jobs": 2, "load_average": [0.5, 0.7]}
    line = _cost_line(Design(3, 12, 2, 0.025), 10.0, SIDE, machine)
    assert line.startswith("cost of a side: about 41 s at 3 seeds, 3 min at the budget (4 runs)")
    assert "counting start 2 s, reading the data 3 s, models 30 s" in line
    assert "reports 6 s" in line
    old = _cost_line(Design(3, 12, 2, 0.025), 10.0, {}, machine)
    assert "about 30 s at 3 seeds" in old and "models only" in old and "predates" in old


def _slipbench(*args: str) -> float:
    """Seconds of ``python -m slipbench ARGS`` in its own process, as CI runs a side."""
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    t0 = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "slipbench", *args], env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    return time.perf_counter() - t0


@pytest.mark.slow
def test_the_planned_side_is_near_a_side_measured_after_it(tmp_path, small_path):
    """Calibrated on a small bench's first look, the plan's cost of a side is within a
    generous factor of a side then run and timed (models are a small share of it here: the
    start, the read and the reports are most of what a small side costs)."""
    path = tmp_path / "bench.toml"
    path.write_text(
        textwrap.dedent(
            f"""\
            [benchmark]
            out = "res"
            report = ["md", "html"]
            intervals = true
            [dataset]
            path = "{small_path}"
            [run]
            split = "grouped"
            repeats = 2
            jobs = 1
            [gate]
            accuracy = 3.0
            budget = 4
            [detectors.holweg]
            [protocols.window-size]
            windows = [50]
            """
        )
    )
    _slipbench("calibrate", str(path), "--seeds", "2", "--quiet")
    cal = read_calibration(calibration_path(path))
    assert set(cal.side) == {"start_s", "read_s", "reports_s", "report_seeds"}
    assert cal.side["report_seeds"] == 2 and all(v > 0 for v in cal.side.values())
    planned, counted = side_seconds(2, cal.wall_seconds_per_seed, cal.side)
    # two seeds' noise may refuse the gate's tolerance: the side runs without the calibration
    calibration_path(path).rename(tmp_path / "measured.calibration.json")
    measured = _slipbench("run", str(path), "--out", str(tmp_path / "side"), "--quiet")
    assert counted and 0.5 < planned / measured < 2.0, (planned, measured, cal.side)


def test_a_dataset_not_yet_simulated_adds_its_simulation_to_the_first_run_only():
    from slipbench.app.gateplan import _cost_line

    machine = {"processors": 2, "jobs": 2, "load_average": [0.5, 0.7]}
    design = Design(3, 6, 2, 0.025)  # two runs of 41 s each
    line = _cost_line(design, 10.0, {**SIDE, "simulate_s": 40.0}, machine, uncached=True)
    assert "about 81 s at 3 seeds, 2 min at the budget (2 runs)" in line  # 41 + 40, 82 + 40
    assert "the first run simulates the dataset first (40 s, counted)" in line
    cached = _cost_line(design, 10.0, {**SIDE, "simulate_s": 40.0}, machine)
    assert "about 41 s at 3 seeds" in cached and "simulat" not in cached
    unmeasured = _cost_line(design, 10.0, SIDE, machine, uncached=True)
    assert "about 41 s at 3 seeds" in unmeasured and "simulates it first, not counted" in unmeasured


@pytest.mark.slow  # simulates a dataset (about 10 s)
def test_calibrate_times_a_simulation_apart_from_the_read_a_side_makes(tmp_path, monkeypatch):
    from slipbench.app.benchspec import load_benchmark
    from slipbench.app.calibrate import measured_read
    from slipbench.app.gateplan import _uncached

    monkeypatch.setenv("SLIPBENCH_CACHE", str(tmp_path / "cache"))
    path = tmp_path / "bench.toml"
    path.write_text(
        "[dataset]\nscale = 0.005\nseed = 3\n[detectors.holweg]\n[protocols.window-size]\n"
    )
    bench = load_benchmark(path)
    assert _uncached(bench)
    ds, side = measured_read(bench, echo=lambda _: None)
    assert set(side) == {"start_s", "read_s", "simulate_s"} and not _uncached(bench)
    assert side["simulate_s"] > 0 < side["read_s"] and len(ds.recordings) > 0
    _, again = measured_read(bench, echo=lambda _: None)
    assert set(again) == {"start_s", "read_s"}  # cached: read only, as a side reads it
