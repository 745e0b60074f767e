"""Shared fixtures: small simulated datasets, generated once per test session."""

from __future__ import annotations

import os
import signal

import pytest

from slipbench.data.read import read_dataset
from slipbench.data.synth import synthesize


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist's own, which reads -n
def pytest_cmdline_main(config: pytest.Config) -> None:
    """A run that names no test (the whole suite or a tier, ``pytest -m "not slow"``) takes every
    core, as ``-n auto``; one that names files or folders stays in one process, where starting
    workers costs more than it saves. An explicit ``-n`` (``-n 0``) or ``-p no:xdist`` wins."""
    if (
        config.pluginmanager.has_plugin("xdist")
        and config.option.numprocesses is None
        and config.args_source == pytest.Config.ArgsSource.TESTPATHS
        and "PYTEST_XDIST_WORKER" not in os.environ  # a worker runs the items it is sent
    ):
        config.option.numprocesses = "auto"


@pytest.fixture(scope="session", autouse=True)
def _isolated_cache(tmp_path_factory):
    """Keep the default-dataset cache of the tests away from the user's, one for the whole run:
    pytest-xdist's workers share it (a dataset simulated by two at once is kept once, as
    ``default_dataset`` does for any two processes) rather than each simulating its own."""
    base = tmp_path_factory.getbasetemp()
    cache = (base.parent if "PYTEST_XDIST_WORKER" in os.environ else base) / "cache"
    cache.mkdir(exist_ok=True)
    mp = pytest.MonkeyPatch()
    mp.setenv("SLIPBENCH_CACHE", str(cache))
    yield
    mp.undo()


@pytest.fixture(scope="session", autouse=True)
def _ctrl_c_handled():
    """Python's Ctrl-C handler, as an interactive shell gives it: a suite started in the
    background of a script (``pytest &``) inherits SIGINT ignored, and the tests of Ctrl-C (an
    interrupt in this process, a signal to a child, which inherits the ignoring) would time out."""
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    yield


def _registries_restored():
    """Plugin folders registered meanwhile (``--plugins`` runs in-process here) are forgotten
    afterwards, as they are when a user's command ends."""
    from slipbench.engine import registry

    for r in (registry.detectors, registry.protocols):
        r.names()  # discover the entry points first: they stay
    saved = [
        (r, dict(r._sources), dict(r._loaded)) for r in (registry.detectors, registry.protocols)
    ]
    yield
    for r, sources, loaded in saved:
        r._sources, r._loaded = sources, loaded


# no test sees another's plugins: per test, and per module for the module-scoped fixtures that
# run in-process with --plugins (set up before any function-scoped fixture can save the state)
_fresh_registries = pytest.fixture(autouse=True)(_registries_restored)
_fresh_module_registries = pytest.fixture(autouse=True, scope="module")(_registries_restored)


@pytest.fixture
def cli(capsys):
    """Run ``slipbench`` in-process: ``cli(argv) -> (exit code, stdout, stderr)``."""
    from slipbench.app.cli import main

    def run(argv: list[str]) -> tuple[int, str, str]:
        with pytest.raises(SystemExit) as exit_:
            main(argv)
            raise SystemExit(0)
        out = capsys.readouterr()
        return exit_.value.code or 0, out.out, out.err

    return run


@pytest.fixture(scope="session")
def small_path(tmp_path_factory):
    """The simulated design at scale 0.02: every sensor, material and speed; ~1.2 M samples."""
    return synthesize(tmp_path_factory.mktemp("data") / "small", scale=0.02, seed=1)


@pytest.fixture(scope="session")
def small(small_path):
    return read_dataset(small_path)


@pytest.fixture(scope="session")
def unit(small, tmp_path_factory):
    """One sensor unit of the small simulation: a few seconds for holweg."""
    from datagen import subset

    from slipbench.data.write import write_dataset

    rec = small.recordings
    ds = subset(small, rec["sensor_type"].eq("OptoForce20") & rec["sensor_instance"].eq("index"))
    return write_dataset(
        tmp_path_factory.mktemp("data") / "unit", ds.recordings, ds.samples, ds.slip_labels
    )
