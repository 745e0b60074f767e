"""The committed reports/README.md is a summary that a reader can open (under 60 KB) and whose
full tables lie in the appendix it links: every link into appendix.md lands on a heading there,
and each protocol's section points to its part of the appendix."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from slipbench.report.document import _anchor

REPORTS = Path(__file__).resolve().parents[2] / "reports"
LIMIT = 60_000  # bytes: the size issue 56 sets for the summary


@pytest.fixture(scope="module")
def readme() -> str:
    return (REPORTS / "README.md").read_text(encoding="utf-8")


def test_the_summary_stays_under_its_bound(readme):
    assert len(readme.encode()) < LIMIT, "move tables to the appendix (split_appendix)"


def test_every_link_into_the_appendix_lands_on_a_heading(readme):
    appendix = (REPORTS / "appendix.md").read_text(encoding="utf-8")
    headings = {_anchor(h) for h in re.findall(r"^#+ (.+)$", appendix, re.M)}
    targets = re.findall(r"\]\(appendix\.md#([^)]+)\)", readme)
    assert targets and not set(targets) - headings
    protocols = re.findall(r"^## ([a-z-]+)$", readme, re.M)
    assert protocols and set(protocols) <= set(targets)  # each protocol names its appendix part
    assert "[README.md](README.md)" in appendix  # and the appendix links back
