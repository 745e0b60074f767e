"""Result rows -> tables in the paper's layout. Formatting only: reads rows, computes nothing
beyond pivoting them."""

from __future__ import annotations

import pandas as pd

SENSOR_NAMES = {"Nano17": "Nano17", "OptoForce20": "OptoForce20", "BioTacSP": "Biotac SP"}


def _percent(value: float, lo: float | None = None, hi: float | None = None) -> str:
    if pd.isna(value):
        return "NA"
    text = f"{100 * value:.1f}"
    if lo is not None and not (pd.isna(lo) or pd.isna(hi)):
        text += f" [{100 * lo:.1f}, {100 * hi:.1f}]"
    return text


def pivot(rows: pd.DataFrame, index: list[str], columns: str, value: str = "accuracy", intervals: bool = False) -> pd.DataFrame:
    """One formatted cell per (index, column); skipped cells read 'skipped'."""
    rows = rows.copy()
    if intervals:
        rows["text"] = [_percent(v, lo, hi) for v, lo, hi in zip(rows[value], rows[f"{value}_lo"], rows[f"{value}_hi"])]
    else:
        rows["text"] = [_percent(v) for v in rows[value]]
    rows.loc[rows["status"] != "ok", "text"] = rows["status"]
    table = rows.pivot_table(index=index, columns=columns, values="text", aggfunc="first", sort=False)
    table = table.reindex(columns=sorted(table.columns, key=_order))
    return table


def _order(value):
    try:
        return (0, float(value), "")
    except (TypeError, ValueError):
        return (1, 0.0, str(value))


def to_markdown(table: pd.DataFrame, index_names: dict[str, str]) -> str:
    flat = table.reset_index()
    for column, name in index_names.items():
        if column == "sensor_type":
            flat[column] = flat[column].map(lambda s: SENSOR_NAMES.get(s, s))
        elif column == "sensor_instance":
            flat[column] = flat[column].str.capitalize()
    flat = flat.rename(columns={**index_names, **{c: f"{c:g}" if isinstance(c, float) else str(c) for c in table.columns}})
    return flat.to_markdown(index=False, stralign="right", disable_numparse=True)


def protocol_table(rows: pd.DataFrame, layout: dict, intervals: bool = False) -> str:
    """The Markdown table of one protocol's rows for one detector, in the paper's layout."""
    index = layout["rows"]
    names = {"sensor_type": "Sensor", "sensor_instance": "Finger"}
    table = pivot(rows, index, layout["columns"], intervals=intervals)
    return f"{layout['title']}\n\n" + to_markdown(table, {c: names.get(c, c) for c in index})
