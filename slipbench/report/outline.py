"""What a report is made of, before any table is drawn (:func:`outline`, once per report): each
protocol's layout (as its rows record it), the order of protocols, detectors and splits, and
the parts of rows each table and figure shows. Shared by the report, its figures, the findings
and compare."""

from __future__ import annotations

import json
from dataclasses import dataclass

import pandas as pd

from slipbench.protocol import NO_CELL, Layout, Presentation, from_record
from slipbench.report.notes import SIMULATED, TRAINED_AS
from slipbench.report.order import rank
from slipbench.report.paper import table_order
from slipbench.report.presentation import ShownLayout, shown
from slipbench.report.provenance import on_simulation
from slipbench.stats.factors import (
    ENTRANT_ID,
    SETTINGS,
    differing_settings,
    factor_values,
    named_entrants,
    setting_text,
)
from slipbench.store.resolved import Resolved, resolve
from slipbench.vocabulary import DETECTOR_ORDER, SENSOR_TYPE, SPLIT_ORDER


def _unit_of(name: str, sensor_type: str) -> tuple[str, str]:
    """A sensor map's ``TYPE:INSTANCE`` as (type, instance); a name that does not split there
    one way keeps the row's type and reads whole as the instance."""
    kind, sep, instance = name.partition(":")
    return (kind, instance) if sep and ":" not in instance else (sensor_type, name)


def as_tested(rows: pd.DataFrame) -> pd.DataFrame:
    """``rows`` with each row trained on one dataset and tested on another (its ``sensor_map``)
    naming the unit it tested: ``sensor_type`` and ``sensor_instance`` those of the test
    dataset's unit, the instance saying what it was tested as (``ff (trained as BioTacSP
    ff)``), the training unit kept in :data:`~slipbench.report.notes.TRAINED_AS`."""
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
        for i, kind, instance in part[[SENSOR_TYPE, "sensor_instance"]].itertuples(name=None):
            names = tested.get(f"{kind}:{instance}")
            if pd.isna(instance) or not names:
                continue
            units = [_unit_of(n, str(kind)) for n in names]
            kinds = list(dict.fromkeys(k for k, _ in units))
            out.at[i, SENSOR_TYPE] = kinds[0] if len(kinds) == 1 else " + ".join(kinds)
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


def _key_columns(rows: pd.DataFrame) -> list[str]:
    """The cell-key columns of rows (from their ``cell`` JSON), in first-seen order."""
    keys: list[str] = []
    for text in rows["cell"].dropna().unique() if "cell" in rows else ():
        for k in json.loads(text):
            if k not in keys:
                keys.append(k)
    return keys


def generic_layout(rows: pd.DataFrame, protocol: str) -> ShownLayout:
    """A layout from the cell keys alone (a protocol whose own layout is unknown or does not fit
    its rows): all keys but the last as rows, the last as columns."""
    keys = [k for k in _key_columns(rows) if k in rows] or ["protocol"]
    what = Layout((keys[0],), "detector") if len(keys) == 1 else Layout(tuple(keys[:-1]), keys[-1])
    return shown(what, Presentation(title=protocol), protocol)


def fits(layout: Layout, rows: pd.DataFrame) -> str:
    """Why ``layout`` cannot lay out ``rows`` (a key column they lack), or "" when it can."""
    missing = [k for k in (*layout.rows, layout.column, layout.pair) if k and k not in rows]
    return f"the rows lack the layout's columns {', '.join(missing)}" if missing else ""


def _recorded(rows: pd.DataFrame, column: str) -> str:
    """The first value the rows record in ``column`` ("" where none does)."""
    if column not in rows:
        return ""
    given = rows[column].dropna().astype(str)
    given = given[given != ""]
    return given.iloc[0] if len(given) else ""


def recorded_layout(rows: pd.DataFrame, protocol: str) -> ShownLayout | None:
    """The layout and presentation that the rows of ``protocol`` record
    (:func:`slipbench.protocol.described`), or None where they record none; a ValueError says
    why a recorded one cannot be read."""
    text = _recorded(rows, "protocol_layout")
    if not text:
        return None
    look = _recorded(rows, "protocol_presentation")
    return shown(
        from_record(Layout, text), from_record(Presentation, look) if look else None, protocol
    )


def layouts(rows: pd.DataFrame) -> dict[str, tuple[ShownLayout, str]]:
    """Each protocol's layout as its rows record it (:func:`recorded_layout`), and a note where
    the report laid its rows out from their cell keys instead: the rows record no layout (rows
    written before results recorded it, that the command could not fill in from the protocol's
    plugin), one that cannot be read, or one that does not fit them. Stand-in rows (:func:`stand_ins`) are not
    laid out: a protocol with nothing else keeps its own layout, for its place in the report."""
    out: dict[str, tuple[ShownLayout, str]] = {}
    for name in rows["protocol"].unique():
        every = rows[rows["protocol"] == name]
        part = every[~stand_ins(every)]
        layout: ShownLayout | None
        try:
            layout = recorded_layout(every, name)
            why = (
                "its rows do not record the protocol's layout"
                if layout is None
                else fits(layout, part)
                if len(part)
                else ""
            )
        except ValueError as exc:
            layout, why = None, f"its rows record a layout that cannot be read ({exc})"
        if why or layout is None:
            out[name] = (
                generic_layout(part if len(part) else every, name),
                f"Laid out from its cell keys: {why}.",
            )
        else:
            out[name] = (layout, "")
    return out


def protocol_order(found: dict[str, tuple[ShownLayout, str]]) -> list[str]:
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
    """The plugin ids of the rows' detectors that are the registered reference (the baseline
    every table compares against), as the rows record it (``detector_reference``)."""
    if "detector_reference" not in rows:
        return []
    ids = rows[ENTRANT_ID] if ENTRANT_ID in rows else rows["detector"]
    flagged = rows["detector_reference"].astype("boolean").fillna(False).to_numpy(bool)
    return sorted(ids[flagged].dropna().astype(str).unique())


@dataclass(frozen=True)
class Split:
    """A protocol's cells of one split (``name``: grouped, paper, ...): their rows and the
    parts of them each table of every detector shows (:func:`split_parts`)."""

    name: str
    rows: pd.DataFrame
    parts: list[tuple[dict, pd.DataFrame]]


@dataclass(frozen=True)
class Section:
    """One protocol's section of a report: its layout, the note where that is the cell keys'
    (:func:`layouts`), why some of its data made no cell (:func:`no_cell_note`; "" where all
    did), and its cells: their rows, the same per split (:func:`splits_of`), and their
    detectors in the tables' order."""

    protocol: str
    layout: ShownLayout
    note: str
    no_cell: str
    cells: pd.DataFrame
    splits: list[Split]
    detectors: list[str]


@dataclass(frozen=True)
class Outline:
    """What a report is made of, decided once before any table is drawn.

    Attributes
    ----------
    rows : every row, each detector named as its entrant
        (:func:`~slipbench.stats.factors.named_entrants`), each unit as it was tested
        (:func:`as_tested`), rows tested on a simulation whose force direction gives slip away
        flagged (:data:`~slipbench.report.notes.SIMULATED`).
    cells : those rows without the stand-ins of protocols that made no cell.
    stored : the cells as the rows store them (detectors by plugin id), for the section that
        pairs a detector's inputs.
    found : each protocol's layout and its note.
    sections : the protocols in the paper's order (:func:`protocol_order`).
    splits : the splits of the rows, the one the leaderboard and the findings rank first.
    lead : the cells of that split.
    reference : the reference detectors (:func:`references`).
    resolved : the rows as tested, resolved once (:func:`slipbench.store.resolved.resolve`):
        every part of ``rows`` carries what it computed.
    """

    rows: pd.DataFrame
    cells: pd.DataFrame
    stored: pd.DataFrame
    found: dict[str, tuple[ShownLayout, str]]
    sections: list[Section]
    splits: list[str]
    lead: pd.DataFrame
    reference: list[str]
    resolved: Resolved

    @property
    def order(self) -> list[str]:
        return [s.protocol for s in self.sections]


def _section(rows: pd.DataFrame, protocol: str, found: tuple[ShownLayout, str]) -> Section:
    mine = rows[rows["protocol"] == protocol]
    standing = stand_ins(mine)
    datasets = mine["dataset_fingerprint"].nunique() if "dataset_fingerprint" in mine else 1
    no_cell = no_cell_note(mine[standing], datasets) if standing.any() else ""
    cells = mine[~standing]
    detectors = rank(cells["detector"].unique(), DETECTOR_ORDER)
    layout = found[0]
    splits = (
        [Split(s, r, split_parts(r, layout)) for s, r in splits_of(cells)] if len(cells) else []
    )
    return Section(protocol, *found, no_cell, cells, splits, detectors)


def outline(rows: pd.DataFrame, found: dict[str, tuple[ShownLayout, str]] | None = None) -> Outline:
    """The :class:`Outline` of a report of ``rows``; ``found``: each protocol's layout and note
    (default: :func:`layouts`)."""
    stored = rows[~stand_ins(rows)]
    resolved = resolve(as_tested(rows).assign(**{SIMULATED: on_simulation(rows)}))
    rows = named_entrants(resolved.rows)
    found = layouts(rows) if found is None else found
    cells = rows[~stand_ins(rows)]
    splits = splits_of(rows)
    lead = splits[0][1]
    return Outline(
        rows,
        cells,
        stored,
        found,
        [_section(rows, p, found[p]) for p in protocol_order(found)],
        [s for s, _ in splits],
        lead[~stand_ins(lead)],
        references(cells),
        resolved,
    )
