"""Result rows -> whole reports (Markdown, LaTeX, HTML). Reads only result rows and the
protocols' layouts.

Every report has the same outline:

1. what it stands on (:mod:`slipbench.report.provenance`): data source, fingerprint, split, labels,
   seeds, detectors with parameters, cells, the smallest test set;
2. the leaderboard (:mod:`slipbench.stats.leaderboard`, its tables
   :mod:`slipbench.report.leaderboard`) and its critical-difference diagram, one per setting
   that differs (:mod:`slipbench.stats.factors`); the test sets of one class, which none ranks;
   with ``paper``, how the paper's findings fare (:mod:`slipbench.report.findings`);
3. what fitting chose, and its warnings;
4. per protocol, in the paper's order: every detector side by side (with the figure that
   overlays them), then each detector's tables in the protocol's own layout and its figure;
   with ``paper``, the published table once and, for the paper's model, ours minus published;
5. the paper's extra tables at window 50 (baseline, TP/TN rates);
6. where a detector ran with both inputs, what the reduction keeps: its channels cells against
   their univariate twins (:mod:`slipbench.report.reduction`).

``leaderboard_only`` stops after 2. Each detector's own blocks (what fitting chose for it, its
tables and figures of a protocol, its TP/TN rates), every detector side by side on a split after
the first and the published tables are :class:`Detail`: inline in the whole report, or moved to
an appendix by :func:`split_appendix` so that the summary stays short however many splits and
detectors it holds.
"""

from __future__ import annotations

import dataclasses
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import pandas as pd

from slipbench.protocol import Layout
from slipbench.report.blocks import OWN, Detail, Heading, Link, Table, Text
from slipbench.report.leaderboard import (
    leaderboard_tables,
    one_class_table,
    versus_baseline,
    versus_column,
)
from slipbench.report.meta import meta_blocks
from slipbench.report.notes import SIMULATED, simulation_note
from slipbench.report.order import rank
from slipbench.report.outline import (
    Section,
    Split,
    as_tested,
    layouts,
    no_cell_note,
    outline,
    protocol_order,
    references,
    split_parts,
    stand_ins,
    which_text,
)
from slipbench.report.paper import paper_frame
from slipbench.report.presentation import ShownLayout
from slipbench.report.provenance import fitted_tables, header_tables, on_simulation
from slipbench.report.reduction import reduction_blocks
from slipbench.report.render import Drawn, renderer
from slipbench.report.tables import (
    TableValues,
    baseline_table,
    build_table,
    compute_table,
    metrics_table,
    rates_table,
    side_by_side,
    split_table,
    table_keys,
)
from slipbench.stats.factors import setting_parts
from slipbench.stats.leaderboard import leaderboard
from slipbench.vocabulary import DETECTOR_ORDER, SENSOR_TYPE

OTHER_SPLITS = "every detector on the other splits"  # what a summary's link names
PUBLISHED = "the published table"
PAPER_DETECTOR = (
    "lstm"  # the published tables are this detector's: only its tables get "ours minus published"
)


@dataclass(frozen=True)
class ReportOptions:
    """What a report shows. ``metric``: the figure the tables show and the leaderboard ranks;
    ``intervals``: 95 % intervals; ``paper``: the published tables, differences and findings;
    ``leaderboard_only``: the header and the leaderboard only; ``with_figures``: the
    :class:`~slipbench.report.plots.FigureSpec` blocks; ``benchmark``: the benchmark file the
    rows come from, named in the header; ``predictions``: results folders holding the cells'
    test predictions (intervals pooled over seeds and fingers by one joint bootstrap);
    ``superseded``: rows left out because their cell and seed was run again later, named in the
    header (:func:`slipbench.stats.factors.latest_runs`); ``unproven``: the results files the
    rows come from that carry no row digests, named in a line under the header (edits to them
    cannot be detected).

    Report functions take these as keywords (``build_report(rows, intervals=True)``) and build
    one object of them, as a command does of its options."""

    metric: str = "accuracy"
    intervals: bool = False
    paper: bool = False
    leaderboard_only: bool = False
    with_figures: bool = False
    benchmark: str = ""
    predictions: Sequence[str | os.PathLike] = ()
    superseded: int = 0
    unproven: Sequence[str] = ()


def _unproven(files: Sequence[str]) -> list[Text]:
    """The line that says which rows cannot be proved (files without row digests)."""
    if not files:
        return []
    return [
        Text(
            f"Rows from files without row digests (another tool or an older slipbench wrote "
            f"them): {', '.join(Path(f).name for f in files)}: edits to "
            f"{'it' if len(files) == 1 else 'them'} cannot be detected; their figures were "
            "checked against the ranges of the results schema."
        )
    ]


def flatten(blocks: list) -> list:
    """The blocks with every :class:`Detail` inline: the whole report."""
    out: list = []
    for block in blocks:
        out += block.blocks if isinstance(block, Detail) else [block]
    return out


def _anchor(heading: str) -> str:
    """A Markdown heading's anchor as GitHub and most renderers make it."""
    return re.sub(r"[^\w\- ]", "", heading.lower()).replace(" ", "-")


def _listed(parts: list[str]) -> str:
    """``a``, ``a and b``, ``a, b and c``."""
    return parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + " and " + parts[-1]


def split_appendix(
    blocks: list, appendix: str, fmt: str = "md", summary_path: str = ""
) -> tuple[list, list]:
    """(summary, appendix): the report without its :class:`Detail` blocks, each section that
    had some pointing to ``appendix`` (the appendix's path as the summary links it) and naming
    what went there, and the appendix: those blocks under their sections' headings, pointing
    back to ``summary_path`` (the summary's path as the appendix links it; "" where the summary
    has no file). Links name their target where format ``fmt`` links files, else they show
    their label."""
    links = renderer(fmt).cross_links
    whats: dict[str, list[str]] = {}
    for block in blocks:  # the link says all that its section moved, wherever it stands
        if isinstance(block, Detail) and block.what not in whats.setdefault(block.section, []):
            whats[block.section].append(block.what)
    summary: list = []
    sections: dict[str, list] = {}
    for block in blocks:
        if not isinstance(block, Detail):
            summary.append(block)
            continue
        if block.section not in sections:
            summary.append(
                Text(
                    f"In the appendix, {_listed(whats[block.section])} of this section: ",
                    Link(f"{appendix}, {block.section}", f"{appendix}#{_anchor(block.section)}")
                    if links
                    else Link(f"{appendix}, section {block.section}", ""),
                    ".",
                )
            )
        sections.setdefault(block.section, []).extend(block.blocks)
    back = Link(summary_path, summary_path if links else "") if summary_path else None
    # each detector's own first, the rest as they first come
    moved = sorted(dict.fromkeys(w for ws in whats.values() for w in ws), key=lambda w: w != OWN)
    rest: list = [
        Heading("slipbench report: appendix", 1),
        Text(
            f"What the summary{' (' if back else ''}",
            back,
            (")" if back else "")
            + f" leaves out, section by section: {_listed(moved or [OWN])}. The summary says "
            "what data and settings stand behind them.",
        ),
    ]
    for section, parts in sections.items():
        rest += [Heading(section, 2), *parts]
    return summary, rest


def protocol_tables(
    rows: pd.DataFrame,
    layout: ShownLayout,
    protocol: str,
    detector: str,
    split: str = "",
    **options,
) -> list[tuple[str, Table]]:
    """The tables of one protocol and detector: one per ``split`` value of the layout (e.g.
    decimation), captions naming the detector and protocol. ``options``: :class:`ReportOptions`.
    With ``paper``, the paper's model (PAPER_DETECTOR) gets ours minus published after each; the
    published table itself is :func:`published_table`, shown once per protocol. With
    ``intervals``, figures run under several seeds get one interval pooled over the seeds from
    their ``predictions`` folders."""
    o = ReportOptions(**options)
    metric, intervals, predictions = o.metric, o.intervals, o.predictions
    ref = (
        paper_frame(layout.paper_table)
        if o.paper and layout.paper_table and detector == PAPER_DETECTOR
        else None
    )
    named = (
        f"Detector {detector}, protocol {protocol}" + (f", {split} split" if split else "") + "."
    )
    out = []
    for which, part in split_parts(rows, layout):
        tag = "-".join(
            [
                f"{protocol}-{detector}",
                *([split] if split and split != "paper" else []),
                *(str(v) for v in which.values()),
            ]
        )
        suffix = f" ({', '.join(f'{c}: {v}' for c, v in which.items())})" if which else ""
        table = build_table(
            part,
            layout,
            metric,
            intervals,
            TableValues(pooled=_pooled(part, layout, predictions) if intervals else None),
        )
        table.label = f"tab:{tag}"
        table.caption += which_text(which)
        table.subject = named
        out.append((f"{detector}{suffix}", table))
        if layout.metrics and "stream_s" in part:
            table.notes.append(_stream_note(part))
        if layout.metrics and any(f"op_{m}" in part for m in layout.metrics):
            out.append(
                (
                    f"{detector}{suffix}, operating point",
                    _operating_point(part, layout, intervals, f"tab:{tag}-op"),
                )
            )
        compute = compute_table(part, layout, f"tab:{tag}-compute") if layout.metrics else None
        if compute is not None:
            compute.caption += which_text(which)
            compute.subject = named
            out.append((f"{detector}{suffix}, compute per hop", compute))
        if ref is not None and len(ref) and metric == "accuracy":
            dt = build_table(part, layout, metric, shown=TableValues("difference", ref))
            dt.label = f"tab:{tag}-difference"
            dt.caption = (
                f"Ours minus published, {detector} against the paper's LSTM.{which_text(which)}"
            )
            dt.subject = named
            out.append((f"{detector} - paper{suffix}", dt))
    return out


def _pooled(
    rows: pd.DataFrame, layout: Layout, predictions: Sequence[str | os.PathLike]
) -> dict[tuple, dict]:
    """Per figure of the table that ran under several seeds: the joint bootstrap of its seeds."""
    if not predictions or layout.metrics or "seed" not in rows or rows["seed"].nunique() < 2:
        return {}
    from slipbench.stats.joint import joint_means

    keys = table_keys(rows, layout)
    repeated = rows.groupby(keys, dropna=False)["seed"].transform("nunique") > 1
    return joint_means(rows[repeated], keys, predictions)


def _stream_note(rows: pd.DataFrame) -> str:
    """How the recordings were streamed, from the rows."""

    def values(column: str) -> str:
        return (
            ", ".join(str(v) for v in rank(rows[column].dropna().unique()))
            if column in rows
            else "?"
        )

    head = (
        f"Streamed: window {values('window')} samples, a score every {values('hop')} samples; whole test trials, "
        f"held out from training by trial (seed {values('seed')}) whatever the run's split. "
    )
    old = rows["compute_ms"].dropna() if "compute_ms" in rows else pd.Series(dtype=float)
    if len(old) and ("compute_ms_per_hop" not in rows or rows["compute_ms_per_hop"].isna().all()):
        # rows of an older slipbench: their delays hold their machine's compute time
        return head + (
            "Delays include the compute time per hop measured on the machine that ran the cells "
            f"({old.median():.3f} ms median): rows written before delays were counted on the stream alone."
        )
    return head + (
        "Delays are counted on the stream: from the onset's sample to the alarm's, at the sampling "
        "rate, so they are the same on every machine; the compute time per hop is checked apart, "
        "against the hop period."
    )


def _operating_point(
    rows: pd.DataFrame, layout: ShownLayout, intervals: bool, label_: str
) -> Table:
    """A streaming table at the operating point (``op_`` columns): the threshold that keeps 1
    false alarm per minute on the training trials' streams, evaluated on the test trials."""
    budget = (
        rows["op_budget_per_min"].dropna()
        if "op_budget_per_min" in rows
        else pd.Series(dtype=float)
    )
    per_min = f"{budget.iloc[0]:g}" if len(budget) else "1"
    table = metrics_table(rows, layout, layout.metrics, intervals, prefix="op_")
    table.label = label_
    table.group = (
        f"At {per_min} false alarm per minute (threshold chosen on the training trials' streams)"
    )
    notes = rows["op_note"].dropna() if "op_note" in rows else pd.Series(dtype=str)
    for note in sorted(set(notes) - {""}):
        table.notes.append(f"NA: {note}.")
    return table


def published_table(rows: pd.DataFrame, layout: ShownLayout, protocol: str) -> Table | None:
    """The published table (the paper's LSTM) laid out on the cells of ``rows``, or None where
    the layout names no paper table."""
    ref = paper_frame(layout.paper_table) if layout.paper_table else None
    if ref is None or not len(ref):
        return None
    part = split_parts(rows, layout)[0][1]
    table = build_table(part, layout, shown=TableValues("paper", ref))
    table.label = f"tab:{protocol}-paper"
    table.caption = (
        f"Published (Van Wyk & Falco, their LSTM): {table.caption[0].lower()}{table.caption[1:]}"
    )
    if layout.column_label:
        table.notes.append("The full-rate column is Table I at window 200, the same setting.")
    return table


def _every_detector(
    section: Section, split: Split, o: ReportOptions, reference: Sequence[str]
) -> list:
    """The tables that set every detector of a protocol side by side, one per part of a split,
    each with its change from the ``reference`` detector where that ran."""
    protocol, layout, tables = section.protocol, section.layout, []
    for which, part in split.parts:
        tag = [protocol, "detectors", *([split.name] if split.name != "paper" else [])]
        table = side_by_side(
            part,
            layout,
            [d for d in section.detectors if d in set(part["detector"])],
            o.metric,
            label_="tab:" + "-".join([*tag, *(str(v) for v in which.values())]),
        )
        if table is not None:
            table.caption += which_text(which)
            table.subject = f"Protocol {protocol}, {split.name} split."
            if "detector" not in table_keys(part, layout):
                versus_column(table, part, reference, o.predictions, o.metric)
            tables.append(table)
    return tables


def _side_by_side(
    section: Section, o: ReportOptions, figures: list, reference: Sequence[str]
) -> list:
    """Every detector of a protocol side by side: the lead split's tables and figure, then
    each other split's as :class:`Detail` (a summary leads with one split, as its leaderboard
    does; the splits side by side say how the others differ)."""
    protocol, splits = section.protocol, [split.name for split in section.splits]
    blocks: list = []
    for n, split in enumerate(section.splits):
        side = _every_detector(section, split, o, reference)
        side += [f for f in figures if f.detector is None and f.split == split.name]
        named = f" ({split.name} split)" if len(splits) > 1 else ""
        heading = Heading(f"{protocol}: every detector{named}", 3)
        if n == 0:
            blocks += [heading, *side]
        elif side:
            blocks.append(Detail(protocol, [heading, *side], OTHER_SPLITS))
    return blocks + [f for f in figures if f.detector is None and f.split not in splits]


def _protocol_blocks(
    section: Section, o: ReportOptions, figures: list, reference: Sequence[str]
) -> list:
    """A protocol's section: why some of its data made no cell, its layout's note, every
    detector side by side (with ``figures`` of them all), the published table, then each
    detector's own tables and figures."""
    protocol, layout = section.protocol, section.layout
    blocks: list = [Heading(protocol, 2)]
    if section.no_cell:  # the protocol made no cell on (some of) the data: say why
        blocks.append(Text(section.no_cell))
    if section.cells.empty:
        return blocks
    if section.note:
        blocks.append(Text(section.note))
    if len(section.detectors) > 1:
        blocks += _side_by_side(section, o, figures, reference)
    if o.paper:
        published = published_table(section.cells, layout, protocol)
        if published is not None:
            blocks.append(
                Detail(protocol, [Heading(f"{protocol}: published", 3), published], PUBLISHED)
            )
    for split in section.splits:
        for detector in section.detectors:
            drows = split.rows[split.rows["detector"] == detector]
            if drows.empty:
                continue
            detail: list = [Heading(f"{protocol}: {detector} ({split.name} split)", 3)]
            detail += [
                t
                for _, t in protocol_tables(
                    drows, layout, protocol, detector, split.name, **dataclasses.asdict(o)
                )
            ]
            detail += [f for f in figures if f.detector == detector and f.split == split.name]
            blocks.append(Detail(protocol, detail))
    return blocks


def build_report(
    rows: pd.DataFrame, found: dict[str, tuple[ShownLayout, str]] | None = None, **options
) -> list:
    """The report as blocks (:class:`Heading`, :class:`Text`, tables, and, with
    ``with_figures``, :class:`~slipbench.report.plots.FigureSpec`), in the module's outline.
    ``found``: each protocol's layout and fallback note (default: :func:`layouts`);
    ``options``: :class:`ReportOptions`. With ``intervals`` and ``predictions``, means over
    fingers and over seeds get one joint bootstrap over the trials they share.
    A detector run on the raw channels competes as its own entrant, ``tcn (channels)``, in
    every table, leaderboard and finding; the last section pairs it with its univariate twin."""
    o = ReportOptions(**options)
    metric, intervals, paper, with_figures = o.metric, o.intervals, o.paper, o.with_figures
    predictions = o.predictions
    made = outline(rows, found)
    cells, lead, splits = made.cells, made.lead, made.splits
    figures: dict[str | None, list] = {}
    if with_figures:
        from slipbench.report.plots import figure_specs

        for spec in figure_specs(made, paper):
            figures.setdefault(spec.section, []).append(spec)
    blocks: list = [
        Heading("slipbench report", 1),
        Heading("What this report stands on", 2),
        *header_tables(made.rows, metric, made.order, o.benchmark, o.superseded),
        *_unproven(o.unproven),
        Heading("Leaderboard", 2),
    ]
    side = (
        split_table(cells, splits, metric, made.order, DETECTOR_ORDER) if len(splits) > 1 else None
    )
    if len(splits) > 1:
        blocks.append(
            Text(
                f"{'The leaderboard and the findings rank' if paper else 'The leaderboard ranks'} the {splits[0]} split"
                + (
                    f"; the table after the leaderboard sets the {splits[1]} split beside it."
                    if side
                    else "."
                )
            )
        )
    blocks += _leaderboards(lead, metric, made.order, with_figures, predictions)
    lone = one_class_table(cells)  # ranked in no split
    if lone is not None:
        blocks += [Heading("Test sets of one class", 2), lone]
    if side is not None:
        blocks += [Heading("The splits side by side", 2), side]
    if o.leaderboard_only:
        return blocks
    if paper:
        blocks += _findings(lead, made.found, made.order)
    fitted = fitted_tables(cells)
    if fitted:
        # each detector's choices are detail; the warnings about them stay in the summary
        own = [t for t in fitted if t.label.startswith("tab:fitted-")]
        blocks += [Heading("What fitting chose", 2)]
        blocks += [Detail("What fitting chose", own)] if own else []
        blocks += [t for t in fitted if not t.label.startswith("tab:fitted-")]
    for section in made.sections:
        blocks += _protocol_blocks(section, o, figures.get(section.protocol, []), made.reference)
    table_one = [s.protocol for s in made.sections if s.layout.paper_table == "window-size"]
    if table_one and "window" in lead:
        title = "At window 50: accuracy and TP/TN rates" + (
            f", {splits[0]} split" if len(splits) > 1 else ""
        )
        blocks += _window_50(
            lead[lead["protocol"].isin(table_one)], title, intervals, paper, predictions
        )
    blocks += meta_blocks(cells, made.reference, predictions, with_figures)
    return blocks + reduction_blocks(made.stored, predictions, with_figures)


def _tag(which: dict) -> str:
    """A part's values (:func:`~slipbench.stats.factors.setting_parts`) for labels and stems."""
    return "".join(f"-{v}" for v in which.values())


def _name_part(table: Table, which: dict) -> None:
    """A table of one part of the rows says which, in its caption and its label."""
    table.caption += which_text(which)
    table.label += _tag(which)


def _leaderboards(
    rows: pd.DataFrame,
    metric: str,
    order: list[str],
    with_figures: bool,
    predictions: Sequence[str | os.PathLike],
) -> list:
    """The leaderboard of ``rows`` (and its critical-difference diagram), with the line to beat:
    one per combination of the settings that differ between them, so that no mean or test
    pools two of them."""
    blocks: list = []
    for which, part in setting_parts(rows):
        board = leaderboard(part, metric, protocols=order)
        tables = leaderboard_tables(board)
        versus_baseline(tables, part, predictions, metric)
        for table in tables:
            _name_part(table, which)
        tables[-1 if len(tables) == 1 else 1].notes += simulation_note(part)  # under the means
        blocks += tables
        if with_figures:
            from slipbench.report.plots import leaderboard_specs

            blocks += leaderboard_specs(board, which_text(which), _tag(which))
    return blocks


def _findings(
    rows: pd.DataFrame, found: dict[str, tuple[ShownLayout, str]], order: list[str]
) -> list:
    """How the paper's findings fare on ``rows``: one pair of tables per combination of the
    settings that differ between them."""
    from slipbench.report.findings import findings_table, paper_findings_table

    tables = []
    for which, part in setting_parts(rows):
        for table in (paper_findings_table(part, found), findings_table(part, found, order)):
            if table is not None:
                _name_part(table, which)
                tables.append(table)
    return [Heading("The paper's findings, ours beside them", 2), *tables] if tables else []


def _window_50(
    rows: pd.DataFrame,
    title: str,
    intervals: bool,
    paper: bool,
    predictions: Sequence[str | os.PathLike],
) -> list:
    """Every detector's accuracy (the registered reference named as the baseline) and the TP/TN
    rates at window 50 of the rows of protocols laid out as the paper's Table I: one set per
    combination of the settings that differ between them."""
    from slipbench.report.tables import BASELINE_WINDOW

    blocks: list = []
    for which, one in setting_parts(rows):
        joint = None
        if intervals and predictions:
            from slipbench.stats.joint import joint_means

            joint = joint_means(
                one[one["window"] == BASELINE_WINDOW], ["detector", SENSOR_TYPE], predictions
            )
        tables = [baseline_table(one, intervals, paper, joint, references(one))]
        rates = [
            rates_table(one, d, intervals, paper, joint)
            for d in rank(one["detector"].unique(), DETECTOR_ORDER)
        ]
        for table in (t for t in [*tables, *rates] if t is not None):
            _name_part(table, which)
        rates = [t for t in rates if t is not None]
        blocks += [t for t in tables if t is not None]
        blocks += [Detail(title, rates)] if rates else []
    return [Heading(title, 2), *blocks] if blocks else []


# ----------------------------------------------------------------------------- rendering
def write_figures(blocks: list, folder: str | os.PathLike) -> dict[str, list[Path]]:
    """Draw every figure of ``blocks`` into ``folder`` (PNG and PDF); stem -> paths."""
    from slipbench.report.plots import FigureSpec, save

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    out = {}
    for block in flatten(blocks):
        if isinstance(block, FigureSpec):
            fig = block.draw()
            if fig is not None:
                out[block.stem] = save(fig, folder, block.stem)
    return out


def _png(block, files: dict[str, list[Path]]) -> bytes | None:
    """The figure as PNG bytes: from its file where drawn already, else drawn now."""
    from io import BytesIO

    from slipbench.report.plots import DPI

    for path in files.get(block.stem, []):
        if path.suffix == ".png":
            return path.read_bytes()
    fig = block.draw()
    if fig is None:
        return None
    buffer = BytesIO()
    fig.savefig(buffer, format="png", dpi=DPI)
    return buffer.getvalue()


def render(
    blocks: list,
    fmt: str = "md",
    standalone: bool = False,
    files: dict[str, list[Path]] | None = None,
    link_from: str | os.PathLike | None = None,
) -> str:
    """Blocks as one text in format ``fmt`` (:data:`~slipbench.report.render.FORMATS`), by
    that format's renderer.

    ``files``: figures drawn already (stem -> paths, from :func:`write_figures`): Markdown links
    them (relative to ``link_from``, the report's folder), LaTeX includes their PDF. HTML embeds
    every figure as a base64 PNG, drawing those not drawn yet: one self-contained page.
    """
    from slipbench.report.plots import FigureSpec

    out = renderer(fmt, standalone)
    files = files or {}
    base = Path(link_from) if link_from is not None else Path.cwd()
    parts = []
    for block in flatten(blocks):
        if isinstance(block, Heading):
            parts.append(out.heading(block))
        elif isinstance(block, Text):
            parts.append(out.paragraph(block))
        elif isinstance(block, Table):
            parts.append(out.table(block))
        elif isinstance(block, FigureSpec):
            paths = {
                p.suffix: Path(os.path.relpath(p, base)).as_posix()
                for p in files.get(block.stem, [])
            }
            parts.append(
                out.figure(Drawn(block.stem, block.caption, paths, partial(_png, block, files)))
            )
    return out.document([p for p in parts if p])


def protocol_table(rows: pd.DataFrame, intervals: bool = False) -> str:
    """The Markdown table(s) of one protocol's rows for one detector (what ``evaluate`` prints),
    in the layout the rows record (:func:`~slipbench.report.outline.layouts`)."""
    rows = pd.DataFrame(rows)
    if rows.empty:
        return "(no cells)"
    standing = stand_ins(rows)
    if standing.all():
        return no_cell_note(rows)
    rows = as_tested(rows[~standing])
    rows = rows.assign(**{SIMULATED: on_simulation(rows)})
    protocol, detector = str(rows["protocol"].iloc[0]), str(rows["detector"].iloc[0])
    layout, _ = layouts(rows)[protocol]
    tables = protocol_tables(rows, layout, protocol, detector, intervals=intervals)
    markdown = renderer("md")
    return "\n\n".join(markdown.table(t) for _, t in tables)


__all__ = [
    "Detail",
    "Heading",
    "ReportOptions",
    "Text",
    "build_report",
    "layouts",
    "protocol_order",
    "protocol_table",
    "protocol_tables",
    "published_table",
    "render",
    "split_appendix",
    "split_parts",
    "write_figures",
]
