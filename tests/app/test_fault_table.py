"""The fault table (docs/reference/faults.md) stays true to the tests: every row names the test files that check
it, and every file it names exists (a renamed or deleted test must take its row along)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = next(p for p in Path(__file__).resolve().parents if (p / "pyproject.toml").is_file())


def _fault_rows() -> list[tuple[str, list[str]]]:
    section = (ROOT / "docs" / "reference" / "faults.md").read_text()
    rows = []
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 3 and cells[0] not in ("fault", "---"):
            rows.append((cells[0], re.findall(r"`(test_\w+\.py)`", cells[2])))
    return rows


def test_every_fault_names_existing_tests():
    rows = _fault_rows()
    assert len(rows) >= 20, "the fault table was not found or lost rows"
    known = {p.name for p in (ROOT / "tests").rglob("test_*.py")}
    unnamed = [fault for fault, files in rows if not files]
    missing = {(fault, f) for fault, files in rows for f in files if f not in known}
    assert not unnamed, f"fault rows naming no test: {unnamed}"
    assert not missing, f"fault rows naming test files that do not exist: {sorted(missing)}"
