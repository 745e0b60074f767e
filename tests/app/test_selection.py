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
