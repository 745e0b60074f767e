"""Golden files: texts the report pins (tables, outlines, the compare summary), kept in golden/.

Regenerate them after an intended layout change by running the tests that call `check_golden`
(``grep -rl check_golden tests``) with ``SLIPBENCH_UPDATE_GOLDEN=1``, and review the diff.
"""

from __future__ import annotations

import os
from pathlib import Path

GOLDEN = Path(__file__).parent / "golden"


def check_golden(name: str, text: str) -> None:
    path = GOLDEN / name
    if os.environ.get("SLIPBENCH_UPDATE_GOLDEN"):
        path.write_text(text)
    assert text == path.read_text(), f"{name} changed; see tests/goldens.py to update it"
