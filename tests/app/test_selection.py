"""Several detectors and protocols in one `evaluate`: a repeated option runs each value, and a
value may be a comma list (before, a repeated --detector silently kept only its last value)."""

from __future__ import annotations

import pandas as pd
import pytest

from slipbench.errors import UsageError

FAST = ["--protocol-param", "windows=[50]", "--quiet"]


@pytest.mark.slow
@pytest.mark.parametrize(
    "options",
    [
        ["--detector", "holweg", "--detector", "bandpass"],
        ["--detector", "holweg,bandpass"],
        ["--detector", "bandpass, holweg", "--detector", "holweg"],  # each once
    ],
)
def test_every_named_detector_runs(unit, tmp_path, cli, options):
    out = tmp_path / "out"
    argv = ["evaluate", *options, "--protocol", "window-size", "--dataset", str(unit)]
    code, _, err = cli(argv + ["--out", str(out), *FAST])
    assert code == 0, err
    rows = pd.read_parquet(out / "results.parquet")
    assert sorted(rows["detector"].unique()) == ["bandpass", "holweg"]
    assert len(rows) == 2  # one window-size cell of one unit, per detector


@pytest.mark.slow
def test_repeated_protocols_run_each(unit, tmp_path, cli):
    out = tmp_path / "out"
    argv = ["evaluate", "--detector", "holweg", "--protocol", "window-size,cross-instance"]
    code, _, err = cli(argv + ["--dataset", str(unit), "--out", str(out), "--quiet"])
    assert code == 0, err
    rows = pd.read_parquet(out / "results.parquet")
    assert set(rows["protocol"]) == {"window-size", "cross-instance"}


def test_an_empty_list_is_refused():
    from slipbench.app.selection import select_plugins
    from slipbench.engine import registry

    with pytest.raises(UsageError, match="no detector named"):
        select_plugins(registry.detectors, [" , "], [])


def test_all_names_each_plugin_it_selects_and_where_it_comes_from(tmp_path):
    """What 'all' means depends on what is installed: one line per selected plugin says which
    and where from (built in, a package and version, or a plugin file); a named one says nothing."""
    import toys

    import slipbench
    from slipbench.app.selection import add_plugin_folders, select_plugins
    from slipbench.engine import registry

    (tmp_path / "protocols").mkdir()
    (tmp_path / "detectors").mkdir()
    (tmp_path / "protocols" / "two_cells.py").write_text(toys.source(toys.TwoCells))
    add_plugin_folders((str(tmp_path),))
    lines: list[str] = []
    chosen = select_plugins(registry.protocols, ("all",), [], lines.append)
    assert len(lines) == len(chosen) and set(chosen) >= {"window-size", "two-cells"}
    built_in = f"all: protocol 'window-size' from built in (slipbench {slipbench.__version__})"
    assert built_in in lines
    plugin_file = tmp_path / "protocols" / "two_cells.py"
    assert f"all: protocol 'two-cells' from plugin file {plugin_file}" in lines
    lines.clear()
    select_plugins(registry.protocols, ("window-size",), [], lines.append)
    assert lines == []


@pytest.mark.parametrize(
    "option, typo, suggestion",
    [("--detector", "holwge", "holweg"), ("--protocol", "windowsize", "window-size")],
)
def test_a_misspelt_id_is_refused_with_the_closest_ids(cli, option, typo, suggestion):
    argv = ["evaluate", "--detector", "holweg", "--protocol", "window-size", option, typo]
    code, _, err = cli(argv)
    kind = option.removeprefix("--")
    assert code == 2
    assert f"unknown {kind} {typo!r} (did you mean {suggestion!r}?); available: " in err


def test_an_unknown_id_after_a_known_one_imports_no_plugin():
    """Every id is checked before any plugin is imported: the error comes first, however late."""
    from slipbench.app.selection import select_plugins
    from slipbench.base import BaseDetector
    from slipbench.engine.registry import Registry

    reg = Registry("detector", BaseDetector, "slipbench.detectors")
    with pytest.raises(UsageError, match="unknown detector 'nope'; available: bandpass"):
        select_plugins(reg, ["holweg,nope"], [])
    assert not reg._loaded


@pytest.mark.parametrize("option", ["--param", "--protocol-param"])
def test_a_bad_name_value_item_names_its_own_option(cli, option):
    code, _, err = cli(
        ["evaluate", "--detector", "holweg", "--protocol", "window-size", option, "x"]
    )
    assert code == 2 and f"error: {option} 'x': expected NAME=VALUE, e.g. {option} " in err


def test_list_shows_each_plugins_first_sentence_as_plain_text(cli):
    from slipbench.engine.registry import detectors, protocols, summary

    code, text, _ = cli(["list"])
    assert code == 0 and "``" not in text
    for reg in (detectors, protocols):
        for name in reg.names():
            description = reg.describe(name)["description"]
            assert description == "" or description.endswith((".", ")")), (name, description)
    assert detectors.describe("tcn")["description"].startswith("A temporal convolutional network")
    doc = """Uses :func:`~a.b` and ``x``, e.g. over
    two lines. A second sentence.

    A second paragraph."""
    assert summary(doc) == "Uses a.b and x, e.g. over two lines."
    assert summary("Log energy. ``band``: a pair.") == "Log energy."
