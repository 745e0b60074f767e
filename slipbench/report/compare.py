"""`slipbench compare` said: the pull-request comment (Markdown) and the JSON for bots.

The decisions (paired intervals, per-cell and summary verdicts, the exit code) are made by
:mod:`slipbench.gate.compare`; this module only writes them down: cells in the paper's order
(protocols as the paper's tables, then sensors, fingers, materials as the tables list them),
short cell labels, the verdicts' marks, and a comment held under the size a pull request takes.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pandas as pd

from slipbench.errors import UsageError
from slipbench.gate.compare import (
    ALPHA,
    CELL_ALPHA,
    POOLED_ALPHA,
    VERDICTS,
    Comparison,
    level_text,
    primary_change,
    repeats_note,
    summary,
)
from slipbench.gate.gate import Gate, unit
from slipbench.report.markdown import md_code, md_table, md_text
from slipbench.report.outline import layouts, protocol_order
from slipbench.stats.contrast import family_level
from slipbench.stats.factors import SETTINGS, setting_text
from slipbench.store import columns
from slipbench.store.columns import FIGURES, STREAMED, WINDOWED, figure_of, figures
from slipbench.vocabulary import KEY_ORDER, LOW_N, ORDERS, cell_label

MARKS = dict(
    zip(
        VERDICTS,
        (
            "▼ regressed",
            "◆ mixed (better on one figure, worse on another)",
            "▲ improved",
            "▽ worse (not shown beyond its tolerance)",
            "△ better (not shown beyond its tolerance)",
            "≈ within margin",
            "= no significant change",
            "? inconclusive",
            "≡ identical",
        ),
    )
) | {"undecided": "◇ undecided"}
#: the rates of one class each, TP then TN: a windowed cell's second column
_CLASS_RATES = [f.name for f in figures(WINDOWED) if f.one_class]
#: of the JSON: 4 read verdicts from Bonferroni intervals (``p``, not ``p_holm``); 5 names the
#: interval each pooled verdict reads (``read_lo``, ``read_hi``, ``read_level``) and adds the
#: cells' words mixed, worse and better
SCHEMA_VERSION = 5
MAX_ROWS = 60  # cells listed besides the regressed ones (the CLI default)
#: a comparison's cells in order of their name (protocol, detector, split, cell), a cell's
#: seeds side by side
_ORDER = (
    *columns.identity(columns.ENTRANT, columns.SETTING, columns.CELL_ROLE, named=True),
    *columns.identity(columns.SEED, named=True),
)
COMMENT_LIMIT = 60_000  # characters; a pull-request comment is capped at 65,536


def _cell_items(cell: str) -> list[tuple[str, object]]:
    """A cell's key items, sensor first (the JSON is stored with sorted keys)."""
    try:
        items = json.loads(cell).items()
    except (TypeError, json.JSONDecodeError):
        return [("cell", cell)]
    return sorted(
        items,
        key=lambda kv: (KEY_ORDER.index(kv[0]) if kv[0] in KEY_ORDER else len(KEY_ORDER), kv[0]),
    )


def _cell_rank(cell: str) -> tuple:
    """Sort key of a cell in the paper's order: sensors, fingers, materials as the tables list them."""
    out = []
    for k, v in _cell_items(cell):
        order = ORDERS.get(k, ())
        out.append(
            (0, order.index(v), "")
            if v in order
            else (1, float(v), "")
            if isinstance(v, (int, float))
            else (2, 0.0, str(v))
        )
    return tuple(out)


def in_paper_order(cmp: Comparison) -> Comparison:
    """The comparison with its cells in the paper's order: protocols as the paper's tables
    (laid out from the result rows), then detector, split, the cell key as the tables list it,
    seed."""
    cells = cmp.cells
    order = protocol_order(layouts(cells if cmp.rows is None else cmp.rows))
    rank = [
        (
            order.index(r[columns.PROTOCOL]),
            *(_cell_rank(v) if c == "cell" else v for c, v in r.items()),
        )
        for r in cells[list(_ORDER)].to_dict("records")
    ]
    cells = cells.iloc[sorted(range(len(cells)), key=rank.__getitem__)].reset_index(drop=True)
    return replace(cmp, cells=cells)


def summary_rows(cmp: Comparison) -> pd.DataFrame:
    """:func:`slipbench.gate.compare.summary` with its worst cell named by its label."""
    lines = summary(cmp)
    lines["worst_row"] = [
        "" if i is None or pd.isna(i) else _label(cmp.cells.loc[int(i)], cmp)
        for i in lines["worst_row"]
    ]
    return lines.rename(columns={"worst_row": "worst_cell"})


def _label(r: dict, cmp: Comparison) -> str:
    """A cell's short label; the split, seed and settings (labels, dataset, ...) only where the
    comparison holds several."""
    text = cell_label(r["cell"])
    for column in ("split", "seed"):
        if cmp.cells[column].nunique() > 1:
            text += f", {column} {r[column]}"
    for column in SETTINGS:
        if column != "split" and column in cmp.cells and cmp.cells[column].nunique() > 1:
            text += f", {setting_text(column, r[column])}"
    return text


def _delta(r: dict, name: str, scale: float = 100.0, digits: int = 1, bounds: bool = True) -> str:
    d, lo, hi = r.get(f"d_{name}"), r.get(f"d_{name}_lo"), r.get(f"d_{name}_hi")
    if d is None or pd.isna(d):
        return "—"
    text = f"{scale * d:+.{digits}f}"
    if bounds and lo is not None and hi is not None and not (pd.isna(lo) or pd.isna(hi)):
        text += f" [{scale * lo:+.{digits}f}, {scale * hi:+.{digits}f}]"
    return text


def _row(r: dict, cmp: Comparison) -> dict:
    """One compared cell as a table row: base -> candidate, the change and the verdict."""
    both = r["base_status"] == r["candidate_status"] == "ok"
    line = {"protocol": r["protocol"], "detector": r["detector"], "cell": _label(r, cmp)}
    if r["stream"]:
        line["base → candidate"] = (
            ", ".join(
                f"{f.scale * r['base_' + f.name]:.{f.decimals}f} → "
                f"{f.scale * r['candidate_' + f.name]:.{f.decimals}f} {f.display}"
                for f in figures(STREAMED, gated=True)
            )
            if both
            else f"{r['base_status']} → {r['candidate_status']}"
        )
        line["Δ [simultaneous CI]"] = "; ".join(
            f"{f.called} {_delta(r, f.name, f.scale, f.decimals)} {f.change_unit}"
            for f in figures(STREAMED, gated=True)
        ) + _compute_text(r)
        line["Δ TP / TN rate"] = ""
    else:
        line["base → candidate"] = (
            f"{100 * r['base_accuracy']:.1f} → {100 * r['candidate_accuracy']:.1f}"
            if both
            else f"{r['base_status']} → {r['candidate_status']}"
        )
        line["Δ [simultaneous CI]"] = _delta(r, "accuracy")
        line["Δ TP / TN rate"] = " / ".join(_delta(r, name, bounds=False) for name in _CLASS_RATES)
    why = r.get("inconclusive_reason") or ""
    if not cmp.look.final and r.get("read_at_look"):
        why = ", ".join(filter(None, [why, f"Δ at this look's {level_text(cmp.level)}"]))
    line[""] = MARKS[r["verdict"]] + (f" ({why})" if why else "") + _regressed_figures(r)
    return line


def _regressed_figures(r: dict) -> str:
    """The figures a regressed cell regressed in: the one its Δ column shows by name, each
    other with its own change and interval (points unless said)."""
    named = [f for f in str(r.get("regressed_figures") or "").split(", ") if f]
    shown = (columns.DETECTION_RATE if r.get("stream") else columns.ACCURACY).name

    def said(f: str) -> str:
        if f == shown:
            return FIGURES[f].called
        u = "" if unit(f) == "points" else f" {unit(f)}"
        return f"{FIGURES[f].called} {_delta(r, f, FIGURES[f].scale, FIGURES[f].decimals)}{u}"

    return f": {', '.join(map(said, named))}" if named else ""


def _compute_text(r: dict) -> str:
    """A streaming cell's compute check, where the candidate is over its real-time budget: a
    note beside the verdict, never part of it (the figure is the candidate machine's)."""
    if r.get("compute_check") != "over the real-time budget":
        return ""
    on = f" on {r['candidate_processor']}" if r.get("candidate_processor") else ""
    return (
        f"; ⚠ over the real-time budget: {r['candidate_compute_ms_per_hop']:.3g} ms per hop > "
        f"{r['candidate_compute_budget_ms']:.3g} ms{on}"
    )


def _table(rows: list[dict]) -> str:
    """A pipe table of the rows (dicts of one set of keys), every text escaped."""
    header = list(rows[0]) if rows else []
    return md_table(header, [[str(r[k]) for k in header] for r in rows], align="left")


def _summary_table(cmp: Comparison) -> str:
    lines = []
    for s in summary_rows(cmp).to_dict("records"):
        bounds = "" if pd.isna(s["worst_lo"]) else f" [{s['worst_lo']:+.1f}, {s['worst_hi']:+.1f}]"
        lines.append(
            {
                "protocol": s["protocol"],
                "detector": s["detector"],
                "cells": s["cells"],
                "▼": s["regressed"],
                "▲": s["improved"],
                "?": s["inconclusive"],
                "≡": s["identical"],
                "mean Δ": "—" if pd.isna(s["mean_change"]) else f"{s['mean_change']:+.1f}",
                "worst cell": f"{s['worst_cell']}: {s['worst_change']:+.1f}{bounds}"
                if s["worst_cell"]
                else "—",
            }
        )
    return _table(lines)


def _shown(cmp: Comparison) -> pd.DataFrame:
    """The cells the comment lists: a cell shared by two protocols once (under the first)."""
    cells = cmp.cells
    return cells[cells["shared_with"] == ""] if "shared_with" in cells else cells


def _folded(cmp: Comparison) -> pd.Series:
    """The low-n cells that did not regress: counted, not listed (their intervals undercover)."""
    cells = _shown(cmp)
    return cells["low_n"].astype(bool) & (cells["verdict"] != "regressed")


def _others(cmp: Comparison) -> pd.DataFrame:
    """The cells that did not regress, improved ones first, then by the size of their change;
    low-n cells folded (:func:`_folded`)."""
    cells = _shown(cmp)
    rest = cells[~cells["verdict"].isin(["regressed", "identical"]) & ~_folded(cmp)]
    size = -np.abs([primary_change(r) for r in rest.to_dict("records")])
    order = np.lexsort((np.nan_to_num(size, nan=0.0), (rest["verdict"] != "improved").to_numpy()))
    return rest.iloc[order]


def _side_lines(rows: pd.DataFrame, limit: int) -> list[str]:
    """Cells on one side only, counted per protocol and detector, the first ``limit`` named."""
    counts = rows.groupby(["protocol", "detector"], sort=False).size()
    lines = [
        f"- {md_text(p)}, {md_text(d)}: {n} cell{'s' * (n > 1)}" for (p, d), n in counts.items()
    ]
    apart = [c for c in SETTINGS if c != "split" and c in rows]
    named = [
        "  - "
        + md_text(
            f"{r['protocol']}, {r['detector']}, {cell_label(r['cell'])}, split {r['split']}, "
            f"seed {r['seed']}" + "".join(f", {setting_text(c, r[c])}" for c in apart)
        )
        for r in rows.head(limit).to_dict("records")
    ]
    more = (
        [f"  - … and {len(rows) - limit} more (`--format json` lists them all)"]
        if len(rows) > limit
        else []
    )
    return lines + named + more


def comment_markdown(cmp: Comparison, max_rows: int = MAX_ROWS) -> str:
    """A pull-request comment: the verdict and a summary per protocol and detector, then the
    regressed cells, then at most ``max_rows`` others (improved first, then the largest
    changes); each cell once. Held under ``COMMENT_LIMIT`` characters: past it the regressed
    list is cut with a line that says how many it leaves out."""
    if max_rows < 0:
        raise UsageError(f"--max-rows must be >= 0, got {max_rows}")
    cmp = in_paper_order(cmp)
    return headline(cmp) + (_unchanged(cmp) if cmp.unchanged else _changed(cmp, max_rows))


def headline(cmp: Comparison) -> str:
    """The comment's first line where the gate is not simply the candidate's to read: the
    base's bench judged and the candidate's differs, a calibration was refused, or work the
    base's bench ran is missing from the candidate ("" otherwise)."""
    said = [*cmp.headline]
    if cmp.missing:
        said.append(
            "Missing from the candidate (lost work, a regression): " + "; ".join(cmp.missing) + "."
        )
    return f"⚠ {md_text(' '.join(said))}\n\n" if said else ""


def _changed(cmp: Comparison, max_rows: int) -> str:
    cells = _shown(cmp)
    counts = cells["verdict"].value_counts()
    head = [
        "## slipbench compare",
        "",
        f"BASE {md_code(cmp.base)} → CANDIDATE {md_code(cmp.candidate)}; {len(cells)} cells paired "
        f"(seeds {_seeds_text(cmp)}); gate: {md_text(gate_text(cmp.gate))}.",
        "",
        _verdict_line(cmp),
        "",
        ", ".join(f"{MARKS[v]}: {int(counts.get(v, 0))}" for v in VERDICTS),
    ]
    parts = ["\n".join(head)]
    if not cmp.pooled.empty:
        parts.append(
            "### Pooled per protocol and detector\n\n"
            + _pooled_table(cmp)
            + "\n\n"
            + _pooled_footnote(cmp)
        )
    parts.append(
        "### Per protocol and detector\n\n" + _summary_table(cmp) + "\n\n_mean Δ and worst "
        "cell: accuracy points (streaming cells: detection rate), candidate − base, over the cells both sides "
        "finished; the worst cell is the lowest change among cells that decided something; ▼ regressed, "
        "▲ improved, ? inconclusive, ≡ identical._"
    )
    notes = _notes(cmp)
    for title, rows in (
        ("Cells only in BASE", cmp.only_base),
        ("Cells only in CANDIDATE", cmp.only_candidate),
    ):
        if len(rows):
            notes.insert(
                0,
                f"**{title}** ({len(rows)}), not compared:\n\n"
                + "\n".join(_side_lines(rows, max_rows)),
            )
    budget = (
        COMMENT_LIMIT - sum(len(p) + 2 for p in (*parts, *notes)) - 400
    )  # 400: the headings and cut lines
    shown = _shown(cmp)
    regressed = [_row(r, cmp) for r in shown[shown["verdict"] == "regressed"].to_dict("records")]
    table, listed = _fit(regressed, budget)
    if regressed:
        parts.append(
            "### Regressed\n\n"
            + table
            + (
                f"\n\n_… and {len(regressed) - listed} more regressed cells: "
                "`--format json` lists them all._"
                if listed < len(regressed)
                else ""
            )
        )
    others = _others(cmp)
    room = (
        budget - len(table) if listed == len(regressed) else 0
    )  # a regressed cell left out: no other cell in
    table, listed = _fit([_row(r, cmp) for r in others.head(max_rows).to_dict("records")], room)
    if listed:
        parts.append("### Other cells\n\n" + table)
    if listed < len(others):
        parts.append(
            f"_{len(others) - listed} other cells not shown (`--max-rows`; `--format json` lists every cell)._"
        )
    parts += _folded_lines(cmp)
    return "\n\n".join(parts + notes) + "\n"


def _folded_lines(cmp: Comparison) -> list[str]:
    """What the lists leave out, counted: low-n cells, and cells two protocols share."""
    out = []
    low = int(_folded(cmp).sum())
    if low:
        out.append(
            f"_{low} low-n cells (fewer than {LOW_N} test trials of a class) not listed: their "
            "intervals undercover, so they decide nothing (`--format json` lists them)._"
        )
    if "shared_with" in cmp.cells:
        twins = cmp.cells[cmp.cells["shared_with"] != ""]
        for (protocol, first), n in (
            twins.groupby(["protocol", "shared_with"], sort=False).size().items()
        ):
            out.append(
                f"_{n} cells of {md_text(protocol)} are {md_text(first)}'s (the same models "
                "tested on the same test set): counted and listed once, under "
                f"{md_text(first)}._"
            )
    return out


def _seeds_text(cmp: Comparison) -> str:
    b, c = cmp.min_seeds_base, cmp.min_seeds_candidate
    return f"{b} per cell on each side" if b == c else f"BASE {b}, CANDIDATE {c} per cell at least"


def gate_text(gate: Gate) -> str:
    """The gate's figures and tolerances, in words."""
    return ", ".join(f"{FIGURES[f].called} ±{t:g} {unit(f)}" for f, t in gate.tolerances.items())


def _interval(r: dict) -> str:
    """A pooled test's change with the interval its verdict reads, at that level."""
    return (
        f"{r['change']:+.2g} [{r['read_lo']:+.2g}, {r['read_hi']:+.2g}] {unit(r['figure'])} "
        f"({level_text(r['read_level'])})"
    )


def _pooled_phrase(r: dict) -> str:
    return (
        f"{md_text(r['protocol'])}, {md_text(r['detector'])}: {FIGURES[r['figure']].called} "
        f"{_interval(r)}"
    )


def _sees(r: dict) -> str:
    """The drop a pooled test flags with 80 % power (at this look); where that is beyond any
    change the figure can make (100 points of a rate), that it cannot see a drop of any
    size."""
    seen = r["detectable"]
    if not np.isfinite(seen):
        return "—"
    lo, hi = FIGURES[r["figure"]].bounds
    if seen > FIGURES[r["figure"]].scale * (hi - lo):
        return "cannot see a drop of any size" + ("" if r.get("final", True) else " at this look")
    return f"{seen:.2g} {unit(r['figure'])}"


def _flagged(cmp: Comparison) -> list[str]:
    """What regressed: each pooled figure, and the cells per figure."""
    flagged = [f"{_pooled_phrase(r)} (pooled)" for r in cmp.pooled_regressions.to_dict("records")]
    flagged += [f"missing: {md_text(m)}" for m in cmp.missing]
    shown = _shown(cmp)
    regressions = shown[shown["verdict"] == "regressed"]
    failed = regressions["regressed_figures"] == ""
    if failed.any():
        flagged.append(f"{int(failed.sum())} cells the candidate no longer finishes")
    figures = regressions.loc[~failed, "regressed_figures"].str.split(", ").explode()
    for figure, n in figures.value_counts(sort=False).items():
        flagged.append(f"{FIGURES[str(figure)].called} in {n} cell{'s' * (n != 1)} (cell level)")
    return flagged


def _verdict_line(cmp: Comparison) -> str:
    """The state: what regressed where, what is undecided and what would decide it, or what
    each "no regression" could have seen."""
    state, flagged = cmp.state, _flagged(cmp)
    if state == "regressed":
        line = f"**Regressed** beyond the tolerance: {'; '.join(flagged)}."
    elif state == "undecided":
        line = (
            "**Undecided** (exit 6): "
            + "; ".join([*(f"{f}, on one seed per side" for f in flagged), *_undecided(cmp)])
            + "."
            + (f" {_what_to_run(cmp)}" if _what_to_run(cmp) else "")
        )
    else:
        line = "**No regression**: " + "; ".join(map(_seen, cmp.pooled.to_dict("records"))) + "."
    note = repeats_note(cmp)
    return line + (f"\n\n⚠ Note: {md_text(note)}." if note else "")


def _seen(r: dict) -> str:
    """What a pooled test that flagged nothing could see, read from the interval printed
    with it: before the last look, the drop that interval rules out (its worse end); at the
    last, also the drop it flags with 80 % power."""
    what = f"{FIGURES[r['figure']].called} of {md_text(r['protocol'])}, {md_text(r['detector'])}"
    u = unit(r["figure"])
    said = f"{what} {_interval(r)}"
    if not r.get("final", True):
        if r["bound"] <= 0:
            return f"{said}: a drop of any size ruled out"
        return f"{said}: a drop beyond {r['bound']:.2g} {u} ruled out"
    sees = _sees(r)
    if sees == "—":
        return said
    if sees.startswith("cannot"):
        return f"{said}: it {sees}"
    return f"{said}: a drop of {sees} would show (80 % power)"


def _what_to_run(cmp: Comparison) -> str:
    """What settles an undecided comparison: the gate's next look (its seeds more on both
    sides), or, with the budget spent, what a larger budget would take."""
    look, gate = cmp.look, cmp.gate
    if not look.final:
        seed = _look_json(cmp)["next_seed"]
        return (
            f"Run the next look: {look.next_seeds - look.seeds} more seeds on both sides "
            f"(`slipbench run BENCH --seed {seed} --out BASE`, the same with `--out CANDIDATE`), "
            "then compare again."
        )
    if not gate.sequential and gate.budget <= gate.seeds and gate.seeds:
        budget = f"The bench's {gate.seeds} seeds a side are its budget"
    elif gate.sequential:
        budget = f"The budget of {gate.budget} seeds a side is spent"
    else:
        return ""
    needed = [int(n) for n in cmp.undecided.get("seeds_needed", []) if n]
    more = f" about {max(needed)} seeds a side would decide it ([gate] budget)," if needed else ""
    return f"{budget}:{more} or a larger tolerance; `slipbench run BENCH --plan` shows both."


def _undecided(cmp: Comparison, shown: int = 5) -> list[str]:
    """Why pooled tests are undecided and what would decide them: one line for a reason every
    one of them shares (one seed per side, low n), else the first ``shown`` of them."""
    rows = cmp.undecided.to_dict("records")
    reasons = {r["undecided_reason"] for r in rows}
    if len(reasons) == 1 and "80 % power" not in next(iter(reasons), ""):
        return [f"{len(rows)} pooled tests: {reasons.pop()}"] if rows else []
    out = []
    for r in rows[:shown]:
        if not r.get("final", True):
            out.append(f"{_pooled_phrase(r)}: {r['undecided_reason']}")
            continue
        more = f"{r['seeds_needed']} seeds per side"
        if r["trials_needed"]:
            more += f" or {r['trials_needed']} test trials per class"
        out.append(f"{_pooled_phrase(r)}: {r['undecided_reason']}; about {more} would decide it")
    return out + ([f"and {len(rows) - shown} more pooled tests"] if len(rows) > shown else [])


def _unchanged(cmp: Comparison) -> str:
    """The comment of a comparison in which nothing changed: a few lines."""
    return (
        "## slipbench compare\n\n"
        f"BASE {md_code(cmp.base)} → CANDIDATE {md_code(cmp.candidate)}: all {len(cmp.cells)} paired cells are "
        "identical (the same result keys or the same predictions), and no cell is on one side only.\n\n"
        "**Nothing changed.**\n"
        + _unchanged_compute(cmp)
        + "".join(f"\n_{md_text(n)}_\n" for n in cmp.notes)
    )


def _unchanged_compute(cmp: Comparison) -> str:
    """Streams identical on both sides may still run slower on the candidate's machine: its
    compute check is said even when nothing else changed."""
    streams = cmp.cells[cmp.cells["stream"]] if "stream" in cmp.cells else cmp.cells.iloc[:0]
    if streams.empty:
        return ""
    summary = _compute_summary(streams)
    over = (
        "compute_check" in streams
        and (streams["compute_check"] == "over the real-time budget").any()
    )
    return (
        f"\n{'⚠ ' if over else ''}Streaming: the compute time per hop is each machine's own and "
        f"never makes a verdict: {summary}\n"
    )


def _pooled_table(cmp: Comparison) -> str:
    lines = []
    for r in cmp.pooled.to_dict("records"):
        u = unit(r["figure"])
        lines.append(
            {
                "protocol": r["protocol"],
                "detector": r["detector"],
                "figure": FIGURES[r["figure"]].called,
                "cells (changed)": f"{r['cells']} ({r['changed_cells']})",
                "mean Δ [CI]": f"{r['change']:+.2g} [{r['read_lo']:+.2g}, {r['read_hi']:+.2g}] {u}",
                "level": level_text(r["read_level"]),
                "sees": _sees(r),
                "": MARKS[r["verdict"]]
                + (f" ({r['undecided_reason']})" if r["undecided_reason"] else ""),
            }
        )
    return _table(lines)


def _pooled_footnote(cmp: Comparison) -> str:
    """How the pooled table's intervals are read, at this look."""
    n = len(cmp.pooled)
    family = level_text(family_level(n, POOLED_ALPHA))
    head = (
        "_mean Δ: candidate − base over the cells both sides finished (identical cells count 0), "
        "with the interval its verdict reads, at the level beside it (one joint cluster "
        "bootstrap over the trials the cells share, where both sides kept predictions). "
    )
    if cmp.look.final:
        read = (
            f"The interval is this look's ({level_text(cmp.pooled_level)}: Bonferroni over the {n} "
            f"pooled tests at {100 * POOLED_ALPHA:g} %"
            + (", its share of the budget's looks" if cmp.gate.sequential else "")
            + "): a figure regressed or improved where it lies beyond its tolerance, within "
            "margin where inside it; worse or better where it lies on one side of no change "
            "only. sees: the drop flagged with 80 % power (tolerance + se × (t(1 − α/2N, df) + "
            "t(0.8, df))); undecided where that is more than twice the tolerance._"
        )
    else:
        read = (
            f"At this look ({cmp.look.seeds} of {cmp.gate.budget} seeds a side) a figure is "
            f"flagged only where its interval at the look's level ({level_text(cmp.pooled_level)}, "
            "its O'Brien-Fleming share of the error) lies beyond its tolerance, and that "
            "interval is printed; otherwise the interval printed is the family's "
            f"({family}: Bonferroni over the {n} pooled tests at {100 * POOLED_ALPHA:g} %), and "
            "no regression means its worse end lies inside the tolerance: that end is the drop "
            "it rules out. sees: the drop this look flags with 80 % power; undecided where a "
            "drop beyond the tolerance is not ruled out._"
        )
    return head + read


def _fit(rows: list[dict], budget: int) -> tuple[str, int]:
    """The table of the first rows that fits in ``budget`` characters, and how many it holds."""
    n = len(rows)
    while n and len(_table(rows[:n])) > budget:
        n = max(0, min(n - 1, int(n * budget / len(_table(rows[:n])))))
    return (_table(rows[:n]) if n else ""), n


def _notes(cmp: Comparison) -> list[str]:
    cells = cmp.cells
    n = int(((cells["base_status"] == "ok") & (cells["candidate_status"] == "ok")).sum())
    methods = cells["method"].str.replace(r", \d+ shared windows", "", regex=True).value_counts()
    n_family = int(
        (
            (cells["base_status"] == "ok")
            & (cells["candidate_status"] == "ok")
            & (cells["verdict"] != "identical")
            & ~cells["low_n"].astype(bool)
        ).sum()
    )
    notes = [
        f"_The family: the chance that anything in this comparison is wrongly called regressed or improved is at "
        f"most {100 * ALPHA:g} %, split between the pooled tests ({100 * POOLED_ALPHA:g} %, Bonferroni over the "
        f"protocols, detectors and figures) and the cells ({100 * CELL_ALPHA:g} %, Bonferroni over the figures of the "
        f"{n_family} cells that changed and are not low-n, of {n} both sides finished). Every verdict reads the "
        "interval printed beside it. Cells with identical predictions on both sides leave the family._",
        f"_Δ: candidate − base, percentage points, with {_cell_levels(cmp)} "
        f"({'; '.join(f'{m}: {k} cells' for m, k in methods.items())}; a paired cluster bootstrap over the shared "
        f"test windows where both sides kept predictions; over seeds and trials where a side ran several seeds). "
        f"A cell regresses when a figure of the gate ({md_text(gate_text(cmp.gate))}) is worse than its "
        "tolerance (its interval lies beyond it), or when the candidate did not finish a cell the base finished; "
        "it improves when one is better beyond its tolerance and none worse; mixed when one is better beyond its "
        "tolerance and another worse (its interval below no change, or its change beyond its tolerance); worse "
        "(better) when an interval lies on the worse (better) side of no change without a figure flagged beyond "
        "its tolerance, never no significant change; within margin when every figure's interval lies inside its "
        "tolerance. "
        f"A cell is inconclusive when it is low-n (fewer than 10 test trials of a class: its intervals undercover) "
        f"or its interval, deciding nothing, is wider than {cmp.gate.max_width:g} points._",
    ]
    if cells["stream"].any():
        notes.append(
            "_Streaming cells: Δ with the interval above from the rows' bootstrap intervals over "
            "trials, combined as independent (unpaired; both sides stream the same trials, so this is conservative). "
            "A streaming cell is judged on false alarms per minute, detection rate and median delay as the gate "
            "lists them. "
            "Delays are counted on the streams' samples, the same on every machine. The compute time per hop "
            "is each machine's own and never makes a verdict: "
            + _compute_summary(cells[cells["stream"]])
            + "_"
        )
    return notes + [f"_{md_text(n)}_" for n in cmp.notes]


def _cell_levels(cmp: Comparison) -> str:
    """The level of the cells' intervals, in words: the look's, or before the last look the
    family's where the look flags nothing."""
    if cmp.look.final:
        return f"a {level_text(cmp.level)} interval"
    return (
        f"a {level_text(cmp.read_level)} interval (the cells' family: Bonferroni at "
        f"{100 * CELL_ALPHA:g} %; at this look, {cmp.look.seeds} of {cmp.gate.budget} seeds a side, "
        f"a cell is flagged only where its interval at the look's level, "
        f"{level_text(cmp.level)}, lies beyond a tolerance, and such a cell prints that interval)"
    )


def _compute_summary(cells: pd.DataFrame) -> str:
    """How many streaming cells of the candidate run over their real-time budget."""
    check = cells["compute_check"] if "compute_check" in cells else pd.Series("", index=cells.index)
    measured = int(check.isin(["over the real-time budget", "within the real-time budget"]).sum())
    if not measured:
        return "these rows hold none (written before it was measured apart)."
    over = int((check == "over the real-time budget").sum())
    machines = sorted(set(cells.get("candidate_processor", pd.Series(dtype=str)).dropna()) - {""})
    on = f" (measured on {md_text('; '.join(machines))})" if machines else ""
    return (
        f"{over} of {measured} candidate cells over the real-time budget, the hop period{on}."
        if over
        else f"all {measured} candidate cells within the real-time budget, the hop period{on}."
    )


def _in_points(frame: pd.DataFrame) -> pd.DataFrame:
    """The cells' columns that hold fractions (figures and their changes) in percentage points."""
    out = frame.copy()
    for col in out.columns:
        shown = figure_of(col)
        if shown is not None and shown.unit == "fraction":
            out[col] = 100 * pd.to_numeric(out[col], errors="coerce")
    return out


def _look_json(cmp: Comparison) -> dict:
    """The gate's look as a workflow reads it: where the next look's seeds start."""
    look, gate = cmp.look, cmp.gate
    seeds = pd.to_numeric(cmp.rows["seed"]) if cmp.rows is not None else pd.Series(dtype=float)
    return {
        "index": look.index,
        "seeds": look.seeds,
        "final": look.final,
        "next_seeds": look.next_seeds,
        "next_seed": int(seeds.max()) + 1 if len(seeds) and not look.final else None,
        "budget": gate.budget or look.seeds,
    }


def to_json(cmp: Comparison) -> str:
    """Every compared cell with its changes and verdict, the pooled tests, the summary and the
    one-sided cells, for bots (``compare.schema.json`` describes it). Rates and their changes
    in percentage points throughout; delays in ms, false alarms per minute; levels and
    p-values as probabilities."""

    def records(frame: pd.DataFrame) -> list[dict]:
        out = json.loads(frame.to_json(orient="records", double_precision=6))
        for r in out:
            if isinstance(r.get("cell"), str):
                try:
                    r["cell"] = json.loads(r["cell"])
                except json.JSONDecodeError:
                    r["cell"] = {"cell": r["cell"]}
        return out

    cmp = in_paper_order(cmp)
    cells = cmp.cells.assign(label=[_label(r, cmp) for r in cmp.cells.to_dict("records")])
    doc = {
        "schema_version": SCHEMA_VERSION,
        "units": {
            "rates": "percentage points (0-100), changes candidate - base",
            "delays": "ms",
            "false_alarms": "per minute",
            "levels": "probability",
        },
        "base": cmp.base,
        "candidate": cmp.candidate,
        "gate": {"tolerances": dict(cmp.gate.tolerances), "max_width": cmp.gate.max_width},
        "level": cmp.level,
        "pooled_level": cmp.pooled_level,
        "read_level": cmp.read_level,
        "family": {
            "alpha": ALPHA,
            "pooled": {
                "alpha": POOLED_ALPHA,
                "method": "Bonferroni over protocols x detectors x figures, read from the intervals",
            },
            "cells": {
                "alpha": CELL_ALPHA,
                "method": "Bonferroni over the figures of changed, not low-n cells, read from the intervals",
            },
        },
        "seeds": {"base": cmp.min_seeds_base, "candidate": cmp.min_seeds_candidate},
        "look": _look_json(cmp),
        "noise_measured": cmp.measured,
        "retraining_noise_covered": cmp.retraining_covered,
        "exit_code": cmp.exit_code,
        "verdict": cmp.state,
        "counts": {v: int((cmp.cells["verdict"] == v).sum()) for v in VERDICTS},
        "pooled": records(cmp.pooled),
        "summary": records(summary_rows(cmp)),
        "cells": records(_in_points(cells)),
        "only_base": records(cmp.only_base),
        "only_candidate": records(cmp.only_candidate),
        "notes": [*cmp.notes, *([repeats_note(cmp)] if repeats_note(cmp) else [])],
        "headline": list(cmp.headline),
        "missing": list(cmp.missing),
    }
    return json.dumps(doc, indent=1, allow_nan=False, default=str) + "\n"
