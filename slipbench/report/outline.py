"""What a report is made of, before any table is drawn: each protocol's layout (from the
registry), the order of protocols, detectors and splits, and the parts of rows each table and
figure shows. Shared by the report, its figures, the findings and compare."""

from __future__ import annotations

import json

import pandas as pd

from slipbench.errors import SlipbenchError
from slipbench.protocol import Layout
from slipbench.report.paper import table_order
from slipbench.report.tables import fits, generic_layout, rank
from slipbench.vocabulary import DETECTOR_ORDER, SPLIT_ORDER


def layouts(rows: pd.DataFrame) -> dict[str, tuple[Layout, str]]:
    """Each protocol's layout, from its class in the registry (built-in, entry point or plugin
    folder) made with the options its rows ran with, and a note when it fell back to a layout
    from the cell keys (the protocol cannot be loaded, or its layout does not fit its rows)."""
    from slipbench.engine.registry import protocols

    out: dict[str, tuple[Layout, str]] = {}
    for name in rows["protocol"].unique():
        part = rows[rows["protocol"] == name]
        layout: Layout | None
        try:
            cls = protocols.get(name)
            params = (
                json.loads(part["protocol_params"].iloc[0]) if "protocol_params" in part else {}
            )
            layout = cls(**params).layout
            why = "it declares no layout" if layout is None else fits(layout, part)
        except (SlipbenchError, TypeError, ValueError, json.JSONDecodeError) as exc:
            layout, why = (
                None,
                f"protocol {name!r} could not be loaded ({exc}); pass its plugin folder with --plugins",
            )
        if layout is not None and not why:
            out[name] = (layout, "")
        else:
            out[name] = (generic_layout(part, name), f"Laid out from its cell keys: {why}.")
    return out


def protocol_order(found: dict[str, tuple[Layout, str]]) -> list[str]:
    """Protocols laid out as the paper's tables first, in the paper's order, then the others."""
    paper_order = table_order()

    def position(p: str) -> tuple[int, str]:
        table = found[p][0].paper_table
        if table is not None and table in paper_order:
            return paper_order.index(table), p
        return len(paper_order), p

    return sorted(found, key=position)


def splits_of(rows: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
    """(split, rows) per split of the rows (grouped, paper, ...): the split by trial first, as
    the one whose test trials never trained the model through another unit."""
    if "split" not in rows:
        return [("paper", rows)]
    return [
        (s, rows[rows["split"] == s]) for s in rank(rows["split"].unique(), ("grouped", "paper"))
    ]


def sections_of(
    rows: pd.DataFrame, found: dict[str, tuple[Layout, str]]
) -> list[tuple[str, str, str, pd.DataFrame]]:
    """(protocol, detector, split, rows): the paper's protocols in its order, then the others."""
    out = []
    for protocol in protocol_order(found):
        prows = rows[rows["protocol"] == protocol]
        for detector in rank(prows["detector"].unique(), DETECTOR_ORDER):
            out += [
                (protocol, detector, split, part)
                for split, part in splits_of(prows[prows["detector"] == detector])
            ]
    return out


def split_parts(rows: pd.DataFrame, layout: Layout) -> list[tuple[dict, pd.DataFrame]]:
    """The rows of each table: one part per combination of the layout's ``split`` columns
    (those the rows hold), named by its values; the rows whole when there are none."""
    splits = [c for c in layout.splits if c in rows]
    if not splits:
        return [({}, rows)]
    parts = [
        (dict(zip(splits, k if isinstance(k, tuple) else (k,))), part)
        for k, part in rows.groupby(
            splits if len(splits) > 1 else splits[0], sort=False, dropna=False
        )
    ]
    for c in reversed(splits):  # stable sorts, last column first: lexicographic order
        order = rank([w[c] for w, _ in parts], SPLIT_ORDER)
        parts.sort(key=lambda p: order.index(p[0][c]))
    return parts
