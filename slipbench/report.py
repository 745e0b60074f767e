"""Result rows -> whole reports: every table the rows allow, each protocol's in its own layout,
optionally beside the paper's numbers. Reads only result rows and the protocols' layouts.
"""

from __future__ import annotations

import json

import pandas as pd

from .errors import SlipbenchError
from .paper import paper_frame, table_order
from .protocol import Layout
from .render import standalone_latex, to_latex, to_markdown
from .tables import Table, baseline_table, build_table, fits, generic_layout, metrics_table, rank, rates_table

DETECTOR_ORDER = ("holweg", "lstm")  # the paper's baseline, then its model; others follow by name
SPLIT_ORDER = ("plain", "lag", False, True)  # the paper's decimation first, without a filter first


def layouts(rows: pd.DataFrame) -> dict[str, tuple[Layout, str]]:
    """Each protocol's layout, from its class in the registry (built-in, entry point or plugin
    folder) made with the options its rows ran with, and a note when it fell back to a layout
    from the cell keys (the protocol cannot be loaded, or its layout does not fit its rows)."""
    from .registry import protocols

    out = {}
    for name in rows["protocol"].unique():
        part = rows[rows["protocol"] == name]
        try:
            cls = protocols.get(name)
            params = json.loads(part["protocol_params"].iloc[0]) if "protocol_params" in part else {}
            layout, why = cls(**params).layout, ""
            why = fits(layout, part)
        except (SlipbenchError, TypeError, ValueError, json.JSONDecodeError) as exc:
            layout, why = None, f"protocol {name!r} could not be loaded ({exc}); pass its plugin folder with --plugins"
        if why:
            out[name] = (generic_layout(part, name), f"Laid out from its cell keys: {why}.")
        else:
            out[name] = (layout, "")
    return out


def protocol_order(found: dict[str, tuple[Layout, str]]) -> list[str]:
    """Protocols laid out as the paper's tables first, in the paper's order, then the others."""
    paper_order = table_order()
    return sorted(found, key=lambda p: (
        paper_order.index(found[p][0].paper_table) if found[p][0].paper_table in paper_order else len(paper_order), p))


def _sections(rows: pd.DataFrame, found: dict[str, tuple[Layout, str]]) -> list[tuple[str, str, str, pd.DataFrame]]:
    """(protocol, detector, split, rows): the paper's protocols in its order, then the others."""
    out = []
    for protocol in protocol_order(found):
        prows = rows[rows["protocol"] == protocol]
        for detector in rank(prows["detector"].unique(), DETECTOR_ORDER):
            drows = prows[prows["detector"] == detector]
            for split in rank(drows["split"].unique() if "split" in drows else ["paper"], ("paper", "grouped")):
                out.append((protocol, detector, split, drows[drows["split"] == split] if "split" in drows else drows))
    return out


def split_parts(rows: pd.DataFrame, layout: Layout) -> list[tuple[dict, pd.DataFrame]]:
    """The rows of each table: one part per combination of the layout's ``split`` columns
    (those the rows hold), named by its values; the rows whole when there are none."""
    splits = [c for c in layout.splits if c in rows]
    if not splits:
        return [({}, rows)]
    parts = [(dict(zip(splits, k if isinstance(k, tuple) else (k,))), part)
             for k, part in rows.groupby(splits if len(splits) > 1 else splits[0], sort=False, dropna=False)]
    for c in reversed(splits):  # stable sorts, last column first: lexicographic order
        order = rank([w[c] for w, _ in parts], SPLIT_ORDER)
        parts.sort(key=lambda p: order.index(p[0][c]))
    return parts


def protocol_tables(rows: pd.DataFrame, layout: Layout, protocol: str, detector: str, metric: str = "accuracy",
                    intervals: bool = False, paper: bool = False) -> list[tuple[str, Table]]:
    """The tables of one protocol and detector: one per ``split`` value of the layout (e.g.
    decimation), each followed, with ``paper``, by the published table and the difference."""
    ref = paper_frame(layout.paper_table) if paper and layout.paper_table else None
    out = []
    for which, part in split_parts(rows, layout):
        tag = "-".join([f"{protocol}-{detector}", *(str(v) for v in which.values())])
        suffix = f" ({', '.join(f'{c}: {v}' for c, v in which.items())})" if which else ""
        table = build_table(part, layout, metric, intervals, label_=f"tab:{tag}")
        table.caption += "".join(f" {c.capitalize()}: {v}." for c, v in which.items())
        out.append((f"{detector}{suffix}", table))
        if layout.metrics and "stream_s" in part:
            table.notes.append(_stream_note(part))
        if layout.metrics and any(f"op_{m}" in part for m in layout.metrics):
            out.append((f"{detector}{suffix}, operating point", _operating_point(part, layout, intervals, f"tab:{tag}-op")))
        if ref is not None and len(ref) and metric == "accuracy":
            cap = "Published (Van Wyk & Falco, LSTM): " + layout.caption[0].lower() + layout.caption[1:]
            pt = build_table(part, layout, metric, values="paper", paper=ref, label_=f"tab:{tag}-paper")
            pt.caption = cap
            if layout.paper_table == "sampling-rate":
                pt.notes.append("The full-rate column is Table I at window 200, the same setting.")
            dt = build_table(part, layout, metric, values="difference", paper=ref, label_=f"tab:{tag}-difference")
            dt.caption = f"Ours ({detector}) minus published (LSTM)."
            out += [(f"paper{suffix}", pt), (f"{detector} - paper{suffix}", dt)]
    return out


def _stream_note(rows: pd.DataFrame) -> str:
    """How the recordings were streamed, from the rows."""
    def values(column: str) -> str:
        return ", ".join(str(v) for v in rank(rows[column].dropna().unique())) if column in rows else "?"
    return (f"Streamed: window {values('window')} samples, a score every {values('hop')} samples; whole test trials, "
            f"held out from training by trial (seed {values('seed')}) whatever the run's split. Delays include the "
            f"compute time per hop measured on this machine ({rows['compute_ms'].median():.3f} ms median).")


def _operating_point(rows: pd.DataFrame, layout: Layout, intervals: bool, label_: str) -> Table:
    """A streaming table at the operating point (``op_`` columns): the threshold that keeps 1
    false alarm per minute on the training trials' streams, evaluated on the test trials."""
    budget = rows["op_budget_per_min"].dropna() if "op_budget_per_min" in rows else pd.Series(dtype=float)
    per_min = f"{budget.iloc[0]:g}" if len(budget) else "1"
    table = metrics_table(rows, layout, layout.metrics, intervals, label_, prefix="op_",
                          group=f"At {per_min} false alarm per minute (threshold chosen on the training trials' streams)")
    notes = rows["op_note"].dropna() if "op_note" in rows else pd.Series(dtype=str)
    for note in sorted(set(notes) - {""}):
        table.notes.append(f"NA: {note}.")
    return table


def render_report(rows: pd.DataFrame, fmt: str = "md", metric: str = "accuracy", intervals: bool = False,
                  paper: bool = False, standalone: bool = False,
                  found: dict[str, tuple[Layout, str]] | None = None) -> str:
    """Every table the rows allow, in the paper's order, as one Markdown or LaTeX text.

    ``found``: each protocol's layout and fallback note (default: :func:`layouts`)."""
    found = layouts(rows) if found is None else found
    render = to_markdown if fmt == "md" else to_latex
    blocks: list[str] = []
    for protocol, detector, split, part in _sections(rows, found):
        layout, note = found[protocol]
        tables = protocol_tables(part, layout, protocol, detector, metric, intervals, paper)
        if note:
            tables[0][1].notes.append(note)
        blocks.append(f"## {protocol}: {detector} (split {split})" if fmt == "md" else f"% {protocol}: {detector} (split {split})")
        blocks += [render(t) for _, t in tables]
    table_one = [p for p, (layout, _) in found.items() if layout.paper_table == "window-size"]
    if table_one and "window" in rows:
        one = rows[rows["protocol"].isin(table_one)]
        extra = [baseline_table(one, intervals, paper)]
        extra += [rates_table(one, d, intervals, paper) for d in rank(one["detector"].unique(), DETECTOR_ORDER)]
        extra = [t for t in extra if t is not None]
        if extra:
            blocks.append("## At window 50: baseline and TP/TN rates" if fmt == "md" else "% at window 50")
            blocks += [render(t) for t in extra]
    text = "\n\n".join(blocks) + "\n"
    return standalone_latex(text) if fmt == "latex" and standalone else text


def protocol_table(rows: pd.DataFrame, layout: Layout, intervals: bool = False) -> str:
    """The Markdown table(s) of one protocol's rows for one detector (what ``evaluate`` prints)."""
    rows = pd.DataFrame(rows)
    if rows.empty:
        return "(no cells)"
    protocol, detector = str(rows["protocol"].iloc[0]), str(rows["detector"].iloc[0])
    why = fits(layout, rows)
    tables = protocol_tables(rows, generic_layout(rows, protocol) if why else layout, protocol, detector, intervals=intervals)
    return "\n\n".join(to_markdown(t) for _, t in tables)
