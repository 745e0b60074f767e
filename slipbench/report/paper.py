"""The published numbers of Van Wyk & Falco (package data ``slipbench/report/paper/van_wyk_falco.json``)."""

from __future__ import annotations

import json
from functools import cache
from importlib import resources
from typing import Any

import pandas as pd

from slipbench.stats.metrics import RATES
from slipbench.vocabulary import SENSOR_TYPE


@cache
def paper_data() -> dict[str, Any]:
    """The published numbers of Van Wyk & Falco (package data ``slipbench/report/paper/van_wyk_falco.json``)."""
    # one name per joinpath: Python 3.10's Traversable takes no more
    text = (
        resources.files("slipbench.report")
        .joinpath("paper")
        .joinpath("van_wyk_falco.json")
        .read_text()
    )
    return json.loads(text)


def paper_frame(name: str) -> pd.DataFrame:
    """One published table as rows, values as fractions (0.880 for 88.0 %).

    ``name`` is a protocol (``window-size``, ``sampling-rate``, ``material-holdout``,
    ``speed-holdout``, ``cross-instance``), ``holweg`` or ``rates_window_50``. The sampling-rate
    table gains the full-rate column (downsample 1) from Table I at window 200, the same setting.
    """
    data = paper_data()
    spec = data["tables"].get(name) or data.get(name)
    if spec is None:
        return pd.DataFrame()
    frame = pd.DataFrame(spec["rows"], columns=spec["columns"])
    for col in RATES:
        if col in frame:
            frame[col] = frame[col] / 100
    if name == "sampling-rate":
        full = paper_frame("window-size").query("window == 200").drop(columns="window")
        full = full.assign(
            downsample=1, rate_hz=full[SENSOR_TYPE].map({"BioTacSP": 850.0}).fillna(1000.0)
        )
        # every published rate is of windows of 200 full-rate samples: the caption's window
        frame = pd.concat([frame, full[frame.columns]], ignore_index=True).assign(window=200)
    return frame


def table_order() -> list[str]:
    """The published tables in the paper's order (window size, sampling rate, ...)."""
    return list(paper_data()["tables"])
