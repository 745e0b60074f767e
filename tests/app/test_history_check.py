"""The reviewer's check of history: eight real runs of holweg on the simulated data (scale
0.01; window-size at 50 and 100, grouped, seeds 1 to 8), keep 0.8 in runs 1-4 and 0.6 in runs
5-8, added as commits c1..c8. `history steps` names c5 and no other commit; `history page`
writes site/index.html loading no script from the network."""

from __future__ import annotations

import io
import json
import re
from contextlib import redirect_stdout

import pytest

from slipbench.app.cli import main


def _cli(*args: str) -> tuple[int, str]:
    out = io.StringIO()
    with pytest.raises(SystemExit) as exit_, redirect_stdout(out):
        main(list(args))
        raise SystemExit(0)
    return int(exit_.value.code or 0), out.getvalue()


@pytest.mark.slow
def test_keep_changed_at_c5_is_named_there_alone(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for k in range(1, 9):
        code, _ = _cli(
            "evaluate",
            "--detector",
            "holweg",
            "--protocol",
            "window-size",
            "--protocol-param",
            "windows=[50,100]",
            "--split",
            "grouped",
            "--scale",
            "0.01",
            "--seed",
            str(k),
            "--param",
            f"keep={0.8 if k <= 4 else 0.6}",
            "--out",
            f"c{k}",
            "--quiet",
        )
        assert code == 0
        code, _ = _cli(
            "history",
            "add",
            f"c{k}",
            "--history",
            "hist",
            "--commit",
            f"c{k}",
            "--date",
            f"2026-01-0{k}T12:00:00Z",
        )
        assert code == 0
    code, text = _cli("history", "steps", "--history", "hist")
    assert code == 0
    named = set(re.findall(r"\bc\d\b", text.split("\n", 1)[1]))
    assert named == {"c5"}, text
    # four seeds a side on their own datasets cannot confirm it: c5 is named as the proposed
    # step, with its interval and the seeds a side that would confirm a change that large
    (line,) = [x for x in text.splitlines() if x.startswith("- c5")]
    assert re.search(r"\[[-+]\d+\.\d+, [-+]\d+\.\d+\] points at 99 % on 6 df", line), line
    assert re.search(r"about \d+ seeds a side .* would confirm", line), line
    _, doc = _cli("history", "steps", "--history", "hist", "--json")
    steps = json.loads(doc)["steps"]
    assert steps and {s["commit"] for s in steps} == {"c5"}
    assert all("parameters" in s["what_changed"] for s in steps)
    assert _cli("history", "page", "--history", "hist", "--out", "site")[0] == 0
    index = (tmp_path / "site" / "index.html").read_text()
    assert re.findall(r'<script[^>]*src="([^"]+)"', index) == ["assets/plotly.js", "assets/site.js"]
    assert not re.search(r'src="(https?:)?//', index)
