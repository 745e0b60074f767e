"""The results store and its keys: round trips, reading without results.parquet, rewriting only
on change, corrupt files refused with exit 2, canonical keys (one pinned), code identity, exit
codes, EnvironmentFault."""

from __future__ import annotations

import errno
import json
import os
import re
import shutil
import sys
import threading
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import toys
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from parquetfaults import name_not_utf8, name_twice

from slipbench import errors
from slipbench.base import BaseDetector
from slipbench.errors import CellsFailed, DataError, EnvironmentFault, environment_fault, writing
from slipbench.protocol import Part
from slipbench.store import keys
from slipbench.store import scan as scan_module
from slipbench.store.columns import COLUMNS
from slipbench.store.keys import KEY_SCHEMA, canonical, canonical_json, cell_key, code_identity
from slipbench.store.results import (
    RESULTS_FILE,
    ResultsStore,
    cells_failed,
    read_predictions,
    read_results,
)


def row(i: int, **extra) -> dict:
    """A cell row; extras the results schema does not declare are the protocol's own cell-key
    columns, which its ``cell`` column names (as a real protocol's rows do)."""
    own = {k: v for k, v in extra.items() if k not in COLUMNS}
    return {
        "key": f"k{i:04d}",
        "protocol": "window-size",
        "detector": "holweg",
        "status": "ok",
        "reason": "",
        "window": 5 * (i + 1),
        "accuracy": 0.5 + i / 800,
        "cell": json.dumps({"window": 5 * (i + 1), **own}, sort_keys=True),
        **extra,
    }


def stored(folder: Path, n: int, **extra) -> ResultsStore:
    store = ResultsStore(folder)
    for i in range(n):
        store.put(row(i, **extra), pd.DataFrame({"window_index": [0, 1], "score": [0.25, 0.75]}))
    return store


# ----------------------------------------------------------------------------- the store
scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(2**62), 2**62),
    st.floats(allow_nan=False, width=64),
    st.text(max_size=12),
)


@settings(
    max_examples=40,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(
    values=st.lists(
        st.fixed_dictionaries(
            {"x": scalars.filter(lambda v: not isinstance(v, bool)), "label": st.text(max_size=20)}
        ),
        min_size=1,
        max_size=6,
    )
)
def test_rows_round_trip_through_cells_and_results(values, tmp_path_factory):
    folder = tmp_path_factory.mktemp("rt")
    store = ResultsStore(folder)
    # one type per column across cells, as a plugin writes them
    kind = type(next((v["x"] for v in values if v["x"] is not None), None))
    rows = [
        row(i, x=v["x"] if v["x"] is None or isinstance(v["x"], kind) else None, label=v["label"])
        for i, v in enumerate(values)
    ]
    for r in rows:
        store.put(r)
    assert store.finished() == {r["key"]: r for r in rows}  # straight from cells/
    store.consolidate()
    back = {r["key"]: r for r in pq.read_table(folder / RESULTS_FILE).to_pylist()}
    assert back == {r["key"]: r for r in rows}
    assert store.finished() == back


def test_cells_this_store_wrote_are_not_read_back(tmp_path, monkeypatch):
    store = stored(tmp_path, 5)
    fresh = ResultsStore(tmp_path).finished()  # as another process reads them
    assert store.finished() == fresh
    calls = []
    monkeypatch.setattr(scan_module, "read_cell", lambda *a: calls.append(a))
    store.consolidate()
    assert calls == []
    back = {r["key"]: r for r in pq.read_table(tmp_path / RESULTS_FILE).to_pylist()}
    assert back == fresh


def test_a_cell_rewritten_by_another_process_is_read_again(tmp_path):
    store = stored(tmp_path, 2)
    ResultsStore(tmp_path).put(row(1, accuracy=0.25))  # another process, the same key
    assert store.finished()["k0001"]["accuracy"] == 0.25


def test_finished_cells_are_read_without_results_file(tmp_path):
    stored(tmp_path, 3)
    assert not (tmp_path / RESULTS_FILE).exists()
    rows = read_results(tmp_path)
    assert sorted(rows["key"]) == ["k0000", "k0001", "k0002"]
    assert rows.set_index("key").loc["k0002", "accuracy"] == 0.5025


def test_results_file_is_rewritten_only_when_a_row_changed(tmp_path):
    store = stored(tmp_path, 3)
    path = store.consolidate()
    before = path.stat()
    assert store.consolidate() == path
    assert (path.stat().st_ino, path.stat().st_mtime_ns) == (before.st_ino, before.st_mtime_ns)
    store.put(row(1, accuracy=0.99))  # a cell recomputed (--force)
    store.put(row(7))  # and a new one
    assert (
        read_results(tmp_path).set_index("key").loc["k0001", "accuracy"] == 0.99
    )  # before consolidating
    store.consolidate()
    after = pq.read_table(path).to_pandas().set_index("key")
    assert path.stat().st_ino != before.st_ino
    assert after.loc["k0001", "accuracy"] == 0.99 and "k0007" in after.index and len(after) == 4


def test_a_copied_folder_is_not_rewritten(tmp_path):
    """Copies get new inodes and times: rows are compared instead, so a read-only copy of a
    finished folder still reads and consolidates without writing."""
    stored(tmp_path / "a", 4).consolidate()
    shutil.copytree(tmp_path / "a", tmp_path / "b")
    before = (tmp_path / "b" / RESULTS_FILE).stat()
    ResultsStore(tmp_path / "b").consolidate()
    assert (tmp_path / "b" / RESULTS_FILE).stat().st_ino == before.st_ino


def test_protocols_with_different_cell_columns_consolidate_into_their_union(tmp_path):
    store = ResultsStore(tmp_path)
    store.put(row(0, material="PVC", training="with"))
    store.put(row(1, speed_mm_s=25.0))
    store.put(row(2, seed=3))
    store.consolidate()
    table = pq.read_table(tmp_path / RESULTS_FILE)
    assert {"material", "speed_mm_s", "seed"} <= set(table.column_names)
    assert table.schema.field("seed").type == pa.int64()  # an int column with gaps stays int
    assert store.finished()["k0002"]["seed"] == 3


def test_rows_that_disagree_on_a_column_type_name_it(tmp_path):
    store = ResultsStore(tmp_path)
    store.put(row(0, instance="index"))
    store.put(row(1, instance=3))
    with pytest.raises(DataError, match="column 'instance'"):
        store.consolidate()


def test_unfinished_writes_are_ignored(tmp_path):
    store = stored(tmp_path, 2)
    (tmp_path / "cells" / ".k0009.parquet.0123abcd.tmp").write_bytes(b"PAR1 half a file")
    assert sorted(store.finished()) == ["k0000", "k0001"]
    assert len(read_results(tmp_path)) == 2


def test_a_damaged_cell_is_recomputed_by_a_run_and_refused_by_a_report(tmp_path):
    store = stored(tmp_path, 3)
    bad = tmp_path / "cells" / "k0001.parquet"
    bad.write_bytes(bad.read_bytes()[:100])
    with pytest.warns(UserWarning, match="k0001.parquet: unreadable cell file"):
        assert sorted(store.finished()) == ["k0000", "k0002"]
    with pytest.raises(DataError, match="k0001.parquet"):
        read_results(tmp_path)


def write_cell(folder: Path, name: str, rows: list[dict]) -> None:
    (folder / "cells").mkdir(parents=True, exist_ok=True)
    pq.write_table(
        pa.Table.from_pylist(rows) if rows else pa.table({"key": pa.array([], pa.string())}),
        folder / "cells" / f"{name}.parquet",
    )


def corrupt_results(folder: Path, data: bytes) -> None:
    (folder / RESULTS_FILE).write_bytes(data)


def parquet_bytes(rows: list[dict]) -> bytes:
    return table_bytes(pa.Table.from_pylist(rows))


def table_bytes(table: pa.Table) -> bytes:
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink)
    return sink.getvalue().to_pybytes()


CORRUPTIONS = {
    "empty results file": lambda f: corrupt_results(f, b""),
    "results file of random bytes": lambda f: corrupt_results(
        f, np.random.default_rng(0).bytes(2000)
    ),
    "truncated results file": lambda f: corrupt_results(f, parquet_bytes([row(0)])[:-30]),
    "results file without its footer magic": lambda f: corrupt_results(
        f, parquet_bytes([row(0)])[:-4] + b"XXXX"
    ),
    "JSON instead of Parquet": lambda f: corrupt_results(f, json.dumps([row(0)]).encode()),
    "results file without a key column": lambda f: corrupt_results(
        f, parquet_bytes([{"protocol": "p", "detector": "d"}])
    ),
    "results file without a status column": lambda f: corrupt_results(
        f, parquet_bytes([{"key": "a", "protocol": "p", "detector": "d"}])
    ),
    "empty cell file": lambda f: write_cell(f, "k0000", []),
    "cell file of two rows": lambda f: write_cell(f, "k0000", [row(0), row(1)]),
    "cell file whose key is not its name": lambda f: write_cell(f, "k0000", [row(5)]),
    "cell file without a key": lambda f: write_cell(f, "k0000", [{"protocol": "p"}]),
    "truncated cell file": lambda f: (
        write_cell(f, "k0000", [row(0)]),
        (f / "cells" / "k0000.parquet").write_bytes(
            (f / "cells" / "k0000.parquet").read_bytes()[:50]
        ),
    ),
    "cell file that is a folder": lambda f: (f / "cells" / "k0000.parquet").mkdir(parents=True),
    "results file with a column name not UTF-8": lambda f: corrupt_results(
        f, name_not_utf8(parquet_bytes([row(0)]), "status")
    ),
    "results file naming a column twice": lambda f: corrupt_results(
        f, table_bytes(name_twice(pa.Table.from_pylist([row(0)]), 5, 6))
    ),
    "cell file with a column name not UTF-8": lambda f: (
        write_cell(f, "k0000", [row(0)]),
        (f / "cells" / "k0000.parquet").write_bytes(
            name_not_utf8((f / "cells" / "k0000.parquet").read_bytes(), "accuracy")
        ),
    ),
    "cell file naming a column twice": lambda f: (
        (f / "cells").mkdir(),
        (f / "cells" / "k0000.parquet").write_bytes(
            table_bytes(name_twice(pa.Table.from_pylist([row(0)]), 1, 4))
        ),
    ),
}


@pytest.mark.parametrize("kind", list(CORRUPTIONS))
def test_corrupt_results_are_refused_with_exit_2_naming_the_file(kind, tmp_path, cli):
    CORRUPTIONS[kind](tmp_path)
    with pytest.raises(DataError) as err:
        read_results(tmp_path)
    assert err.value.exit_code == 2
    assert str(tmp_path) in str(err.value)
    code, _, stderr = cli(["report", str(tmp_path)])
    assert code == 2 and "Traceback" not in stderr and str(tmp_path) in stderr


@pytest.mark.parametrize("fault", ["not UTF-8", "twice"])
def test_a_predictions_file_with_a_bad_column_name_is_refused_naming_it(fault, tmp_path):
    stored(tmp_path, 1)
    path = tmp_path / "predictions" / "k0000.parquet"
    if fault == "twice":
        path.write_bytes(table_bytes(name_twice(pq.read_table(path), 0, 1)))
        message = "columns 1 and 2 of 2 are both named 'window_index'"
    else:
        path.write_bytes(name_not_utf8(path.read_bytes(), "score"))
        message = "column 2 of 2 (after 'window_index'): its name is not valid UTF-8"
    with pytest.raises(DataError, match=re.escape(f"{path}: {message}")):
        read_predictions(tmp_path, "k0000")


def test_model_path_makes_its_folder(tmp_path):
    path = ResultsStore(tmp_path / "r").model_path("abc")
    assert path.parent.is_dir() and path.name == "abc.npz"


def test_cells_failed_groups_reasons_and_exits_4(tmp_path):
    store = ResultsStore(tmp_path)
    for i in range(6):
        status = ("failed", "timeout", "ok", "skipped")[min(i, 3)] if i < 4 else "failed"
        store.put(
            row(
                i,
                status=status,
                cell=json.dumps({"window": 5 * i}),
                reason={
                    "failed": "detector 'x' raised: ValueError: nan",
                    "timeout": "over 5 s",
                }.get(status, ""),
            )
        )
    err = cells_failed(read_results(tmp_path), str(tmp_path))
    assert isinstance(err, CellsFailed) and err.exit_code == 4 and len(err.cells) == 4
    text = str(err)
    assert text.startswith(
        f"4 of 6 cells did not finish (their rows, with status and reason, are in {tmp_path})"
    )
    assert (
        "  3 failed: detector 'x' raised: ValueError: nan [window-size/holweg {\"window\": 0};"
        in text
    )
    assert "  1 timeout: over 5 s" in text
    many = CellsFailed([(f"c{i}", "failed", "boom") for i in range(10)], total=10)
    assert str(many).endswith("[c0; c1; c2; and 7 more]")
    assert cells_failed(read_results(tmp_path).query("status in ['ok', 'skipped']")) is None


# ----------------------------------------------------------------------------- errors
def test_each_exit_code_means_one_thing():
    codes = {
        errors.UsageError: 2,
        errors.DataError: 2,
        errors.PluginError: 3,
        errors.CellsFailed: 4,
        errors.EnvironmentFault: 5,
    }
    assert {c: c.exit_code for c in codes} == codes
    assert (
        errors.EXIT_OK,
        errors.EXIT_REGRESSION,
        errors.EXIT_USAGE,
        errors.EXIT_PLUGIN,
        errors.EXIT_CELLS_FAILED,
        errors.EXIT_ENVIRONMENT,
    ) == (0, 1, 2, 3, 4, 5)


@pytest.mark.parametrize(
    "code,cause",
    [
        (errno.ENOSPC, "no space left on device (ENOSPC)"),
        (errno.EROFS, "read-only file system (EROFS)"),
        (errno.EACCES, "permission denied (EACCES)"),
        (errno.EPERM, "operation not permitted (EPERM)"),
        (errno.EDQUOT, "disk quota exceeded (EDQUOT)"),
    ],
)
def test_environment_oserrors_become_one_line_faults(code, cause):
    fault = environment_fault(OSError(code, os.strerror(code), "/x/.tmp123"), "/x/cell.parquet")
    assert isinstance(fault, EnvironmentFault) and fault.exit_code == 5
    assert str(fault) == f"cannot write /x/cell.parquet: {cause}" and "\n" not in str(fault)


def test_errors_cross_process_boundaries_whole():
    import pickle

    fault = EnvironmentFault("/x/cell.parquet", "no space left on device (ENOSPC)")
    failed = CellsFailed([("p/d {}", "failed", "boom")], total=3, where="out")
    for err in (fault, failed):
        back = pickle.loads(pickle.dumps(err))
        assert type(back) is type(err) and str(back) == str(err) and back.exit_code == err.exit_code


def test_other_oserrors_pass_through_unchanged():
    original = OSError(errno.EBADF, "bad file descriptor")
    with pytest.raises(OSError) as err:
        with writing("/x/y"):
            raise original
    assert err.value is original and not isinstance(err.value, EnvironmentFault)
    with pytest.raises(EnvironmentFault, match="cannot write /x/y: no space left"):
        with writing("/x/y"):
            raise OSError(errno.ENOSPC, "No space left on device")


# ----------------------------------------------------------------------------- keys
def test_one_key_is_pinned():
    """Changing this value invalidates every cached cell of every user: bump KEY_SCHEMA instead
    of editing the canonical form, and update the value here deliberately."""
    fields = {
        "dataset": "0f3c",
        "detector": "holweg",
        "params": {"band": (300, 495), "threshold": 0.5},
        "cell": {"sensor_type": "Nano17", "speed_mm_s": np.float64(25.0)},
        "train": Part((("Nano17", "index"),), "train", (("material", "!=", np.str_("PVC")),)),
        "seed": np.int64(0),
    }
    assert canonical_json(fields) == (
        '{"fields":{"cell":{"sensor_type":"Nano17","speed_mm_s":25},"dataset":"0f3c","detector":"holweg",'
        '"params":{"band":[300,495],"threshold":0.5},"seed":0,"train":{"sensors":[["Nano17","index"]],'
        '"side":"train","where":[["material","!=","PVC"]]}},"schema":1}'
    )
    assert KEY_SCHEMA == 1
    assert cell_key(fields) == "eb7afa984081c4853102"


def test_equal_meanings_give_equal_keys():
    assert (
        cell_key({"v": np.float64(25.0)})
        == cell_key({"v": 25})
        == cell_key({"v": 25.0})
        == cell_key({"v": np.int32(25)})
    )
    assert (
        cell_key({"v": (1, 2.0)})
        == cell_key({"v": [1, 2]})
        == cell_key({"v": np.array([1.0, 2.0])})
    )
    assert cell_key({"v": np.str_("a"), "b": np.bool_(True)}) == cell_key({"v": "a", "b": True})
    assert cell_key({"v": -0.0}) == cell_key({"v": 0})
    assert cell_key({"v": 0.1}) != cell_key(
        {"v": 0.1 + 1e-16 * 2}
    )  # a different float is a different key
    assert cell_key({"v": True}) != cell_key({"v": 1})
    assert cell_key({"v": "25"}) != cell_key({"v": 25})
    assert cell_key({"v": float("inf")}) != cell_key({"v": "inf"})
    assert canonical(float("nan")) == {"__float__": "nan"}


@pytest.mark.parametrize(
    "value",
    [{1, 2}, Path("/tmp"), object(), b"bytes", pd.Timestamp(0), {1: "a"}, np.array(["a"]), 1 + 2j],
)
def test_values_without_one_plain_spelling_are_refused(value):
    with pytest.raises(TypeError, match=r"key\.params"):
        cell_key({"params": value})


json_values = st.recursive(
    st.one_of(
        st.none(),
        st.booleans(),
        st.integers(-(2**53), 2**53),
        st.floats(allow_nan=False),
        st.text(max_size=8),
    ),
    lambda children: st.one_of(
        st.lists(children, max_size=4), st.dictionaries(st.text(max_size=6), children, max_size=4)
    ),
    max_leaves=20,
)


def numpyfied(value):
    """The same value as NumPy would hand it over: NumPy scalars, tuples and arrays."""
    if isinstance(value, bool):
        return np.bool_(value)
    if isinstance(value, int):
        return np.int64(value)
    if isinstance(value, float):
        return np.float64(value)
    if isinstance(value, str):
        return np.str_(value)
    if isinstance(value, list):
        if value and all(isinstance(v, float) and not isinstance(v, bool) for v in value):
            return np.array(value)
        return tuple(numpyfied(v) for v in value)
    if isinstance(value, dict):
        return {k: numpyfied(v) for k, v in value.items()}
    return value


@settings(max_examples=200, deadline=None, derandomize=True)
@given(json_values)
def test_numpy_spellings_do_not_change_a_key(value):
    assert cell_key({"v": numpyfied(value)}) == cell_key({"v": value})
    text = canonical_json({"v": value})
    assert json.loads(text)["fields"]["v"] == canonical(value)  # the key text is plain JSON


# ----------------------------------------------------------------------------- code identity
def test_slipbench_and_its_built_in_plugins_share_one_identity():
    import slipbench
    from slipbench.engine.registry import detectors, protocols

    ident = code_identity(slipbench)
    assert ident.startswith("src:") and len(ident) == 36
    assert (
        code_identity(BaseDetector)
        == code_identity(detectors.get("holweg"))
        == code_identity(protocols.get("window-size"))
        == ident
    )
    labels = [label for label, _ in keys._source_files("slipbench")]
    assert {
        "slipbench.store/keys.py",  # a subpackage's files count too
        "slipbench.detectors/holweg.py",
        "slipbench.protocols/window_size.py",
    } <= set(labels)
    assert not any("__pycache__" in label for label in labels)


def load_plugin(folder: Path, name: str):
    import importlib

    sys.path.insert(0, str(folder))
    try:
        top = name.split(".")[0]
        for mod in [m for m in sys.modules if m == top or m.startswith(top + ".")]:
            del sys.modules[mod]
        importlib.invalidate_caches()
        return importlib.import_module(name)
    finally:
        sys.path.remove(str(folder))


# a plugin package: the detector module imports a helper of its package
PLUGIN = toys.source(toys.Energy) + "\nfrom .helper import THRESHOLD  # noqa: F401\n"


def test_a_changed_plugin_changes_its_identity(tmp_path):
    """A plugin package: editing any of its files (not only the class's own) changes the
    identity; the same files elsewhere have the same identity."""
    for where in ("a", "b"):
        pkg = tmp_path / where / "plugpkg"
        pkg.mkdir(parents=True)
        (pkg / "__init__.py").write_text("")
        (pkg / "det.py").write_text(PLUGIN)
        (pkg / "helper.py").write_text("THRESHOLD = 0.5\n")
    keys._unit_identity.cache_clear()
    first = code_identity(load_plugin(tmp_path / "a", "plugpkg.det").Energy)
    keys._unit_identity.cache_clear()
    assert (
        code_identity(load_plugin(tmp_path / "b", "plugpkg.det").Energy) == first
    )  # same code, elsewhere
    (tmp_path / "b" / "plugpkg" / "helper.py").write_text("THRESHOLD = 0.6\n")
    keys._unit_identity.cache_clear()
    changed = code_identity(load_plugin(tmp_path / "b", "plugpkg.det").Energy)
    assert changed.startswith("src:") and changed != first
    assert changed != code_identity(BaseDetector)
    for mod in [m for m in sys.modules if m.startswith("plugpkg")]:
        del sys.modules[mod]


def test_a_single_file_plugin_is_hashed_alone(tmp_path):
    (tmp_path / "lonely_plugin.py").write_text("class Lonely:\n    pass\n")
    keys._unit_identity.cache_clear()
    first = code_identity(load_plugin(tmp_path, "lonely_plugin").Lonely)
    (tmp_path / "lonely_plugin.py").write_text("class Lonely:\n    x = 1\n")
    keys._unit_identity.cache_clear()
    assert code_identity(load_plugin(tmp_path, "lonely_plugin").Lonely) != first
    del sys.modules["lonely_plugin"]


def test_code_without_source_falls_back_to_its_distribution_or_this_process(monkeypatch):
    import types

    module = types.ModuleType("sourceless_plugin")  # as typed into a REPL: no __file__
    exec("class Typed:\n    pass\n", module.__dict__)
    monkeypatch.setitem(sys.modules, "sourceless_plugin", module)
    keys._unit_identity.cache_clear()
    assert code_identity(module.Typed) == keys._PROCESS_NONCE and keys._PROCESS_NONCE.startswith(
        "process:"
    )
    monkeypatch.setattr(keys, "packages_distributions", lambda: {"sourceless_plugin": ["numpy"]})
    keys._unit_identity.cache_clear()
    assert code_identity(module.Typed) == f"dist:numpy=={np.__version__}"
    keys._unit_identity.cache_clear()


def test_code_identity_is_cached_per_process(monkeypatch):
    import slipbench

    first = code_identity(slipbench)

    def no_reading(self):
        raise AssertionError(f"read {self} again")

    monkeypatch.setattr(Path, "read_bytes", no_reading)
    assert code_identity(slipbench) == first
    with pytest.raises(TypeError, match="a class or a module"):
        code_identity(3)


# ----------------------------------------------------------------------------- models
class Saved(BaseDetector):
    name = "saved"

    def __init__(self, scale: float = 1.0):
        self.scale = scale

    def _fit(self, x, y, seed):
        self.mean_ = x.mean(axis=0) * self.scale

    def _predict_proba(self, x):
        return np.full(len(x), 0.5)


def test_models_saved_at_once_to_one_path_stay_whole(tmp_path):
    """Two savers of one model key (two runs) used to share the fixed name ``path.tmp``."""
    rng = np.random.default_rng(0)
    x, y = rng.normal(size=(40, 400)), np.repeat([0, 1], 20)
    detectors = [Saved(scale=s).fit(x, y, sampling_rate=1000.0, seed=0) for s in (1.0, 2.0)]
    path = tmp_path / "models" / "m.npz"
    path.parent.mkdir()
    threads = [
        threading.Thread(target=lambda d=d: [d.save(path) for _ in range(20)]) for d in detectors
    ]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    loaded = Saved.load(path)
    assert any(np.array_equal(loaded.mean_, d.mean_) for d in detectors)
    assert [p.name for p in path.parent.iterdir()] == ["m.npz"]
