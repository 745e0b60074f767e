"""A results or cell file that is not Parquet is refused from its first and last bytes, before
the rest is read: a 2 GB file (sparse here: it costs no disk) is never read into memory."""

from __future__ import annotations

import builtins
from pathlib import Path

import pytest

from slipbench.errors import DataError
from slipbench.store import scan
from slipbench.store.results import read_results
from slipbench.store.scan import read_cell

SIZE = 2 * 2**30


def _sparse(path: Path, head: bytes = b"a log, not a table\n", tail: bytes = b"") -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as f:
        f.write(head)
        f.truncate(SIZE)
        if tail:
            f.seek(SIZE - len(tail))
            f.write(tail)
    return path


@pytest.fixture
def reads(monkeypatch):
    """The bytes each read of scan's files asked for (-1: the whole rest of the file)."""
    asked: list[int] = []

    class Counted:
        def __init__(self, file):
            self.file = file

        def read(self, n=-1):
            asked.append(n)
            return self.file.read(n)

        def __getattr__(self, name):
            return getattr(self.file, name)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.file.close()

    monkeypatch.setattr(
        scan, "open", lambda *a, **k: Counted(builtins.open(*a, **k)), raising=False
    )
    return asked


FOOTER_CLAIMS_TOO_MUCH = (2**32 - 1).to_bytes(4, "little") + b"PAR1"


@pytest.mark.parametrize(
    ("head", "tail", "why"),
    [
        (b"a log, not a table\n", b"", "it does not begin and end with Parquet's magic bytes PAR1"),
        (b"PAR1", FOOTER_CLAIMS_TOO_MUCH, f"its footer claims {2**32 - 1} bytes of a {SIZE}-byte"),
    ],
    ids=["no magic", "footer too long"],
)
def test_a_huge_results_file_that_is_not_parquet_is_refused_from_its_footer(
    tmp_path, reads, head, tail, why
):
    path = _sparse(tmp_path / "results.parquet", head, tail)
    with pytest.raises(DataError) as err:
        read_results(tmp_path)
    assert str(err.value).startswith(f"{path}: not a readable results file (not a Parquet file: ")
    assert why in str(err.value) and f"refused before reading its {SIZE} bytes" in str(err.value)
    assert reads and all(0 <= n <= 8 for n in reads), reads  # never the whole file


def test_a_huge_cell_file_that_is_not_parquet_is_refused_from_its_footer(tmp_path, reads):
    path = _sparse(tmp_path / "cells" / "k0000.parquet")
    with pytest.raises(DataError, match="not a readable cell file \\(not a Parquet file: "):
        read_cell(path, "k0000")
    assert reads and all(0 <= n <= 8 for n in reads), reads


def test_a_file_too_short_for_parquet_is_refused(tmp_path, reads):
    (tmp_path / "results.parquet").write_bytes(b"PAR1PAR1")
    with pytest.raises(DataError, match="8 bytes, too few for Parquet"):
        read_results(tmp_path)
    assert not reads
