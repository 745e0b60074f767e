"""`slipbench compare`: no change against itself (exit 0), a degraded detector named (exit 1),
cells on one side listed, bad input refused (exit 2)."""

from __future__ import annotations

import shutil
import textwrap

import pandas as pd
import pytest
from resultgen import fake_rows

from slipbench.cli import main
from slipbench.compare import compare

PROTOCOL = '''
from slipbench.protocol import BaseProtocol, Cell, Layout, Part


class TwoCells(BaseProtocol):
    """Window 50 of two Nano17 fingers: the window-size protocol, cut down for speed."""

    layout = Layout("two cells", ("sensor_type", "sensor_instance"), "window")

    def cells(self, recordings):
        for finger in ("index", "middle"):
            part = (("Nano17", finger),)
            yield Cell(key={"sensor_type": "Nano17", "sensor_instance": finger, "window": 50},
                       train=Part(part, "train"), test=Part(part, "test"), window=50)
'''


@pytest.fixture(scope="module")
def runs(small_path, tmp_path_factory):
    """Holweg as shipped (BASE) and Holweg on a useless band (a degraded CANDIDATE)."""
    root = tmp_path_factory.mktemp("compare")
    (root / "plugins" / "protocols").mkdir(parents=True)
    (root / "plugins" / "protocols" / "two_cells.py").write_text(textwrap.dedent(PROTOCOL))
    common = ["evaluate", "--detector", "holweg", "--protocol", "two-cells", "--dataset", str(small_path),
              "--plugins", str(root / "plugins"), "--quiet"]
    for name, extra in (("base", []), ("degraded", ["--param", "band=[300,495]"])):
        with pytest.raises(SystemExit) as exit_:
            main([*common, "--out", str(root / name), *extra])
            raise SystemExit(0)
        assert (exit_.value.code or 0) == 0
    return root


def test_self_compare_reports_no_change(runs, cli):
    code, out, _ = cli(["compare", str(runs / "base"), str(runs / "base" / "results.parquet")])
    assert code == 0
    assert "**No regression**" in out and "▼ regressed: 0" in out and "= no significant change: 2" in out
    assert out.count("+0.0 [+0.0, +0.0]") == 6  # accuracy, TP and TN rate of both cells: exactly zero


def test_degraded_detector_exits_1_and_names_the_cells(runs, cli, tmp_path):
    comment = tmp_path / "comment.md"
    code, out, _ = cli(["compare", str(runs / "base"), str(runs / "degraded"), "--out", str(comment)])
    assert code == 1
    assert "**2 cells regressed**" in out
    for finger in ("index", "middle"):
        assert f"sensor_type=Nano17, sensor_instance={finger}, window=50" in out
    assert "paired" in out and comment.read_text() == out
    # the same drop is forgiven by a margin wider than it
    result = compare(runs / "base", runs / "degraded", margin=50)
    assert result.exit_code == 0 and set(result.cells["verdict"]) == {"within margin"}


def test_cells_on_one_side_are_listed(tmp_path, cli):
    base = fake_rows("window-size", "holweg")
    cand = base[base["window"] != 5].copy()
    extra = base[base["window"] == 200].assign(cell=lambda f: f["cell"].str.replace("200", "400"), window=400)
    for name, rows in (("base", base), ("cand", pd.concat([cand, extra]))):
        (tmp_path / name).mkdir()
        rows.to_parquet(tmp_path / name / "results.parquet")
    code, out, _ = cli(["compare", str(tmp_path / "base"), str(tmp_path / "cand")])
    assert code == 0  # no predictions: unpaired, and nothing changed
    assert "**Cells only in BASE** (8)" in out and "**Cells only in CANDIDATE** (8)" in out
    assert "sensor_type=Nano17, sensor_instance=index, window=5, split paper" in out
    assert "window=400" in out and "unpaired" in out


def test_unpaired_regression_without_predictions(tmp_path):
    for name, shift in (("base", 0.0), ("cand", -0.2)):
        (tmp_path / name).mkdir()
        fake_rows("speed-holdout", shift=shift).to_parquet(tmp_path / name / "results.parquet")
    result = compare(tmp_path / "base", tmp_path / "cand")
    assert result.exit_code == 1 and (result.cells["verdict"] == "regressed").all()
    assert (result.cells["method"] == "unpaired").all()


def test_a_failed_cell_is_a_regression(tmp_path):
    base = fake_rows("window-size")
    cand = base.copy()
    cand.loc[3, ["status", "reason"]] = ["failed", "detector 'lstm' raised: boom"]
    for name, rows in (("base", base), ("cand", cand)):
        (tmp_path / name).mkdir()
        rows.to_parquet(tmp_path / name / "results.parquet")
    result = compare(tmp_path / "base", tmp_path / "cand")
    assert list(result.regressions["cell"]) == [base.loc[3, "cell"]]


def test_bad_input_exits_2(runs, tmp_path, cli):
    code, _, err = cli(["compare", str(runs / "base"), str(tmp_path / "missing")])
    assert code == 2 and "no results file here" in err
    (tmp_path / "junk.parquet").write_text("not parquet")
    code, _, err = cli(["compare", str(runs / "base"), str(tmp_path / "junk.parquet")])
    assert code == 2 and "not a readable results file" in err
    code, _, err = cli(["compare", str(runs / "base"), str(runs / "base"), "--margin", "-1"])
    assert code == 2 and "--margin" in err
    code, _, _ = cli(["compare", str(runs / "base")])
    assert code == 2  # a usage error from click
    other = tmp_path / "other"
    other.mkdir()
    fake_rows("cross-instance").to_parquet(other / "results.parquet")
    code, _, err = cli(["compare", str(runs / "base"), str(other)])
    assert code == 2 and "share no cell" in err
    two = tmp_path / "two"
    shutil.copytree(runs / "base", two)
    rows = pd.read_parquet(two / "results.parquet")
    pd.concat([rows, rows.assign(detector="other")]).to_parquet(two / "results.parquet")
    code, _, err = cli(["compare", str(other), str(two / "results.parquet")])
    assert code == 2 and "cannot pair detectors" in err
