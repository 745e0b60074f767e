"""Faults the results store survives: kill -9 at random moments, a full disk (injected, a file
size limit, a real small tmpfs), a read-only folder, two writers on one folder, a lock held by a
hung process, and the umask of shared folders."""

from __future__ import annotations

import errno
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
import storegen
import toys
from fsfaults import mounted, read_only
from storegen import cell_predictions, cell_row

from slipbench.atomic import folder_lock, unique_folder, write_text_atomic
from slipbench.base import BaseDetector
from slipbench.errors import EnvironmentFault
from slipbench.store.results import RESULTS_FILE, ResultsStore, read_results

WRITER = storegen.__file__


def writer(folder: Path, n: int, every: int, prefix: str = "c") -> subprocess.Popen:
    # from outside the source tree, so that `slipbench` is the installed package
    return subprocess.Popen(
        [sys.executable, WRITER, str(folder), str(n), str(every), prefix],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=folder.parent,
    )


def leftovers(folder: Path) -> list[Path]:
    return [p for p in folder.rglob(".*.tmp")]


def check_intact(
    folder: Path, prefix: str = "c", size=lambda i: 3000, checked: frozenset = frozenset()
) -> set[str]:
    """Every finished cell reads back exactly as written, with its predictions (but those of
    ``checked`` cells); returns the keys."""
    rows = read_results(folder)
    assert rows["key"].is_unique
    for r in rows.to_dict("records"):
        i = int(r["key"][len(prefix) :])
        expected = cell_row(prefix, i)
        assert {k: r[k] for k in expected} == expected
        if r["key"] in checked:
            continue
        predictions = pd.read_parquet(folder / "predictions" / f"{r['key']}.parquet")
        pd.testing.assert_frame_equal(predictions, cell_predictions(i, size(i)))
    return set(rows["key"])


@pytest.mark.slow
def test_kill_9_at_random_moments_then_resume(tmp_path):
    """A writer killed by SIGKILL at seeded random moments (mid-put, mid-consolidate, anywhere)
    leaves every finished cell whole and readable; resuming completes the rest."""
    folder, n = tmp_path / "out", 600  # enough that six kills of up to 0.5 s never see it finish
    rng = np.random.default_rng(20240611)
    counts, checked = [], frozenset()
    for _ in range(6):
        proc = writer(folder, n, every=9)
        assert proc.stdout.readline().strip() == "ready", proc.stderr.read()
        time.sleep(rng.uniform(0.05, 0.5))
        proc.kill()
        proc.communicate()
        if (folder / "cells").is_dir():
            checked = frozenset(check_intact(folder, checked=checked))
        counts.append(len(checked))
    assert counts[-1] > 0 and counts == sorted(counts), counts
    assert counts[-1] < n, "the writer finished before any kill; give it more cells"
    done = subprocess.run(
        [sys.executable, WRITER, str(folder), str(n), "9", "c"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stderr
    assert check_intact(folder, checked=checked) == {cell_row("c", i)["key"] for i in range(n)}
    assert pq.read_table(folder / RESULTS_FILE).num_rows == n  # consolidated, every row once
    # killed writes leave hidden temporaries at most, never a visible partial file
    assert all(p.name.startswith(".") for p in leftovers(folder))


# ----------------------------------------------------------------------------- disk full
@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full (Linux)")
def test_disk_full_injected_gives_environment_fault_and_no_partial_file(tmp_path, monkeypatch):
    store = ResultsStore(tmp_path)
    store.put(cell_row("c", 0), cell_predictions(0))
    cell = tmp_path / "cells" / "c00000.parquet"
    before = cell.read_bytes()

    real_open = os.open

    def full_disk(path, flags, mode=0o777, *args, **kwargs):
        fd = real_open(path, flags, mode, *args, **kwargs)
        if flags & os.O_CREAT:
            os.write(
                fd, b"PAR1" + bytes(4096)
            )  # part of the file reaches the disk, then it is full:
            full = real_open("/dev/full", os.O_WRONLY)  # every later write fails with ENOSPC
            os.dup2(full, fd)
            os.close(full)
        return fd

    monkeypatch.setattr(os, "open", full_disk)
    with pytest.raises(EnvironmentFault) as err:
        store.put({**cell_row("c", 0), "accuracy": 1.0})
    assert err.value.exit_code == 5
    assert str(err.value) == f"cannot write {cell}: no space left on device (ENOSPC)"
    assert cell.read_bytes() == before and not leftovers(tmp_path)
    monkeypatch.undo()

    def fsync_fails(fd):  # NFS and thin-provisioned disks report a full disk only here
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "fsync", fsync_fails)
    with pytest.raises(EnvironmentFault, match="no space left on device"):
        store.put(cell_row("c", 1), cell_predictions(1))
    with pytest.raises(
        EnvironmentFault, match=re.escape(f"cannot write {tmp_path / RESULTS_FILE}: no space")
    ):
        store.consolidate()
    monkeypatch.undo()
    assert not leftovers(tmp_path) and not (tmp_path / RESULTS_FILE).exists()
    assert check_intact(tmp_path) == {"c00000"}


FSIZE = """
import resource, signal, sys
from storegen import cell_predictions, cell_row
from slipbench.errors import SlipbenchError
from slipbench.store.results import ResultsStore

signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # the kernel then fails the write with EFBIG
resource.setrlimit(resource.RLIMIT_FSIZE, (200_000, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))
store = ResultsStore(sys.argv[1])
try:
    for i in range(100):
        store.put(cell_row("c", i), cell_predictions(i, n=1000 * (i + 1)))
except SlipbenchError as exc:
    print(f"error: {exc}", file=sys.stderr)
    sys.exit(exc.exit_code)
"""


def test_a_file_size_limit_is_an_environment_fault(tmp_path):
    """A real kernel write failure mid-file, without root: RLIMIT_FSIZE (EFBIG)."""
    folder = tmp_path / "out"
    done = subprocess.run(
        [sys.executable, "-c", FSIZE, str(folder)],
        capture_output=True,
        text=True,
        cwd=Path(WRITER).parent,
    )
    assert done.returncode == 5, done.stderr
    line = done.stderr.strip()
    assert "\n" not in line and "Traceback" not in line
    assert line.startswith(f"error: cannot write {folder / 'predictions'}/c000") and line.endswith(
        "(EFBIG)"
    )
    assert not leftovers(folder)
    assert 0 < len(check_intact(folder, size=lambda i: 1000 * (i + 1))) < 100


def test_a_real_full_disk(tmp_path):
    with mounted(tmp_path / "small", "-t", "tmpfs", "-o", "size=1m") as folder:
        store = ResultsStore(folder / "out")
        with pytest.raises(EnvironmentFault, match=r"no space left on device \(ENOSPC\)"):
            for i in range(1000):
                store.put(cell_row("c", i), cell_predictions(i))
        assert not leftovers(folder)
        finished = check_intact(folder / "out")
        assert 0 < len(finished) < 1000
        try:
            store.consolidate()
        except EnvironmentFault as exc:
            assert "no space left on device" in str(exc)
        if (folder / "out" / RESULTS_FILE).exists():  # whole, if it fitted
            assert set(pq.read_table(folder / "out" / RESULTS_FILE)["key"].to_pylist()) == finished
        assert not leftovers(folder)


# ----------------------------------------------------------------------------- read-only


class Tiny(BaseDetector):
    name = "tiny"

    def __init__(self):
        pass

    def _fit(self, x, y, seed):
        self.mean_ = x.mean(axis=0)

    def _predict_proba(self, x):
        return np.full(len(x), 0.5)


def tiny() -> Tiny:
    rng = np.random.default_rng(0)
    return Tiny().fit(
        rng.normal(size=(20, 50)), np.repeat([0, 1], 10), sampling_rate=1000.0, seed=0
    )


def test_a_read_only_folder_reads_and_refuses_writes_with_exit_5(tmp_path):
    store = ResultsStore(tmp_path / "done")
    for i in range(3):
        store.put(cell_row("c", i), cell_predictions(i))
    store.consolidate()
    store.model_path("m")
    pending = ResultsStore(tmp_path / "pending")  # a killed run: a cell results.parquet lacks
    pending.put(cell_row("c", 0), cell_predictions(0))
    pending.consolidate()
    pending.put(cell_row("c", 1), cell_predictions(1))
    with read_only(tmp_path / "done") as done, read_only(tmp_path / "pending") as late:
        assert check_intact(done) == {"c00000", "c00001", "c00002"}
        assert ResultsStore(done).consolidate() == done / RESULTS_FILE  # nothing changed: no write
        assert sorted(ResultsStore(done).finished()) == ["c00000", "c00001", "c00002"]
        assert ResultsStore(done).model_path("m") == done / "models" / "m.npz"
        cause = (
            "read-only file system (EROFS)" if os.geteuid() == 0 else "permission denied (EACCES)"
        )
        with pytest.raises(EnvironmentFault) as err:
            ResultsStore(done).put(cell_row("c", 3), cell_predictions(3))
        assert str(err.value) == f"cannot write {done / 'predictions' / 'c00003.parquet'}: {cause}"
        with pytest.raises(
            EnvironmentFault, match=re.escape(f"cannot write {done / 'models' / 'm.npz'}: {cause}")
        ):
            tiny().save(done / "models" / "m.npz")
        assert check_intact(late) == {"c00000", "c00001"}  # read straight from cells/
        with pytest.raises(
            EnvironmentFault, match=re.escape(f"cannot lock {late / '.lock'}: {cause}")
        ):
            ResultsStore(late).consolidate()


@pytest.mark.slow
def test_a_cached_rerun_works_on_a_read_only_folder_and_a_new_one_exits_5(small_path, tmp_path):
    (tmp_path / "plugins" / "protocols").mkdir(parents=True)
    (tmp_path / "plugins" / "protocols" / "two_cells.py").write_text(toys.source(toys.TwoCells))

    def evaluate(out: Path, *more: str) -> subprocess.CompletedProcess:
        return subprocess.run(
            [
                sys.executable,
                "-m",
                "slipbench.app.cli",
                "evaluate",
                "--detector",
                "holweg",
                "--protocol",
                "two-cells",
                "--dataset",
                str(small_path),
                "--plugins",
                str(tmp_path / "plugins"),
                "--out",
                str(out),
                "--quiet",
                *more,
            ],
            capture_output=True,
            text=True,
            cwd=tmp_path,
        )

    first = evaluate(tmp_path / "out")
    assert first.returncode == 0, first.stderr
    (tmp_path / "empty").mkdir()
    with read_only(tmp_path / "out") as out, read_only(tmp_path / "empty") as empty:
        again = evaluate(out)
        assert again.returncode == 0, again.stderr
        assert len(read_results(out)) == 2 and (read_results(out)["status"] == "ok").all()
        new = evaluate(empty)  # cells to compute, nowhere to put them: exit 5, one line
        cause = (
            "read-only file system (EROFS)" if os.geteuid() == 0 else "permission denied (EACCES)"
        )
        assert new.returncode == 5, new.stderr
        assert new.stderr == (  # refused as --out was read, before the dataset
            f"error: cannot write {empty}: {cause}; found before any work; nothing was written\n"
        )
        before = (out / RESULTS_FILE).stat().st_mtime_ns
        more = evaluate(out, "--seed", "1")  # cells stored, but new ones due: refused by the run
        assert more.returncode == 5 and more.stderr == new.stderr.replace(str(empty), str(out))
        assert (out / RESULTS_FILE).stat().st_mtime_ns == before


# ----------------------------------------------------------------------------- two writers, the lock
@pytest.mark.slow
def test_two_writers_on_one_folder_lose_no_row(tmp_path):
    folder, n = tmp_path / "out", 60
    procs = [writer(folder, n, every=1, prefix=p) for p in ("a", "b")]
    for proc in procs:
        _, err = proc.communicate(timeout=300)
        assert proc.returncode == 0, err
    keys = pq.read_table(folder / RESULTS_FILE)["key"].to_pylist()
    expected = {cell_row(p, i)["key"] for p in ("a", "b") for i in range(n)}
    assert len(keys) == len(set(keys)) and set(keys) == expected
    assert set(read_results(folder)["key"]) == expected


HOLDER = """
import sys, time
from slipbench.atomic import folder_lock
with folder_lock(sys.argv[1]):
    print("locked", flush=True)
    time.sleep(600)
"""


def test_a_lock_held_by_a_hung_process_is_a_fault_and_dies_with_it(tmp_path):
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLDER, str(tmp_path)],
        stdout=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
    )
    try:
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(
            EnvironmentFault,
            match=r"cannot lock .*\.lock: another process has held this lock for over 0\.3 s",
        ):
            with folder_lock(tmp_path, timeout=0.3):
                pass
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait()
    with folder_lock(tmp_path, timeout=5):  # the kernel released the dead holder's lock
        pass


# ----------------------------------------------------------------------------- the umask
@pytest.mark.parametrize("umask", [0o022, 0o002])
def test_files_and_folders_follow_the_umask(umask, tmp_path):
    old = os.umask(umask)
    try:
        store = ResultsStore(tmp_path / "out")
        store.put(cell_row("c", 0), cell_predictions(0))
        store.put(cell_row("c", 1), cell_predictions(1))
        store.consolidate()
        model = store.model_path("m")
        tiny().save(model)
        write_text_atomic(Path(f"{model}.json"), "{}")
        made = unique_folder(tmp_path / "out", ".dataset.")
    finally:
        os.umask(old)
    out = tmp_path / "out"
    files = [
        out / "cells" / "c00000.parquet",
        out / "predictions" / "c00001.parquet",
        out / RESULTS_FILE,
        out / ".lock",
        model,
        Path(f"{model}.json"),
    ]
    folders = [out, out / "cells", out / "predictions", out / "models", made]
    assert {p.name: oct(p.stat().st_mode & 0o777) for p in files} == {
        p.name: oct(0o666 & ~umask) for p in files
    }
    assert {p.name: oct(p.stat().st_mode & 0o777) for p in folders} == {
        p.name: oct(0o777 & ~umask) for p in folders
    }
