"""Channels matched by name and unit, never by position: a unit wired in another order reads as
the others do, and a cell whose recordings name other channels (or the same in other units) is
not run on columns that only share a position."""

from __future__ import annotations

import numpy as np
import pandas as pd

from slipbench.vocabulary import DATASET_SIDE, SENSOR_TYPE

Layout = tuple[tuple[str, str], ...]


def channel_layouts(recordings: pd.DataFrame) -> list[Layout]:
    """Each recording's channels as (name, unit) pairs, in the order of its columns."""
    return [
        tuple((str(c), str(u)) for c, u in zip(names, units))
        for names, units in zip(recordings["channels"], recordings["units"])
    ]


def _references(recordings: pd.DataFrame) -> dict[Layout, Layout]:
    """Per set of (name, unit) pairs, the order every recording holding it is put in: that of
    the first such recording, the training dataset's first across datasets."""
    layouts = channel_layouts(recordings)
    first = np.zeros(len(layouts), int)
    if DATASET_SIDE in recordings:
        first = (recordings[DATASET_SIDE].to_numpy() != "train").astype(int)
    out: dict[Layout, Layout] = {}
    for i in np.argsort(first, kind="stable"):
        out.setdefault(tuple(sorted(layouts[i])), layouts[i])
    return out


def channel_orders(recordings: pd.DataFrame) -> list[np.ndarray | None]:
    """Per recording, the columns that put its channels in their reference order (see
    :func:`_references`); None where they already are in it. A recording naming a pair twice
    is left as it is (its columns cannot be told apart by name)."""
    references = _references(recordings)
    out: list[np.ndarray | None] = []
    for layout in channel_layouts(recordings):
        reference = references[tuple(sorted(layout))]
        if len(set(layout)) < len(layout) or reference == layout:
            out.append(None)
        else:
            out.append(np.array([layout.index(p) for p in reference]))
    return out


def _shown(layout: Layout) -> str:
    return "[" + ", ".join(f"{name} ({unit})" for name, unit in layout) + "]"


def _owners(rec: pd.DataFrame) -> pd.Series:
    """Who holds each recording, as a reason names it: its unit, and its dataset in transfer."""
    unit = rec[SENSOR_TYPE].astype(str) + " " + rec["sensor_instance"].astype(str)
    if DATASET_SIDE in rec:
        return rec[DATASET_SIDE].map({"train": "training", "test": "test"}) + " dataset's " + unit
    return unit


def channel_match(recordings: pd.DataFrame, *rows: np.ndarray) -> tuple[str, str]:
    """Whether the recordings at ``rows`` (a cell's, on both sides) can form one array of
    channels: (why not, "") where they name different channels or units, naming each layout
    and who holds it; ("", what was reordered) where some hold the same channels in another
    order (:func:`channel_orders` puts them in one); ("", "") where all agree."""
    rec = recordings.iloc[pd.unique(np.concatenate(rows))]  # the training side's named first
    if DATASET_SIDE in rec:
        rec = rec.iloc[np.argsort(rec[DATASET_SIDE].to_numpy() != "train", kind="stable")]
    layouts = pd.Series(channel_layouts(rec), index=rec.index)
    owners = _owners(rec)
    sets = layouts.map(lambda x: tuple(sorted(x)))
    if sets.nunique() > 1:
        shown = "; ".join(
            f"{', '.join(sorted(set(owners[mine])))} has {_shown(layouts[mine].iloc[0])}"
            for mine in (
                sets.map(lambda x, s=s: x == s).to_numpy(bool) for s in dict.fromkeys(sets)
            )
        )
        return (
            "the channels input matches channels by name and unit, and this cell's recordings "
            f"name different ones: {shown}",
            "",
        )
    orders = list(dict.fromkeys(layouts))
    if len(orders) < 2:
        return "", ""
    reference = _references(recordings)[sets.iloc[0]]  # Signals.from_dataset's order
    if len(set(reference)) < len(reference):
        return (
            f"the channels input matches channels by name and unit, and this cell's recordings "
            f"name a channel twice, in different orders: {_shown(orders[0])}, {_shown(orders[1])}",
            "",
        )
    moved = layouts.map(lambda x: x != reference).to_numpy(bool)
    return "", (
        f"channels matched by name and unit: {', '.join(sorted(set(owners[moved])))} reordered "
        f"from {_shown(layouts[moved].iloc[0])} to {_shown(reference)}"
    )
