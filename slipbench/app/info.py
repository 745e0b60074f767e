"""The summary table of ``slipbench dataset info``: what a dataset holds per sensor, instance,
scenario, material and speed, and how its per-sample labels sit with its scenarios."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd

from slipbench.data.format import Dataset
from slipbench.vocabulary import SENSOR_TYPE

SCENARIO_LABEL = {
    "slip": 1,
    "press": 0,
    "free-space": 0,
}  # what labelling by scenario calls each sample


def info(dataset: Dataset) -> pd.DataFrame:
    """Recordings, trials, samples and seconds per sensor, instance, scenario, material and speed;
    where the dataset has per-sample labels, the share of labelled samples that slip
    (``slip_fraction``) and the share whose label disagrees with their recording's scenario
    (``scenario_disagreement``: a slip recording's stick phases, say; NaN for hold-slip, whose
    scenario labels no sample)."""
    rec = dataset.recordings.copy()
    rec["samples"] = [len(dataset.samples[r]) for r in rec["recording_id"]]
    rec["seconds"] = rec["samples"] / rec["sampling_rate_hz"]
    # column -> (source column, a pandas aggregation name or function)
    aggregations: dict[str, tuple[str, str | Callable[[pd.Series], Any]]] = dict(
        recordings=("recording_id", "size"),
        trials=("trial", "nunique"),
        samples=("samples", "sum"),
        seconds=("seconds", "sum"),
    )
    if dataset.slip_labels:
        labels = [dataset.slip_labels[r] for r in rec["recording_id"]]
        rec["labelled"] = [int((lab >= 0).sum()) for lab in labels]
        rec["slipping"] = [int((lab == 1).sum()) for lab in labels]
        rec["disagreeing"] = [
            int(((lab >= 0) & (lab != SCENARIO_LABEL[sc])).sum())
            if sc in SCENARIO_LABEL
            else np.nan
            for lab, sc in zip(labels, rec["scenario"])
        ]
        aggregations |= dict(
            labelled=("labelled", "sum"),
            slipping=("slipping", "sum"),
            disagreeing=("disagreeing", lambda v: v.sum(min_count=1)),
        )
    keys = [SENSOR_TYPE, "sensor_instance", "scenario", "material", "speed_mm_s"]
    table = rec.groupby(keys, dropna=False, sort=True).agg(**aggregations).reset_index()
    if dataset.slip_labels:
        table["slip_fraction"] = table["slipping"] / table["labelled"].where(table["labelled"] > 0)
        table["scenario_disagreement"] = table["disagreeing"] / table["labelled"].where(
            table["labelled"] > 0
        )
        table = table.drop(columns=["labelled", "slipping", "disagreeing"])
    return table


def describe(description: dict[str, str]) -> list[str]:
    """The lines ``dataset info`` prints for a dataset's stored source and citation (what
    ``dataset fetch`` records from the card): none when the dataset has neither."""
    import json

    lines = []
    source = description.get("slipbench.source")
    if source:
        try:
            s = json.loads(source)
            lines.append(
                f"source: {s['title']} ({s['homepage']}), card {s['card']}, downloaded from "
                f"{s['downloaded_from']}; license: {s['license']}"
            )
        except (ValueError, TypeError, KeyError):  # written by other means: shown as it is
            lines.append(f"source: {source}")
    if description.get("slipbench.citation"):
        lines.append(f"cite: {description['slipbench.citation']}")
    return lines
