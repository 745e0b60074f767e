"""The first hour: an optional dependency not installed is a state, not a failure (aeon is not
installed in the test environment, so minirocket is really unavailable here), exit 3 lists the
cells that did not finish, and messages for the human (Ctrl-C, an unwritable cache, warnings)."""

from __future__ import annotations

import errno
import importlib.util
import textwrap
import warnings

import pandas as pd
import pytest
import toys

from slipbench.engine import registry

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("aeon") is not None, reason="aeon is installed: minirocket runs"
)
HINT = "pip install 'slipbench[minirocket]'"
FAST = ["--protocol-param", "windows=[50]", "--quiet"]


def _only(monkeypatch, *names: str) -> None:
    """Register only these built-in detectors: 'all' stays fast, minirocket's state stays real."""
    sources = registry.detectors._sources
    monkeypatch.setattr(registry.detectors, "_sources", {n: sources[n] for n in names})


def test_list_shows_minirocket_unavailable_with_its_hint(cli):
    code, text, _ = cli(["list"])
    line = next(li for li in text.splitlines() if li.strip().startswith("minirocket"))
    assert code == 0 and "unavailable" in line and "needs aeon" in line and HINT in line


def test_all_detectors_skip_an_unavailable_one_and_exit_0(monkeypatch, unit, tmp_path, cli):
    _only(monkeypatch, "holweg", "minirocket")
    out = tmp_path / "out"
    code, _, err = cli(
        ["evaluate", "--detector", "all", "--protocol", "window-size", "--dataset", str(unit)]
        + ["--out", str(out), *FAST]
    )
    assert code == 0, err
    skipped = [li for li in err.splitlines() if "minirocket" in li]
    assert len(skipped) == 1 and "skipped detector 'minirocket'" in skipped[0]
    assert HINT in skipped[0]
    rows = pd.read_parquet(out / "results.parquet")
    assert set(rows["detector"]) == {"holweg"} and (rows["status"] == "ok").all()


def test_a_named_unavailable_detector_is_refused_before_any_work(tmp_path, cli):
    out = tmp_path / "out"
    code, _, err = cli(
        ["evaluate", "--detector", "minirocket", "--protocol", "window-size", "--out", str(out)]
    )
    assert code == 3 and "detector 'minirocket' is unavailable here" in err and HINT in err
    assert "Traceback" not in err and not out.exists()
    code, _, err = cli(["bench", "--detector", "holweg", "--detector", "minirocket"])
    assert code == 3 and HINT in err and "timing" not in err  # not even holweg was timed


def test_bench_skips_an_unavailable_detector(monkeypatch, cli):
    _only(monkeypatch, "holweg", "minirocket")
    code, text, err = cli(["bench", "--windows", "20", "--length", "20", "--no-own-figures"])
    assert code == 0, err
    assert "skipped detector 'minirocket'" in err and HINT in err
    assert "timing holweg" in err and "holweg" in text and "minirocket" not in text


@pytest.mark.slow
def test_a_benchmark_file_skips_an_unavailable_detector(unit, tmp_path, cli):
    bench = tmp_path / "bench.toml"
    bench.write_text(
        textwrap.dedent(f"""\
        [benchmark]
        out = "res"
        [dataset]
        path = "{unit}"
        [detectors.holweg]
        [detectors.minirocket]
        [protocols.window-size]
        windows = [50]
        """)
    )
    code, text, err = cli(["run", str(bench), "--quiet"])
    assert code == 0, err
    assert "skipped detector 'minirocket'" in text and HINT in text
    assert set(pd.read_parquet(tmp_path / "res" / "results.parquet")["detector"]) == {"holweg"}
    only = bench.read_text().replace("[detectors.holweg]\n", "")
    bench.write_text(only)
    code, _, err = cli(["run", str(bench), "--quiet"])
    assert code == 3 and "every detector it declares is unavailable here" in err


@pytest.mark.slow
def test_exit_3_lists_the_cells_that_failed(monkeypatch, unit, tmp_path, cli):
    folder = tmp_path / "plugins"
    folder.mkdir()
    (folder / "broken.py").write_text("raise RuntimeError('boom')\n")
    # a file name other than the class's: the worker's message must name the id, 'garbage'
    (folder / "garbage.py").write_text(toys.source(toys.NanScores))
    _only(monkeypatch, "holweg")
    code, _, err = cli(
        ["evaluate", "--detector", "all", "--protocol", "window-size", "--dataset", str(unit)]
        + ["--plugins", str(folder), "--out", str(tmp_path / "out"), *FAST]
    )
    assert code == 3 and "detector 'broken'" in err and "the other plugins ran" in err
    assert "cells did not finish" in err and "window-size/garbage" in err
    assert "detector 'garbage'" in err and "non-finite scores" in err and "nan-scores" not in err


def test_ctrl_c_says_the_finished_cells_are_kept_and_how_to_resume(monkeypatch, cli):
    def interrupted(self):
        raise KeyboardInterrupt

    monkeypatch.setattr(registry.Registry, "names", interrupted)
    code, _, err = cli(["list"])
    assert code == 130 and "finished cells are kept" in err and "same command again" in err


def test_an_unwritable_cache_says_what_to_do(monkeypatch, tmp_path, cli):
    import slipbench.data.defaults as defaults

    def denied(path, scale, seed):
        raise PermissionError(errno.EACCES, "Permission denied", str(path))

    monkeypatch.setenv("SLIPBENCH_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(defaults, "synthesize", denied)
    code, _, err = cli(
        ["evaluate", "--detector", "holweg", "--protocol", "window-size", "--out", str(tmp_path)]
    )
    assert code == 5 and "permission denied" in err and "Traceback" not in err
    assert "SLIPBENCH_CACHE" in err and "XDG_CACHE_HOME" in err and "--dataset" in err


def test_a_warning_prints_as_one_line(monkeypatch, cli):
    def warned():
        warnings.warn("out/cells/3f.parquet: unreadable cell file", stacklevel=2)
        return ["holweg"]

    monkeypatch.setattr(registry.detectors, "names", warned)
    code, _, err = cli(["list"])
    lines = [li for li in err.splitlines() if "unreadable" in li]
    assert code == 0 and lines == ["warning: out/cells/3f.parquet: unreadable cell file"]
    assert "warnings.warn" not in err and "UserWarning" not in err
    assert warnings.showwarning.__name__ != "_one_line_warning"  # only inside the CLI's main
