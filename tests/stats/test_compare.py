"""`slipbench compare`: no change against itself (exit 0), a degraded detector named (exit 1),
cells on one side listed, bad input refused (exit 2), and the verdict's error rate over a whole
run measured on a simulated null."""

from __future__ import annotations

import json
import os
import re
import shutil

import numpy as np
import pandas as pd
import pytest
import toys
from goldens import check_golden
from resultgen import fake_rows, whole_paper_pair
from scipy.special import expit
from scipy.stats import t as student_t
from test_coverage import TAUS, dataset

from slipbench.app.cli import main
from slipbench.errors import EXIT_UNDECIDED, DataError
from slipbench.gate.compare import CELL_ALPHA, compare, family_level
from slipbench.gate.gate import Gate
from slipbench.report.compare import COMMENT_LIMIT, MAX_ROWS, comment_markdown, to_json
from slipbench.stats.factors import latest_runs
from slipbench.stats.metrics import classification_figures, paired_comparison
from slipbench.store.results import check_unique_keys

NULL_RUNS = int(
    os.environ.get("SLIPBENCH_NULL_RUNS", "20")
)  # 100 or more: the full study, 999 resamples
NULL_CELLS = 280  # about the cells of a whole-paper run of one detector


@pytest.fixture(scope="module")
def runs(small_path, tmp_path_factory):
    """Holweg as shipped (BASE) and Holweg on a useless band (a degraded CANDIDATE)."""
    root = tmp_path_factory.mktemp("compare")
    (root / "plugins" / "protocols").mkdir(parents=True)
    (root / "plugins" / "protocols" / "two_cells.py").write_text(toys.source(toys.TwoCells))
    common = [
        "evaluate",
        "--detector",
        "holweg",
        "--protocol",
        "two-cells",
        "--dataset",
        str(small_path),
        "--plugins",
        str(root / "plugins"),
        "--quiet",
    ]
    for name, extra in (("base", []), ("degraded", ["--param", "band=[300,495]"])):
        with pytest.raises(SystemExit) as exit_:
            main([*common, "--out", str(root / name), *extra])
            raise SystemExit(0)
        assert (exit_.value.code or 0) == 0
    return root


def test_self_compare_reports_no_change(runs, cli):
    """An identical candidate: a comment of a few lines, not a table of +0.0 [+0.0, +0.0]."""
    code, out, _ = cli(["compare", str(runs / "base"), str(runs / "base" / "results.parquet")])
    assert code == 0
    assert "**Nothing changed.**" in out and "all 2 paired cells are identical" in out
    assert len(out.splitlines()) <= 8 and "+0.0 \\[+0.0, +0.0\\]" not in out
    doc = json.loads(to_json(compare(runs / "base", runs / "base")))
    assert doc["counts"]["identical"] == 2 and doc["pooled"] == [] and doc["exit_code"] == 0


def test_degraded_detector_is_named_and_undecided_on_one_seed(runs, cli, tmp_path):
    """One seed per side: the drop is named by figure, but retraining noise is not in the
    intervals, so the exit code is 6 (undecided), not 1; Markdown and JSON from one call."""
    comment, doc = tmp_path / "comment.md", tmp_path / "compare.json"
    code, out, _ = cli(
        ["compare", str(runs / "base"), str(runs / "degraded"), "--out", str(comment)]
        + ["--json", str(doc)]
    )
    assert code == EXIT_UNDECIDED
    assert "**Undecided** (exit 6)" in out and "on one seed per side" in out
    assert "accuracy in 2 cells (cell level)" in out
    assert "two-cells, holweg: accuracy" in out and "(pooled)" in out
    for finger in ("index", "middle"):
        assert f"Nano17 {finger.capitalize()} window 50" in out
    assert "paired" in out and comment.read_text() == out
    assert json.loads(doc.read_text())["exit_code"] == EXIT_UNDECIDED
    # the same drop is forgiven by tolerances wider than it
    wide = Gate.of(["accuracy", "tn_rate", "tp_rate"], accuracy=60, tn_rate=60, tp_rate=60)
    result = compare(runs / "base", runs / "degraded", wide)
    assert set(result.cells["verdict"]) == {"within margin"}


def test_cells_on_one_side_are_listed(tmp_path, cli):
    base = fake_rows("window-size", "holweg")
    cand = base[base["window"] != 5].copy()
    extra = base[base["window"] == 200].assign(
        cell=lambda f: f["cell"].str.replace("200", "400"),
        window=400,
        key=lambda f: f["key"] + "-400",
    )
    for name, rows in (("base", base), ("cand", pd.concat([cand, extra]))):
        (tmp_path / name).mkdir()
        rows.to_parquet(tmp_path / name / "results.parquet")
    code, out, _ = cli(["compare", str(tmp_path / "base"), str(tmp_path / "cand")])
    assert code == 0  # no predictions, the same keys and figures: identical, nothing changed
    assert "**Cells only in BASE** (8)" in out and "**Cells only in CANDIDATE** (8)" in out
    assert "- window-size, holweg: 8 cells" in out and "Nano17 Index window 5, split paper" in out
    assert "window 400" in out and "≡ identical: 40" in out


def test_unpaired_regression_without_predictions(tmp_path):
    for name, shift in (("base", 0.0), ("cand", -0.2)):
        (tmp_path / name).mkdir()
        fake_rows("speed-holdout", shift=shift).to_parquet(tmp_path / name / "results.parquet")
    result = compare(tmp_path / "base", tmp_path / "cand")
    assert (result.cells["verdict"] == "regressed").all()
    assert set(result.cells["regressed_figures"]) == {"accuracy, tp_rate, tn_rate"}
    assert result.exit_code == EXIT_UNDECIDED  # one seed per side
    assert result.cells["method"].str.startswith("unpaired").all()


def test_bad_input_exits_2(runs, tmp_path, cli):
    code, _, err = cli(["compare", str(runs / "base"), str(tmp_path / "missing")])
    assert code == 2 and "no results file here" in err
    (tmp_path / "junk.parquet").write_text("not parquet")
    code, _, err = cli(["compare", str(runs / "base"), str(tmp_path / "junk.parquet")])
    assert code == 2 and "not a readable results file" in err
    code, _, err = cli(["compare", str(runs / "base"), str(runs / "base"), "--figure", "tn_rate=0"])
    assert code == 2 and "a tolerance must be > 0" in err and "tn_rate = 0.0" in err
    code, _, err = cli(["compare", str(runs / "base"), str(runs / "base"), "--figure", "auroc"])
    assert code == 2 and "unknown figure auroc" in err
    code, _, _ = cli(["compare", str(runs / "base")])
    assert code == 2  # a usage error from click
    other = tmp_path / "other"
    other.mkdir()
    fingerprint = pd.read_parquet(runs / "base" / "results.parquet")["dataset_fingerprint"].iloc[0]
    fake_rows("cross-instance").assign(dataset_fingerprint=fingerprint).to_parquet(
        other / "results.parquet"
    )
    code, _, err = cli(["compare", str(runs / "base"), str(other)])
    assert code == 2 and "share no cell" in err
    rows = pd.read_parquet(runs / "base" / "results.parquet")
    # a file of its own: beside base's cells/ it would be refused as rows slipbench did not write
    pd.concat([rows, rows.assign(detector="other", key=rows["key"] + "-other")]).to_parquet(
        tmp_path / "two.parquet"
    )
    code, _, err = cli(["compare", str(other), str(tmp_path / "two.parquet")])
    assert code == 2 and "cannot pair detectors" in err


def _write(folder, rows: pd.DataFrame) -> None:
    folder.mkdir()
    rows.to_parquet(folder / "results.parquet")


def test_results_of_different_datasets_are_refused_first(tmp_path, cli):
    base = fake_rows("window-size")
    _write(tmp_path / "base", base)
    _write(
        tmp_path / "cand",
        fake_rows("window-size", detector="holweg").assign(dataset_fingerprint="beef"),
    )
    code, out, err = cli(["compare", str(tmp_path / "base"), str(tmp_path / "cand")])
    assert code == 2 and out == ""
    *said, error = err.splitlines()  # pandas wrote the files: each gets a line, without digests
    assert all("edits to them cannot be detected" in line for line in said)
    assert error.startswith("error: BASE and CANDIDATE were computed on different datasets")
    assert "f00d" in error


def test_repeated_keys_are_refused(tmp_path, cli):
    rows = fake_rows("speed-holdout")
    _write(tmp_path / "twice", pd.concat([rows, rows.iloc[:5]]))
    _write(tmp_path / "once", rows)
    code, _, err = cli(["compare", str(tmp_path / "once"), str(tmp_path / "twice")])
    assert code == 2 and "5 keys appear more than once (10 rows" in err
    with pytest.raises(DataError, match="RESULTS: 64 keys appear more than once"):
        check_unique_keys(pd.concat([rows, rows]), "RESULTS")  # `report A A`
    assert check_unique_keys(rows, "RESULTS") is rows


def test_a_cell_run_again_with_other_code_counts_once_the_latest(tmp_path, cli):
    """A folder that kept cells of older code beside their rerun (the key differs, nothing else):
    compare and report take the latest run of each and say how many they left out; an older
    row of another seed is a result of its own."""
    rows = fake_rows("speed-holdout").assign(finished_at="2026-11-01T10:00:00+00:00")
    older = rows.iloc[:5].assign(
        key=lambda f: f["key"] + "-old", finished_at="2026-10-01T10:00:00+00:00", accuracy=0.123
    )
    other_seed = older.iloc[:1].assign(key="other-seed", seed=1)
    _write(tmp_path / "kept", pd.concat([older, rows, other_seed]))
    _write(tmp_path / "clean", pd.concat([rows, other_seed]))
    assert latest_runs(pd.concat([older, rows, other_seed]))[1] == 5
    code, out, _ = cli(["compare", str(tmp_path / "clean"), str(tmp_path / "kept")])
    assert code == 0 and "all 64 paired cells are identical" in out  # the clean side's rows
    assert "CANDIDATE holds 5 earlier rows of a cell and seed run again later" in out
    code, out, _ = cli(["report", str(tmp_path / "kept")])
    assert code == 0 and "12.3" not in out
    assert re.search(r"Cells run again +\| 5 earlier rows of a cell and seed run again later", out)
    assert re.search(r"\| Cells +\| 65: 65 ok", out)


@pytest.mark.parametrize("status", ["failed", "timeout", "skipped"])
def test_a_cell_the_candidate_no_longer_finishes_is_a_regression(tmp_path, status):
    base = fake_rows("window-size")
    cand = base.assign(accuracy=base["accuracy"] + 0.001)  # changed, so in the family
    cand.loc[3, ["status", "reason"]] = [status, "whatever happened"]
    _write(tmp_path / "base", base)
    _write(tmp_path / "cand", cand)
    result = compare(tmp_path / "base", tmp_path / "cand")
    assert list(result.regressions["cell"]) == [base.loc[3, "cell"]] and result.exit_code == 1
    # the family counts the cells both sides finished
    assert result.level == pytest.approx(1 - 0.025 / (3 * (len(base) - 1)))  # 3 figures each


def test_family_level():
    assert family_level(280) == pytest.approx(1 - 0.05 / 280)
    assert family_level(280, CELL_ALPHA) == pytest.approx(1 - 0.025 / 280)


@pytest.mark.slow
def test_a_whole_paper_null_comparison_rarely_calls_a_regression():
    """Two equally good detectors that differ at random per recording (each its own
    detector-by-recording effect), compared over 280 cells of 10-40 recordings per class: the
    share of runs with any cell called regressed stays at or below 5 %, where per-cell 95 %
    intervals call one in nearly every run. CI runs 20 comparisons with 199 resamples per cell
    (a noisier standard error: a stricter test than the 999 compare uses); the full study
    (``SLIPBENCH_NULL_RUNS=100``) is quoted in slipbench/gate/compare.py."""
    rng = np.random.default_rng(11)
    level = family_level(NULL_CELLS)
    false_runs = false_runs_95 = 0
    for _ in range(NULL_RUNS):
        any_false = any_false_95 = False
        for cell in range(NULL_CELLS):
            d = dataset(rng, int(rng.choice((10, 20, 40))), float(rng.choice(TAUS)))
            out = paired_comparison(
                d["y"],
                d["base"] > 0,
                d["cand"] > 0,
                d["groups"],
                seed=cell,
                level=level,
                n_resamples=199 if NULL_RUNS < 100 else 999,
                figures=("accuracy",),
            )
            any_false |= out["d_accuracy_hi"] < 0  # its simultaneous interval below 0
            any_false_95 |= (
                out["d_accuracy"] + student_t.ppf(0.975, out["df"]) * out["d_accuracy_se"] < 0
            )
        false_runs += any_false
        false_runs_95 += any_false_95
    assert false_runs <= 0.05 * NULL_RUNS, false_runs
    assert false_runs_95 >= 0.9 * NULL_RUNS, false_runs_95


def _simulated_results(root, n_cells: int, shift: float) -> None:
    """BASE and CANDIDATE folders with rows and predictions of simulated cells; the candidate
    calls slip ``shift`` latent units later (fewer slip calls: a real but modest change)."""
    rng = np.random.default_rng(12)
    sides = {"base": [], "cand": []}
    for name in sides:
        (root / name / "predictions").mkdir(parents=True)
    for i in range(n_cells):
        d = dataset(rng, 20, 0.5)
        cell = json.dumps(
            {"sensor_type": "Nano17", "sensor_instance": "index", "window": i + 1}, sort_keys=True
        )
        for name, score in (("base", d["base"]), ("cand", d["cand"] - shift)):
            key = f"{name}{i:04d}"
            sides[name].append(
                {
                    "key": key,
                    "protocol": "window-size",
                    "detector": "holweg",
                    "split": "grouped",
                    "seed": 0,
                    "cell": cell,
                    "window": i + 1,
                    "status": "ok",
                    "reason": "",
                    "dataset_fingerprint": "f00d",
                    **classification_figures(d["y"], score > 0, d["groups"], seed=i, scores=score),
                }
            )
            pd.DataFrame(
                {
                    "recording_id": d["groups"].astype(str),
                    "window_index": np.arange(len(score)),
                    "y_true": d["y"].astype(np.int8),
                    "score": expit(score),
                }
            ).to_parquet(root / name / "predictions" / f"{key}.parquet")
    for name, rows in sides.items():
        pd.DataFrame(rows).to_parquet(root / name / "results.parquet")


@pytest.mark.slow
def test_the_unpaired_fallback_is_no_more_liberal_than_the_paired_path(tmp_path):
    _simulated_results(tmp_path, 40, shift=0.6)
    paired = compare(tmp_path / "base", tmp_path / "cand").cells
    shutil.rmtree(tmp_path / "cand" / "predictions")
    unpaired = compare(tmp_path / "base", tmp_path / "cand").cells
    assert paired["method"].str.startswith("paired over recordings").all()
    assert (unpaired["method"] == "unpaired").all()
    np.testing.assert_allclose(unpaired["d_accuracy"], paired["d_accuracy"])
    # Two detectors on the same windows err together, which only the paired path can see: the
    # unpaired interval is wider in nearly every cell (not all: its degrees of freedom come
    # from each side's own figure, not from the change's)
    ratio = (unpaired["d_accuracy_hi"] - unpaired["d_accuracy_lo"]) / (
        paired["d_accuracy_hi"] - paired["d_accuracy_lo"]
    )
    assert (ratio > 1).mean() >= 0.9 and ratio.median() > 1.2, ratio.describe()
    regressed = [int((c["verdict"] == "regressed").sum()) for c in (paired, unpaired)]
    assert regressed[1] <= regressed[0] and regressed[0] > 0, regressed


# ---------------------------------------------------------------- a comment sized for a pull request
@pytest.fixture(scope="module")
def whole_paper(tmp_path_factory):
    """A whole-paper comparison (1,405 cells) of files named relative to the working folder
    (computed once: its pooled bootstraps take most of a minute on 2 cores)."""
    root = tmp_path_factory.mktemp("whole")
    with pytest.MonkeyPatch.context() as patch:
        patch.chdir(root)
        return compare(*(p.name for p in whole_paper_pair(root)))


@pytest.mark.slow  # a whole paper's pooled bootstraps: a minute or more on 2 cores
def test_compare_summary_golden(whole_paper):
    """The verdict, the summary per protocol and detector, the 12 regressed cells, 60 others."""
    check_golden("compare.md", comment_markdown(whole_paper))


@pytest.mark.slow  # a whole paper's pooled bootstraps: a minute or more on 2 cores
def test_a_whole_paper_comparison_fits_a_pull_request_comment(whole_paper):
    text = comment_markdown(whole_paper)
    assert len(text) < 60_000
    rows = [
        line
        for line in text.splitlines()
        if re.search(r"(▼ regressed(: [^|]+)?|= no significant change) \|$", line)
        and not re.search(r"\| \d+ \(\d+\) +\|", line)  # a pooled test's line
    ]
    assert len(rows) == 12 + MAX_ROWS  # every regressed cell, then --max-rows others, each once
    assert len(set(rows)) == len(rows)
    assert f"_{1405 - 12 - MAX_ROWS} other cells not shown" in text
    assert "<details>" not in text
    assert len(comment_markdown(whole_paper, max_rows=0)) < len(text)


@pytest.mark.slow  # a whole paper's pooled bootstraps: a minute or more on 2 cores
def test_a_comment_with_every_cell_regressed_is_cut_and_says_so(tmp_path):
    base, cand = whole_paper_pair(tmp_path)
    worse = pd.read_parquet(cand)
    for col in [c for c in worse if c.startswith(("accuracy", "tp_rate", "tn_rate"))]:
        worse[col] -= 0.3
    worse.to_parquet(cand)
    result = compare(base, cand, Gate.of(["accuracy"]))  # one figure: a third of the bootstraps
    assert len(result.regressions) == 1400  # all but the 5 cells both sides skipped
    text = comment_markdown(result, max_rows=10_000)
    assert len(text) < COMMENT_LIMIT
    # a cell's mark names the figures it regressed in (a pooled line's does not)
    listed = text.count("▼ regressed: accuracy")
    assert len(result.pooled_regressions) == 25  # every protocol of every detector, pooled
    assert 100 < listed < 1400 and f"… and {1400 - listed} more regressed cells" in text
    assert "### Other cells" not in text  # regressed cells come first, whatever --max-rows says


@pytest.mark.slow  # a whole paper's pooled bootstraps: a minute or more on 2 cores
def test_json_holds_every_cell_for_bots(whole_paper):
    doc = json.loads(to_json(whole_paper))
    assert doc["verdict"] == "undecided" and doc["exit_code"] == EXIT_UNDECIDED  # one seed a side
    assert len(doc["cells"]) == 1405 and doc["counts"]["regressed"] == 12
    assert sum(s["cells"] for s in doc["summary"]) == 1405
    worst = next(
        s for s in doc["summary"] if s["protocol"] == "sampling-rate" and s["detector"] == "lstm"
    )
    assert worst["regressed"] == 12 and worst["worst_change"] < -13 and worst["worst_hi"] < 0
