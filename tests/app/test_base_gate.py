"""Nobody grades their own change: `compare` judges by the bench BASE recorded (its [gate],
budget and detectors), names in the comment's first line where the candidate's bench differs,
fails a detector the candidate dropped, and takes a calibration only where its numbers agree
with BASE's own seeds. Small synthetic result folders (tests/resultgen.py:predictions_pair)
with bench records written as `slipbench run` writes them."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from resultgen import predictions_pair

from slipbench.app.benchfile import load_benchmark, plan_runs, record
from slipbench.app.calibrate import detector_identities, digest, settings
from slipbench.gate.calibration import (
    Calibration,
    DetectorCalibration,
    Noise,
    ProtocolNoise,
    calibration_path,
)
from slipbench.gate.calibration_check import refused

BENCH = """\
[benchmark]
out = "results"
[run]
split = "grouped"
repeats = 3
[gate]
{gate}
[detectors.holweg]
{more}
[protocols.window-size]
"""
BASE_GATE = "accuracy = 1.5\ntn_rate = 3.0\ntp_rate = 3.0"


def _bench(where: Path, gate: str = BASE_GATE, more: str = "") -> Path:
    where.mkdir(parents=True, exist_ok=True)
    path = where / "bench.toml"
    path.write_text(BENCH.format(gate=gate, more=more))
    return path


def _record(folder: Path, bench: Path, runs: bool = False) -> None:
    """What `slipbench run` keeps of its bench file in the results folder."""
    b = load_benchmark(bench)
    record(b, folder, plan_runs(b, check_gate=False) if runs else None)


@pytest.fixture(scope="module")
def sides(tmp_path_factory):
    """BASE and CANDIDATE of 12 window-size cells at seeds 0, 1, 2: the candidate loses
    every window of a tenth of the trials in each cell (about 7 points of accuracy)."""
    root = tmp_path_factory.mktemp("basegate")
    return predictions_pair(root, n_cells=12, base_seeds=(0, 1, 2), cand_seeds=(0, 1, 2), flip=0.1)


def _first(text: str) -> str:
    """The comment's first line as a reader sees it (Markdown's escapes taken off)."""
    return text.splitlines()[0].replace("\\", "")


def _compare(cli, base: Path, cand: Path, *extra: str) -> tuple[int, str, dict, str]:
    out = base.parent / "compare.json"
    code, text, err = cli(["compare", str(base), str(cand), "--json", str(out), *extra])
    return code, text, json.loads(out.read_text()) if out.is_file() else {}, err


def test_widened_tolerances_are_the_base_s_and_named(sides, cli, tmp_path):
    """The candidate's bench widens every tolerance to 50 points: judged as it asks, the real
    drop passes (exit 0); judged by the base's recorded bench it regresses, and the comment's
    first line shows each tolerance old -> new."""
    base, cand = sides
    wide = _bench(tmp_path / "pr", "accuracy = 50\ntn_rate = 50\ntp_rate = 50")
    _record(base, wide)  # as before: both sides ran the pull request's bench
    _record(cand, wide)
    code, _, doc, _ = _compare(cli, base, cand)
    assert code == 0 and doc["headline"] == []
    _record(base, _bench(tmp_path / "main"))
    code, text, doc, _ = _compare(cli, base, cand)
    assert code == 1 and doc["gate"]["tolerances"] == {
        "accuracy": 1.5,
        "tn_rate": 3.0,
        "tp_rate": 3.0,
    }
    assert _first(text).startswith(
        "⚠ The candidate's bench differs from the base's, judged by the base's: tolerance "
        "accuracy 1.5 → 50; tolerance TN rate (false alarms) 3 → 50; tolerance TP rate "
        "(misses) 3 → 50."
    )
    assert doc["headline"][0].endswith("TP rate (misses) 3 → 50.")


def test_figures_dropped_from_the_gate_are_still_judged(sides, cli, tmp_path):
    base, cand = sides
    _record(base, _bench(tmp_path / "main"))
    _record(cand, _bench(tmp_path / "pr", "accuracy = 50"))
    code, text, doc, _ = _compare(cli, base, cand)
    assert code == 1 and set(doc["gate"]["tolerances"]) == {"accuracy", "tn_rate", "tp_rate"}
    assert {r["figure"] for r in doc["pooled"]} == {"accuracy", "tn_rate", "tp_rate"}
    first = _first(text)
    assert "TN rate (false alarms), TP rate (misses) dropped from [gate]" in first
    assert "tolerance accuracy 1.5 → 50" in first


def _renamed(folder: Path, out: Path, detector: str) -> pd.DataFrame:
    """``folder``'s rows and predictions as another detector's (other keys)."""
    rows = pd.read_parquet(folder / "results.parquet")
    other = rows.assign(detector=detector, key=rows["key"] + f"-{detector}")
    (out / "predictions").mkdir(parents=True, exist_ok=True)
    for key in rows["key"]:
        shutil.copy(
            folder / "predictions" / f"{key}.parquet",
            out / "predictions" / f"{key}-{detector}.parquet",
        )
    return other


def test_a_detector_the_candidate_dropped_is_missing_and_fails(sides, cli, tmp_path):
    """The base's bench runs holweg and bandpass; the candidate's deletes bandpass and leaves
    holweg unchanged: before, both sides ran the candidate's bench and nothing changed; now
    bandpass's cells are missing, the gate fails (exit 1) and the first line names both."""
    base, _ = sides
    two, one = tmp_path / "base", tmp_path / "cand"
    shutil.copytree(base, two)
    shutil.copytree(base, one)
    rows = pd.read_parquet(base / "results.parquet")
    pd.concat([rows, _renamed(base, two, "bandpass")]).to_parquet(two / "results.parquet")
    _record(two, _bench(tmp_path / "main", more="[detectors.bandpass]"))
    _record(one, _bench(tmp_path / "pr"))
    code, text, doc, _ = _compare(cli, one, one)  # the old way: the pull request's bench
    assert code == 0 and "Nothing changed" in text
    code, text, doc, _ = _compare(cli, two, one)
    assert code == 1 and doc["verdict"] == "regressed" and "Nothing changed" not in text
    assert doc["missing"] == ["12 cells of bandpass on window-size the base finished"]
    assert doc["counts"]["identical"] == 12  # holweg: the same rows
    first = _first(text)
    assert "detector bandpass removed" in first
    assert "Missing from the candidate (lost work, a regression): 12 cells of bandpass" in first
    assert "**Regressed**" in text and "missing: 12 cells of bandpass" in text


def test_bench_must_be_the_one_base_recorded_and_the_record_proves_it(sides, cli, tmp_path):
    base, cand = sides
    main = _bench(tmp_path / "main")
    _record(base, main)
    _record(cand, main)
    other = _bench(tmp_path / "pr", "accuracy = 50")
    code, _, _, err = _compare(cli, base, cand, "--bench", str(other))
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert f"--bench {other}: not the bench BASE ran" in err
    copy = base / "benchmark.toml"
    copy.write_text(copy.read_text().replace("accuracy = 1.5", "accuracy = 50"))
    code, _, _, err = _compare(cli, base, cand)
    assert code == 2 and "the bench BASE ran cannot be proved" in err
    assert "its benchmark.json records" in err


def test_a_recorded_bench_is_read_for_what_it_measures_not_for_this_machine(tmp_path):
    """A base run on a large machine (many workers) is judged on a small one: its record is
    read for its gate, and its workers are not checked here."""
    from slipbench.app.basegate import recorded_bench

    folder = tmp_path / "base"
    _record(folder, _bench(tmp_path / "main"))
    text = (
        (folder / "benchmark.toml").read_text().replace("repeats = 3", "repeats = 3\njobs = 100000")
    )
    (folder / "benchmark.toml").write_text(text)
    written = json.loads((folder / "benchmark.json").read_text())
    written["sha256"] = hashlib.sha256(text.encode()).hexdigest()
    (folder / "benchmark.json").write_text(json.dumps(written))
    bench = recorded_bench(folder, "BASE")
    assert bench is not None and bench.jobs == 100000 and bench.gate["accuracy"] == 1.5


# ----------------------------------------------------------------------------- calibration
def _calibrate(bench: Path, base: Path, scale: float, paired: float = 0.0) -> None:
    """A calibration of ``bench`` (holding for the code BASE recorded) whose seed variance of
    every cell and figure is ``scale`` times what BASE's own three seeds show."""
    b = load_benchmark(bench)
    runs = plan_runs(b, check_gate=False)
    rows = pd.read_parquet(base / "results.parquet")
    params, code = detector_identities(runs)["holweg"]

    def noise(x: np.ndarray, cells: int = 1) -> Noise:
        v = scale * float(np.var(x, ddof=1))
        return Noise(20, cells, float(np.mean(x)), v, 19.0, paired * v, 20.0, 1e-4)

    figures = ("accuracy", "tn_rate", "tp_rate")
    cells = {
        str(c): {f: noise(g[f].to_numpy(float)) for f in figures} for c, g in rows.groupby("cell")
    }
    means = rows.groupby("seed")[list(figures)].mean()
    now = settings(b, runs)
    cal = Calibration(
        settings=now,
        digest=digest(now),
        seeds=tuple(range(20)),
        dataset_fingerprint="f00d",
        created="2026-01-01T00:00:00+00:00",
        slipbench_version="test",
        wall_seconds_per_seed=1.0,
        machine={},
        detectors={
            "holweg": DetectorCalibration(
                params,
                code,
                False,
                1.0,
                {
                    "window-size": ProtocolNoise(
                        {f: noise(means[f].to_numpy(float), len(cells)) for f in figures}, cells
                    )
                },
            )
        },
    )
    calibration_path(bench).write_text(cal.to_json())


@pytest.mark.parametrize(("scale", "said"), [(25.0, "25 times"), (0.0, "is 0 where")])
def test_a_calibration_beyond_base_s_seeds_is_named_and_not_used(sides, cli, tmp_path, scale, said):
    """As measured (the base's own spread) it is used; 25 times the noise, or none, is
    named in the first line and not used: the sides' own seeds carry the noise."""
    base, cand = sides
    main = _bench(tmp_path / "main")
    _record(base, main, runs=True)
    _record(cand, main)
    _calibrate(main, base, 1.0, paired=0.5)
    code, text, doc, _ = _compare(cli, base, cand, "--bench", str(main))
    assert doc["headline"] == [] and "calibration" in doc["noise_measured"]
    assert not text.startswith("⚠")
    _calibrate(main, base, scale, paired=0.5)
    code, text, doc, _ = _compare(cli, base, cand, "--bench", str(main))
    first = _first(text)
    assert first.startswith("⚠ bench.calibration.json not used for holweg: its seed variance")
    assert said in first and "the sides' own seeds carry its noise" in first
    assert "calibration" not in doc["noise_measured"] and code in (1, 6)


def test_a_negative_variance_is_bad_input_in_one_line(sides, cli, tmp_path):
    base, cand = sides
    main = _bench(tmp_path / "main")
    _record(base, main, runs=True)
    _record(cand, main)
    _calibrate(main, base, 1.0)
    path = calibration_path(main)
    data = json.loads(path.read_text())
    part = data["detectors"]["holweg"]["protocols"]["window-size"]
    part["figures"]["tn_rate"]["seed_var"] = -0.001
    path.write_text(json.dumps(data))
    code, _, _, err = _compare(cli, base, cand, "--bench", str(main))
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "holweg, window-size, tn_rate: seed_var is -0.001, not a finite number >= 0" in err
    part["figures"]["tn_rate"]["seed_var"] = 0.001
    part["figures"]["tn_rate"]["paired_var"] = float("inf")  # json writes Infinity
    path.write_text(json.dumps(data))
    code, _, _, err = _compare(cli, base, cand, "--bench", str(main))
    assert code == 2 and "paired_var is inf" in err


def test_a_twin_louder_than_its_seeds_is_refused():
    """paired_var cannot exceed twice seed_var beyond chance; where it does (25 times) the
    detector is refused before BASE's seeds are read."""
    n = Noise(20, 1, 0.8, 1e-4, 19.0, 25 * 2e-4, 20.0, 1e-4)
    ok = Noise(20, 1, 0.8, 1e-4, 19.0, 2e-4, 20.0, 1e-4)
    rows = pd.DataFrame(columns=["detector", "protocol", "cell", "seed", "status", "accuracy"])

    def cal(noise: Noise) -> Calibration:
        det = DetectorCalibration(
            {}, "src:0", False, 1.0, {"p": ProtocolNoise({"accuracy": noise}, {})}
        )
        return Calibration({}, "", (0,), "", "", "", 1.0, {}, {"d": det})

    assert "twin's variance of accuracy on p" in refused(cal(n), rows, ["accuracy"])["d"]
    assert refused(cal(ok), rows, ["accuracy"]) == {}


def test_the_seed_check_pools_cells_and_skips_what_was_not_measured():
    """The base's pooled seed variance over the calibration's: a true one passes, one 20
    times too small or a base whose seeds never vary is refused, an unmeasured one (null)
    says nothing."""
    x = {0: 0.70, 1: 0.72, 2: 0.74}  # a seed variance of 4e-4 in every cell
    rows = pd.DataFrame(
        [
            {"detector": "d", "protocol": "p", "cell": f"c{c}", "seed": s, "status": "ok"}
            | {"accuracy": v + 0.01 * c}
            for c in range(4)
            for s, v in x.items()
        ]
    )

    def cal(var: float) -> Calibration:
        n = Noise(20, 1, 0.7, var, 19.0, 0.0, 20.0, 1e-4)
        part = ProtocolNoise({}, {f"c{c}": {"accuracy": n} for c in range(4)})
        det = DetectorCalibration({}, "src:0", True, 1.0, {"p": part})
        return Calibration({}, "", (0,), "", "", "", 1.0, {}, {"d": det})

    assert refused(cal(4e-4), rows, ["accuracy"]) == {}
    # an earlier run of the same cells (other code, other values) is left out, as compare does
    rows = rows.assign(finished_at="2026-11-02T00:00:00+00:00")
    older = rows.assign(finished_at="2026-11-01T00:00:00+00:00", accuracy=rows["accuracy"] * 0.1)
    assert refused(cal(4e-4), pd.concat([older, rows]), ["accuracy"]) == {}
    assert refused(cal(4e-4), older.assign(finished_at=rows["finished_at"]), ["accuracy"])
    assert refused(cal(float("nan")), rows, ["accuracy"]) == {}
    assert (
        "is 0.05 times what BASE's 3 seeds a cell show"
        in refused(cal(2e-5), rows, ["accuracy"])["d"]
    )
    flat = rows.assign(accuracy=0.7)
    assert "varies where BASE's seeds do not" in refused(cal(4e-4), flat, ["accuracy"])["d"]
