"""evaluate's options are a typed dict: a misspelt one is refused, never ignored."""

from __future__ import annotations

import pytest

from slipbench.engine.runner import evaluate


def test_a_misspelt_option_is_refused_before_any_work():
    with pytest.raises(TypeError, match=r"unknown options: job, progres"):
        evaluate(None, [], None, job=2, progres=False)  # type: ignore[arg-type, call-arg]
