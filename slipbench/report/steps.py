"""The steps of a history as text (a list of confirmed steps, newest first, with what stands
behind them) and as JSON (every proposal, for bots)."""

from __future__ import annotations

import json
import os

import numpy as np
import pandas as pd

from slipbench.gate.gate import MAX_NEEDED, POWER, unit
from slipbench.history.short import FEWEST, ROUTES
from slipbench.history.steps import JUDGED, MIN_RUNS, SERIES_ALPHA, Steps
from slipbench.stats.contrast import level_text
from slipbench.store.columns import FIGURES

SHOWN = ("commit", "date", "verdict", "figure", "series_label", "change", "runs", "what_changed")


def _header(found: Steps, where: str | os.PathLike) -> str:
    runs = found.runs
    first, last = runs.iloc[0], runs.iloc[-1]
    tolerances = ", ".join(
        f"{FIGURES[f].label} {found.gate.tolerances[f]:g} {unit(f)}"
        for f in JUDGED
        if f in found.gate.tolerances
    )
    counts = found.steps["verdict"].value_counts()
    return (
        f"History {where}: {len(runs)} runs, {first['commit']} ({first['date']}) to "
        f"{last['commit']} ({last['date']}); {found.series} series judged (each cell and each "
        f"protocol's mean over its cells); tolerances: {tolerances}.\n"
        f"{len(found.steps)} steps proposed (ruptures, each point weighted by its interval), "
        f"{int(counts.get('regressed', 0))} regressed and {int(counts.get('improved', 0))} "
        f"improved beyond the tolerance (each segment's seeds against the other's; Bonferroni "
        f"over a series' proposals at {100 * SERIES_ALPHA:g} %, the level of each interval), "
        f"{int(counts.get('inconclusive', 0))} inconclusive (one seed on each side, or low n).\n"
        f"{AGAINST_COMPARE}\n" + unproven_line(runs)
    )


#: why a step and `compare` can read the same change differently
AGAINST_COMPARE = (
    "A step reads the runs of the segment before against those after (each at least "
    f"{MIN_RUNS} runs; their seeds unpaired, their spread the noise) at its series' "
    f"Bonferroni level; in a series of {FEWEST} to {2 * MIN_RUNS - 1} runs, the runs before "
    "against those after at its best cut, each run's own interval its noise (scaled by how "
    "much more the history's series move than their intervals say, or the runs' scatter "
    "where larger), Bonferroni over the cuts; `slipbench compare` reads one base against one candidate, seed by seed "
    "(calibrated noise where the bench has it), at its look's level: on the same change they "
    "differ where their seeds, noise or level differ, and each prints the interval and level "
    "it read."
)


def short_history(found: Steps) -> str:
    """Where no series holds enough runs for a step to be searched (``FEWEST``), how many it
    needs; where the longest is short (fewer than ``2 * MIN_RUNS``), how its steps are judged;
    "" where a series is long."""
    held = (
        int(found.points.groupby(["series", "figure"]).size().max())
        if not found.points.empty
        else len(found.runs)
    )
    if held >= 2 * MIN_RUNS:
        return ""
    if held >= FEWEST:
        return (
            f"No confirmed step. The longest series holds {held} runs, fewer than the "
            f"{2 * MIN_RUNS} the segment search needs: its steps are {ROUTES['short']}."
        )
    return (
        f"No step can be proposed: a series needs {FEWEST} runs for a step to be searched, "
        f"and the longest holds {held}; {FEWEST - held} more runs would let one be proposed."
    )


def route_of(step: dict) -> str:
    """How a step was judged, in words (the long route's where a row predates routes)."""
    return ROUTES.get(str(step.get("route") or "long"), ROUTES["long"])


def unproven_line(runs: pd.DataFrame) -> str:
    """A line naming the runs that hold rows no digest vouched for when they were added (a
    results file written by another tool, or edited), or ""."""
    marked = runs[runs["unproven"] > 0] if "unproven" in runs else runs.iloc[:0]
    if marked.empty:
        return ""
    shown = ", ".join(f"{c} ({n} rows)" for c, n in zip(marked["commit"], marked["unproven"]))
    return (
        f"Unproven: {len(marked)} run{' holds' if len(marked) == 1 else 's hold'} rows that "
        f"entered unproven (results without digests: edits to them cannot be detected): "
        f"{shown}; a step beside them is marked {UNPROVEN!r}.\n"
    )


#: how a step whose sides hold unproven rows is marked, after its verdict
UNPROVEN = "unproven rows beside it"


def verdict_shown(step: dict) -> str:
    """A step's verdict, marked where its sides hold rows that entered unproven."""
    return f"{step['verdict']} ({UNPROVEN})" if step.get("unproven") else str(step["verdict"])


#: commits with proposals none of which was confirmed, listed newest first
UNCONFIRMED_SHOWN = 10


def _unconfirmed(found: Steps) -> str:
    """The commits where steps were proposed and none confirmed, newest first, each with its
    proposal nearest to being confirmed: where to look, not a verdict."""
    rest = found.steps[~found.steps["verdict"].isin(["regressed", "improved"])]
    rest = rest[~rest["commit"].isin(set(found.confirmed["commit"]))]
    if rest.empty:
        return ""
    lines = []
    for commit, part in rest.sort_values("p_adjusted").groupby("commit", sort=False):
        r = part.iloc[0].to_dict()
        lines.append(
            (
                r["run"],
                f"- {commit} ({r['date']}): a step proposed in {len(part)} series, none "
                f"confirmed; nearest: {FIGURES[r['figure']].label} of {r['series_label']}, "
                f"{_change(r)} at {level_text(r['level'])} on {r['df']:.0f} df, "
                f"{r['runs_before']} runs → {r['runs_after']}, {route_of(r)}; "
                f"{_would_confirm(r)}",
            )
        )
    lines.sort(reverse=True)
    shown = [text for _, text in lines[:UNCONFIRMED_SHOWN]]
    more = len(lines) - len(shown)
    return (
        "\nProposed where the series moved, not confirmed (not beyond the tolerance at the "
        "series' level):\n"
        + "\n".join(shown)
        + (f"\n- and {more} more commits" if more else "")
        + "\n"
    )


def _would_confirm(r: dict) -> str:
    """What would decide an unconfirmed proposal: more runs, or none (within the tolerance)."""
    if r["verdict"] == "inconclusive":
        return f"inconclusive: {r['why']}"
    n = int(r["runs_needed"])
    if n == 0:
        return "within the tolerance: no number of seeds confirms it beyond"
    if n >= MAX_NEEDED:
        return (
            f"more than {MAX_NEEDED:,} seeds a side would be needed to confirm a change this large"
        )
    return (
        f"about {n} seeds a side (a run of one seed is one) would confirm a change this large "
        f"({100 * POWER:.0f} % power)"
    )


def _change(r: dict) -> str:
    return f"{r['change']:+.2f} [{r['change_lo']:+.2f}, {r['change_hi']:+.2f}] {unit(r['figure'])}"


def steps_text(found: Steps, where: str | os.PathLike) -> str:
    """The confirmed steps, newest first, after what stands behind them."""
    out = _header(found, where) + _unconfirmed(found)
    confirmed = found.confirmed.sort_values(["run", "series_label"], ascending=[False, True])
    if confirmed.empty:
        return out + f"\n{short_history(found) or 'No confirmed step.'}\n"
    table = pd.DataFrame(
        {
            "commit": confirmed["commit"],
            "date": confirmed["date"],
            "verdict": [verdict_shown(r) for r in confirmed.to_dict("records")],
            "figure": confirmed["figure"].map(lambda f: FIGURES[f].label),
            "series": confirmed["series_label"],
            "change [interval]": [_change(r) for r in confirmed.to_dict("records")],
            "level": [level_text(v) for v in confirmed["level"]],
            "runs": [
                f"{b} → {a}" for b, a in zip(confirmed["runs_before"], confirmed["runs_after"])
            ],
            "what changed": confirmed["what_changed"],
            "judged": [route_of(r) for r in confirmed.to_dict("records")],
        }
    )
    return out + "\n" + table.to_markdown(index=False) + "\n"


def _plain(value):
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (np.floating, float)):
        return float(value) if np.isfinite(value) else None
    if isinstance(value, np.bool_):
        return bool(value)
    return value


def steps_json(found: Steps) -> str:
    """Every proposal with its change, interval, p-value and verdict, and the history's runs."""
    doc = {
        "runs": len(found.runs),
        "first": found.runs.iloc[0][["commit", "date"]].to_dict(),
        "last": found.runs.iloc[-1][["commit", "date"]].to_dict(),
        "series": found.series,
        "series_alpha": SERIES_ALPHA,
        "tolerances": dict(found.gate.tolerances),
        "unproven_runs": found.runs.loc[found.runs["unproven"] > 0, "commit"].tolist(),
        "steps": [{k: _plain(v) for k, v in r.items()} for r in found.steps.to_dict("records")],
    }
    return json.dumps(doc, indent=2) + "\n"
