"""What a report is made of, before any table is drawn: each protocol's layout (from the
registry), the order of protocols, detectors and splits, and the parts of rows each table and
figure shows. Shared by the report, its figures, the findings and compare."""

from __future__ import annotations

import json

import pandas as pd

from slipbench.errors import SlipbenchError
from slipbench.protocol import NO_CELL, Layout
from slipbench.report.paper import table_order
from slipbench.report.presentation import lineage, presented
from slipbench.report.tables import TRAINED_AS, fits, generic_layout, rank
from slipbench.stats.factors import SETTINGS, differing_settings, factor_values, setting_text
from slipbench.vocabulary import DETECTOR_ORDER, SPLIT_ORDER


def _unit_of(name: str, sensor_type: str) -> tuple[str, str]:
    """A sensor map's ``TYPE:INSTANCE`` as (type, instance); a name that does not split there
    one way keeps the row's type and reads whole as the instance."""
    kind, sep, instance = name.partition(":")
    return (kind, instance) if sep and ":" not in instance else (sensor_type, name)


def as_tested(rows: pd.DataFrame) -> pd.DataFrame:
    """``rows`` with each row trained on one dataset and tested on another (its ``sensor_map``)
    naming the unit it tested: ``sensor_type`` and ``sensor_instance`` those of the test
    dataset's unit, the instance saying what it was tested as (``ff (trained as BioTacSP
    ff)``), the training unit kept in :data:`~slipbench.report.tables.TRAINED_AS`."""
    if "sensor_map" not in rows or "sensor_instance" not in rows or rows["sensor_map"].isna().all():
        return rows
    out = rows.assign(**{TRAINED_AS: None})
    for text, part in rows[rows["sensor_map"].notna()].groupby("sensor_map", sort=False):
        try:
            tested: dict[str, list[str]] = {}
            for test, train in json.loads(text).items():
                tested.setdefault(str(train), []).append(str(test))
        except (TypeError, AttributeError, json.JSONDecodeError):
            continue  # a map this version cannot read: the rows keep the training unit's names
        for i, kind, instance in part[["sensor_type", "sensor_instance"]].itertuples(name=None):
            names = tested.get(f"{kind}:{instance}")
            if pd.isna(instance) or not names:
                continue
            units = [_unit_of(n, str(kind)) for n in names]
            kinds = list(dict.fromkeys(k for k, _ in units))
            out.at[i, "sensor_type"] = kinds[0] if len(kinds) == 1 else " + ".join(kinds)
            shown = " + ".join(u if len(kinds) == 1 else f"{k}:{u}" for k, u in units)
            out.at[i, "sensor_instance"] = f"{shown} (trained as {kind} {instance})"
            out.at[i, TRAINED_AS] = f"{kind}:{instance}"
    return out


def stand_ins(rows: pd.DataFrame) -> pd.Series:
    """(n_rows,) bool: the skipped stand-in rows of protocols that made no cell on a dataset
    (:func:`slipbench.protocol.no_cell`): reports say why instead of laying them out."""
    if "cell" not in rows:
        return pd.Series(False, index=rows.index, dtype=bool)
    return rows["cell"].eq(NO_CELL)


def no_cell_note(rows: pd.DataFrame, datasets: int = 1) -> str:
    """What a protocol's stand-in rows say: each reason once, with the detectors it stands for
    and, where the protocol's rows come from several ``datasets``, the dataset."""
    parts = []
    many = "dataset_fingerprint" in rows and datasets > 1
    by = ["reason"] + (["dataset_fingerprint"] if many else [])
    for values, part in rows.fillna({c: "" for c in by}).groupby(by, sort=False):
        reason = values[0] if isinstance(values, tuple) else values
        detectors = ", ".join(rank(part["detector"].unique(), DETECTOR_ORDER))
        where = ""
        if many:
            path = str(part["dataset_path"].iloc[0]) if "dataset_path" in part else ""
            where = f" On dataset {path or str(values[1])[:12]}:"
        parts.append(f"{where} {str(reason).rstrip('.') or 'no cell'}. Detectors: {detectors}.")
    return "No table:" + "".join(parts)


def layouts(rows: pd.DataFrame) -> dict[str, tuple[Layout, str]]:
    """Each protocol's layout, from its class in the registry (built-in, entry point or plugin
    folder) made with the options its rows ran with and shown as :func:`presented` says, and a note when it fell back to a layout
    from the cell keys (the protocol cannot be loaded, or its layout does not fit its rows).
    Stand-in rows (:func:`stand_ins`) are not laid out: a protocol with nothing else keeps its
    own layout, for its place in the report."""
    from slipbench.engine.registry import protocols

    out: dict[str, tuple[Layout, str]] = {}
    for name in rows["protocol"].unique():
        every = rows[rows["protocol"] == name]
        part = every[~stand_ins(every)]
        layout: Layout | None
        try:
            cls = protocols.get(name)
            given = every["protocol_params"].iloc[0] if "protocol_params" in every else None
            params = json.loads(given) if isinstance(given, str) else {}  # absent: the defaults
            declared = cls(**params).layout
            layout = (
                presented(lineage(name, cls), declared)
                if isinstance(declared, Layout)
                else declared
            )
            why = (
                "it declares no layout"
                if layout is None
                else fits(layout, part)
                if len(part)
                else ""
            )
        except (SlipbenchError, TypeError, ValueError, json.JSONDecodeError) as exc:
            layout, why = (
                None,
                f"protocol {name!r} could not be loaded ({exc}); pass its plugin folder with --plugins",
            )
        if why or layout is None:
            out[name] = (
                generic_layout(part if len(part) else every, name),
                f"Laid out from its cell keys: {why}.",
            )
        else:
            out[name] = (layout, "")
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
    (those the rows hold) and of the settings that differ between the rows
    (:func:`slipbench.stats.factors.differing_settings`: labels, dataset, protocol options,
    ...: no table averages two of them), named by its values; the rows whole when there are
    none."""
    splits = [c for c in layout.splits if c in rows]
    settings = [c for c in differing_settings(rows) if c not in splits]
    if not splits and not settings:
        return [({}, rows)]
    keys = pd.DataFrame(
        {**{c: rows[c] for c in splits}, **{c: factor_values(rows, c) for c in settings}},
        index=rows.index,
    )
    by = [*splits, *settings]
    parts = [
        (dict(zip(by, k if isinstance(k, tuple) else (k,))), rows.loc[part.index])
        for k, part in keys.groupby(by if len(by) > 1 else by[0], sort=False, dropna=False)
    ]
    for c in reversed(by):  # stable sorts, last column first: lexicographic order
        order = rank([w[c] for w, _ in parts], SPLIT_ORDER)
        parts.sort(key=lambda p: order.index(p[0][c]))
    return parts


def which_text(which: dict) -> str:
    """What a part of :func:`split_parts` is, for its caption: `` Decimation: lag.`` for a
    layout's split, `` Labels majority.`` for a setting."""
    return "".join(
        f" {setting_text(c, v).capitalize()}." if c in SETTINGS else f" {c.capitalize()}: {v}."
        for c, v in which.items()
    )


def references(rows: pd.DataFrame) -> list[str]:
    """The plugin ids of the rows' detectors that are registered as the reference (the
    baseline every table compares against); a detector that cannot be loaded is none."""
    from slipbench.engine.registry import detectors
    from slipbench.stats.factors import ENTRANT_ID

    ids = rows[ENTRANT_ID] if ENTRANT_ID in rows else rows.get("detector", pd.Series(dtype=str))
    out = []
    for name in sorted(ids.dropna().astype(str).unique()):
        try:
            if getattr(detectors.get(name), "reference", False):
                out.append(name)
        except SlipbenchError:
            continue
    return out
