"""A new column role or figure touches the schema and its computation only.

A copy of the package gains, as a contributor would write them, a new setting (``grip``, a
field of the cell's key) in ``slipbench/store/columns.py`` and a new windowed figure (the Youden
index) there with its computation in ``slipbench/stats/metrics.py``; nothing else is edited.
Run from that copy, the figure is computed with its interval, passes the schema check, and the
gate, the contrast, the leaderboard and the history read it; the contrast, the leaderboard, the
report's tables and the history each keep two grips apart.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import slipbench

PACKAGE = Path(slipbench.__file__).parent

#: (file, a text, what it becomes): the new entries, in the two files they touch
EDITS = (
    (
        "store/columns.py",
        '    Column(\n        "code_identity",',
        '    Column("grip", STR, "", "how the object was held", role=SETTING, keys=("grip",)),\n'
        '    Column(\n        "code_identity",',
    ),
    (
        "store/columns.py",
        "#: every figure by name,",
        'YOUDEN = Figure("youden_index", "", "TP rate + TN rate - 1", label="Youden index", '
        'called="Youden index", display="", decimals=2, tolerance=0.05, se=True, '
        "bounds=(-1.0, 1.0))\n"
        "#: every figure by name,",
    ),
    ("store/columns.py", "        AUROC,\n", "        AUROC,\n        YOUDEN,\n"),
    (
        "stats/metrics.py",
        "    AUROC.name: Computation(_auroc, _auroc_influence),\n",
        "    AUROC.name: Computation(_auroc, _auroc_influence),\n"
        '    "youden_index": Computation(\n'
        "        lambda t, w: 2 * _balanced(t, w) - 1, lambda t, w: 2 * _balanced_influence(t, w)\n"
        "    ),\n",
    ),
)

#: run in the edited copy: every consumer reads the two entries from the schema
CHECK = textwrap.dedent(
    """
    import json, sys
    import numpy as np
    import pandas as pd
    import slipbench
    from slipbench.store import columns
    from slipbench.stats import metrics
    from slipbench.gate.gate import Gate
    from slipbench.stats.contrast import margin_of
    from slipbench.store.resolved import CELL_COLUMNS, cell_of
    from slipbench.stats.factors import setting_labels, setting_parts
    from slipbench.stats.leaderboard import cell_table
    from slipbench.history.series import series_rows
    from slipbench.store.columns import names
    from slipbench.store.history import COLUMNS as HISTORY_COLUMNS

    assert slipbench.__file__.startswith(sys.argv[1]), slipbench.__file__
    rng = np.random.default_rng(0)
    y = np.repeat([0, 1], 60)
    pred = np.where(rng.random(120) < 0.8, y, 1 - y)
    found = metrics.classification_figures(y, pred, np.arange(120) // 6, seed=1)
    tp, tn = found["tp_rate"], found["tn_rate"]
    assert abs(found["youden_index"] - (tp + tn - 1)) < 1e-12, found
    assert found["youden_index_lo"] < found["youden_index"] < found["youden_index_hi"]
    assert found["youden_index_se"] > 0
    assert columns.figure_of("d_youden_index_se").name == "youden_index"
    assert "youden_index" in metrics.FIGURES and "youden_index" not in metrics.RATES

    rows = pd.DataFrame(
        {
            "key": ["a1", "a2", "b1", "b2"],
            "protocol": "window-size",
            "detector": "holweg",
            "detector_params": "{}",
            "split": "paper",
            "seed": [1, 2, 1, 2],
            "cell": '{"window": 50}',
            "grip": ["pinch", "pinch", "power", "power"],
            "status": "ok",
            "accuracy": [0.8, 0.82, 0.7, 0.72],
            "youden_index": [0.6, 0.64, 0.4, 0.44],
            "youden_index_se": 0.05,
            "finished_at": ["t1", "t2", "t3", "t4"],
        }
    )
    for r in rows.to_dict("records"):
        columns.checked(r)
    assert "grip" in CELL_COLUMNS
    assert len({cell_of(r) for r in rows.to_dict("records")}) == 2
    table = cell_table(rows, "youden_index")
    assert "grip" in table.index.names and len(table) == 2, table
    assert sorted(table["holweg"].round(2)) == [0.42, 0.62]
    parts = setting_parts(rows)
    assert [p for p, _ in parts] == [{"grip": "pinch"}, {"grip": "power"}], parts
    assert list(setting_labels(rows)) == ["grip pinch"] * 2 + ["grip power"] * 2
    assert "youden_index" in names(gated=True) and "youden_index_se" in HISTORY_COLUMNS
    assert Gate().tolerances["youden_index"] == 0.05 == margin_of("youden_index")
    series = series_rows(rows)
    assert series["series"].nunique() == 2, series
    assert (series["youden_index_se"] == 0.05).all()
    print("picked up")
    """
)


def _copy_with_edits(tmp: Path) -> Path:
    copy = tmp / "slipbench"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    for file, old, new in EDITS:
        path = copy / file
        text = path.read_text()
        assert text.count(old) == 1, f"{file}: the text the edit replaces moved: {old!r}"
        path.write_text(text.replace(old, new))
    return copy


def test_a_new_setting_and_figure_are_the_schema_and_the_computation_only(tmp_path):
    copy = _copy_with_edits(tmp_path)
    changed = {
        str(p.relative_to(copy))
        for p in copy.rglob("*.py")
        if p.read_bytes() != (PACKAGE / p.relative_to(copy)).read_bytes()
    }
    assert changed == {"store/columns.py", "stats/metrics.py"}
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    done = subprocess.run(
        [sys.executable, "-c", CHECK, str(copy)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.strip().endswith("picked up")
