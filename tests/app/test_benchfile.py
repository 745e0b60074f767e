"""Benchmark files: `slipbench run bench.toml` runs what the file declares, keeps the file with
the results, and refuses a bad file before anything runs, naming the line and the key."""

from __future__ import annotations

import hashlib
import json
import re
import textwrap

import pandas as pd
import pytest

from slipbench.app.benchfile import plan_runs
from slipbench.app.benchspec import load_benchmark
from slipbench.errors import UsageError

GOOD = """\
[benchmark]
out = "res"
report = ["md", "html"]
plots = true
intervals = true

[dataset]
path = "{data}"

[run]
split = "grouped"
seed = 3
repeats = 2

[detectors.holweg]
keep = 0.7

[detectors.bandpass]

[protocols.window-size]
windows = [50]
"""


def write(tmp_path, text: str, **fields) -> str:
    path = tmp_path / "bench.toml"
    path.write_text(textwrap.dedent(text).format(**fields))
    return str(path)


@pytest.mark.slow
def test_run_declares_everything_and_records_the_file(tmp_path, small_path, cli):
    bench = write(tmp_path, GOOD, data=small_path)
    code, out, err = cli(["run", bench, "--quiet"])
    assert code == 0, err
    res = tmp_path / "res"
    rows = pd.read_parquet(res / "results.parquet")
    assert set(rows["detector"]) == {"holweg", "bandpass"} and set(rows["protocol"]) == {
        "window-size"
    }
    assert (
        set(rows["seed"]) == {3, 4}
        and set(rows["split"]) == {"grouped"}
        and set(rows["window"]) == {50}
    )
    assert set(rows.loc[rows["detector"] == "holweg", "detector_params"]) == {
        '{"band": null, "keep": 0.7}'
    }
    assert (res / "benchmark.toml").read_text() == (tmp_path / "bench.toml").read_text()
    record = json.loads((res / "benchmark.json").read_text())
    assert record["sha256"] == hashlib.sha256((tmp_path / "bench.toml").read_bytes()).hexdigest()
    report = (res / "report.md").read_text()
    assert f"| Benchmark file | bench.toml (sha256 {record['sha256'][:16]})" in re.sub(
        " +", " ", report
    )
    assert (
        "## Leaderboard" in report
        and "![" in report
        and (res / "report.html").stat().st_size > 10_000
    )
    assert (res / "figures" / "window-size-detectors-grouped.png").exists()
    code, out, _ = cli(
        ["run", bench, "--quiet", "--out", str(tmp_path / "other")]
    )  # CI: one file, two folders
    assert code == 0 and (tmp_path / "other" / "results.parquet").exists()


@pytest.mark.parametrize(
    "text, message",
    [
        (
            '[benchmark]\nout = "r"\nformat = "md"\n[detectors.holweg]\n[protocols.window-size]\n',
            "bench.toml, line 3, [benchmark] format: unknown key 'format'; [benchmark] takes out, report",
        ),
        (
            "[detectors.holweg]\n[protocols.window-size]\n[runs]\nseed = 1\n",
            "bench.toml, line 3, [runs]: unknown table or key 'runs'",
        ),
        (
            '[run]\nseed = "zero"\n[detectors.holweg]\n[protocols.window-size]\n',
            "bench.toml, line 2, [run] seed: seed must be an int in [0, 2**32 - 1], got 'zero'",
        ),
        (
            "[run]\nrepeats = true\n[detectors.holweg]\n[protocols.window-size]\n",
            "line 2, [run] repeats: repeats must be an int >= 1, got True",
        ),
        (
            '[run]\nsplit = "random"\n[detectors.holweg]\n[protocols.window-size]\n',
            "line 2, [run] split: split must be paper or grouped",
        ),
        ("[protocols.window-size]\n", "[detectors]: no detector: add a table [detectors.<id>]"),
        ("[detectors.holweg]\n", "[protocols]: no protocol"),
        (
            '[dataset]\npath = "x"\nscale = 0.1\n[detectors.holweg]\n[protocols.window-size]\n',
            "line 3, [dataset] scale: scale and seed describe the simulated dataset",
        ),
        (
            '[benchmark]\nreport = ["pdf"]\n[detectors.holweg]\n[protocols.window-size]\n',
            "line 2, [benchmark] report: unknown report format 'pdf'",
        ),
        (
            "[detectors]\nholweg = 1\n[protocols.window-size]\n",
            "[detectors] holweg: 'holweg' must be a table",
        ),
        ("[run\nseed = 1\n", "bench.toml: not valid TOML: "),
        (
            "[run]\nrepeats = 3\n[gate]\nbudget = 2\n[detectors.holweg]\n[protocols.window-size]\n",
            "line 4, [gate] budget: budget (2) must be at least run.repeats (3)",
        ),
        (
            "[gate]\nbudget = 6\n[detectors.holweg]\n[protocols.window-size]\n",
            "line 2, [gate] budget: a budget grows seeds in steps of run.repeats, which must then",
        ),
        (
            "[run]\nrepeats = 3\n[gate]\nbudget = 6.5\n[detectors.holweg]\n[protocols.window-size]\n",
            "line 4, [gate] budget: budget must be seeds per side, an int >= run.repeats, got 6.5",
        ),
    ],
)
def test_a_bad_file_is_refused_naming_line_and_key(tmp_path, text, message):
    with pytest.raises(UsageError) as err:
        load_benchmark(write(tmp_path, text.replace("{", "{{").replace("}", "}}")))
    assert message in str(err.value)


@pytest.mark.parametrize(
    "text, message",
    [
        (
            "[detectors.holweg]\nkeep = 3\n[protocols.window-size]\n",
            "line 2, [detectors.holweg] keep: The 'keep' parameter of Holweg must be a float in [0.0, 1.0]. Got 3 instead.",
        ),
        (
            "[detectors.holweg]\nkeeps = 0.5\n[protocols.window-size]\n",
            "line 2, [detectors.holweg] keeps: detector 'holweg' has no parameter keeps; its parameters: band, keep",
        ),
        (
            '[detectors.holweg]\n[protocols.window-size]\nwindows = ["fast"]\n',
            "line 3, [protocols.window-size] windows: The 'windows' parameter of WindowSize",
        ),
        (
            "[detectors.no-such]\n[protocols.window-size]\n",
            "line 1, [detectors.no-such]: unknown detector 'no-such'",
        ),
        (
            '[run]\nplugins = ["missing"]\n[detectors.holweg]\n[protocols.window-size]\n',
            "line 2, [run] plugins: plugin folder",
        ),
    ],
)
def test_plugins_and_their_parameters_are_checked_before_running(tmp_path, text, message):
    with pytest.raises(UsageError) as err:
        plan_runs(load_benchmark(write(tmp_path, text.replace("{", "{{").replace("}", "}}"))))
    assert message in str(err.value)


def test_the_gate_budget_defaults_to_the_first_looks_seeds(tmp_path):
    bench = load_benchmark(
        write(tmp_path, "[run]\nrepeats = 3\n[detectors.holweg]\n[protocols.window-size]\n")
    )
    assert bench.budget is None and bench.seeds_budget == 3 and bench.gate == {}
    text = "[run]\nrepeats = 3\n[gate]\ntn_rate = 2.0\nbudget = 9\n[detectors.holweg]\n[protocols.window-size]\n"
    bench = load_benchmark(write(tmp_path, text))
    assert bench.budget == 9 == bench.seeds_budget and bench.gate == {"tn_rate": 2.0}


def test_the_record_keeps_what_a_calibration_is_checked_against(tmp_path):
    """A comparison runs with the candidate's code: the base's record says which settings and
    detector code made its rows, as `slipbench calibrate` keys them."""
    from slipbench.app.benchfile import record
    from slipbench.app.calibrate import detector_identities, digest, settings

    text = "[run]\nrepeats = 2\n[detectors.holweg]\nkeep = 0.7\n[protocols.window-size]\n"
    bench = load_benchmark(write(tmp_path, text))
    runs = plan_runs(bench)
    record(bench, tmp_path / "res", runs)
    key = json.loads((tmp_path / "res" / "benchmark.json").read_text())["calibration_key"]
    assert key["settings_digest"] == digest(settings(bench, runs))
    params, code = detector_identities(runs)["holweg"]
    assert key["detectors"] == {"holweg": {"params": params, "own_code": code}}
    assert params["keep"] == 0.7 and code.startswith("src:")


def test_cli_exit_code_for_a_bad_file(tmp_path, cli):
    code, _, err = cli(
        ["run", write(tmp_path, "[detectors.holweg]\nkeep = 3\n[protocols.window-size]\n")]
    )
    assert code == 2 and "line 2" in err and "keep" in err
    code, _, err = cli(["run", str(tmp_path / "absent.toml")])
    assert code == 2 and "no such benchmark file" in err


@pytest.mark.slow
def test_run_seed_overrides_the_files_seed(tmp_path, unit, cli):
    bench = write(
        tmp_path,
        """\
        [benchmark]
        out = "res"
        plots = false

        [dataset]
        path = "{data}"

        [run]
        seed = 3

        [detectors.holweg]

        [protocols.window-size]
        windows = [50]
        """,
        data=unit,
    )
    code, _, err = cli(["run", bench, "--quiet", "--seed", "7"])
    assert code == 0, err
    rows = pd.read_parquet(tmp_path / "res" / "results.parquet")
    assert set(rows["seed"]) == {7}
    assert json.loads((tmp_path / "res" / "benchmark.json").read_text())["seed"] == 7
    code, _, err = cli(["run", bench, "--quiet", "--seed", "-1"])
    assert code == 2 and "--seed" in err
