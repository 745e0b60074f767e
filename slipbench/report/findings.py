"""How the paper's findings fare: one contrast per published table, computed alike on the
published numbers and on each detector's rows, from the protocol's layout (never its name):

- a "curve" (accuracy against window size, sampling rate): the change from the smallest to the
  largest ``x``, per sensor type, mean over units;
- a "with-without" pair (material, speed): the mean change without explicit training, and the
  level that loses most;
- a "matrix" (training unit by test unit): the transfer penalty, the mean accuracy on the unit
  trained on minus on the other units (combined training and testing left out).

A layout split into several tables (decimation, anti-aliasing) is read at its first table, the
paper's reading.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from slipbench.protocol import Layout
from slipbench.report.paper import paper_frame
from slipbench.report.tables import Table, fits, ordered, rank, summarize
from slipbench.vocabulary import DETECTOR_ORDER, SENSOR_ORDER, label

COMBINED = "combined"
#: one side of a finding: its text, and whether each of its checks holds
_Shown = tuple[str, list[bool]]


def _means(rows: pd.DataFrame, keys: list[str], values: str) -> pd.DataFrame:
    """Per combination of ``keys``: the mean over seeds of each cell's figure; for published
    numbers (``values == "paper"``) the numbers themselves."""
    if values == "paper":
        return rows[[*keys, "accuracy"]].rename(columns={"accuracy": "mean"})
    s = summarize(rows, keys)
    return s[s["status"] == "ok"][[*keys, "mean"]]


def _curve(
    rows: pd.DataFrame, layout: Layout, values: str, ends: dict | None = None
) -> dict[str, float]:
    """Per sensor type: the mean over units at the largest ``x`` minus at the smallest; with
    ``ends`` (sensor type -> (smallest, largest), the paper's), only where the rows hold both."""
    x, unit = layout.x or layout.column, layout.rows[-1]
    m = _means(rows, ["sensor_type", unit, x], values)
    out = {}
    for sensor, part in m.groupby("sensor_type"):
        by_x = part.groupby(x)["mean"].mean().sort_index()
        lo, hi = (by_x.index[0], by_x.index[-1]) if ends is None else ends.get(sensor, (None, None))
        if len(by_x) > 1 and lo in by_x.index and hi in by_x.index:
            out[sensor] = 100 * (by_x[hi] - by_x[lo])
    return out


def _ends(rows: pd.DataFrame, layout: Layout) -> dict:
    x = layout.x or layout.column
    return {s: (part[x].min(), part[x].max()) for s, part in rows.groupby("sensor_type")}


def _pair(rows: pd.DataFrame, layout: Layout, values: str) -> tuple[float, str]:
    """The mean change without explicit training (points) and the level losing most."""
    keys, pair = [*layout.rows, layout.column], layout.pair
    assert pair is not None  # a with-without layout: its cells come in with/without pairs
    m = _means(rows, [*keys, pair], values).pivot_table(index=keys, columns=pair, values="mean")
    if not {"with", "without"} <= set(m.columns):
        return np.nan, ""
    change = 100 * (m["without"] - m["with"]).dropna()
    if change.empty:
        return np.nan, ""
    per_level = change.groupby(level=layout.column).mean()
    worst = per_level.idxmin()
    return float(change.mean()), f"{label(layout.column, worst)} ({per_level[worst]:+.1f})"


def _matrix(rows: pd.DataFrame, layout: Layout, values: str) -> float:
    """Mean accuracy on the unit trained on minus on the other units (points)."""
    row, column = layout.rows[-1], layout.column
    m = _means(rows, ["sensor_type", row, column], values)
    m = m[(m[row] != COMBINED) & (m[column] != COMBINED)]
    same, other = m[m[row] == m[column]]["mean"], m[m[row] != m[column]]["mean"]
    return 100 * (same.mean() - other.mean()) if len(same) and len(other) else np.nan


def _first_table(rows: pd.DataFrame, layout: Layout) -> pd.DataFrame:
    from slipbench.report.outline import split_parts

    parts = split_parts(rows, layout)
    return (
        parts[0][1] if parts else rows
    )  # no rows (a detector that did not run the protocol): none


def findings_table(
    rows: pd.DataFrame, found: dict[str, tuple[Layout, str]], order: list[str]
) -> Table | None:
    """One line per finding: the paper's value (its LSTM) and each detector's, in points."""
    detectors = rank(rows["detector"].unique(), DETECTOR_ORDER)
    lines: list[tuple[str, str, list[str]]] = []
    for protocol in order:
        layout = found[protocol][0]
        ref = paper_frame(layout.paper_table) if layout.paper_table else pd.DataFrame()
        prows = rows[rows["protocol"] == protocol]
        if ref.empty or layout.figure is None or prows.empty or fits(layout, prows):
            continue  # no cell of the protocol here, or rows its layout cannot read
        ours = {d: _first_table(prows[prows["detector"] == d], layout) for d in detectors}
        if layout.figure == "curve":
            paper = _curve(ref, layout, "paper")
            mine = {d: _curve(r, layout, "ours", _ends(ref, layout)) for d, r in ours.items()}
            what = (layout.title or layout.x or layout.column).lower()
            for sensor in ordered(list(paper), "sensor_type"):
                lines.append(
                    (
                        protocol,
                        f"{label('sensor_type', sensor)}: accuracy from the smallest to the largest "
                        f"{what} (points)",
                        [f"{paper[sensor]:+.1f}"]
                        + [
                            f"{mine[d][sensor]:+.1f}" if sensor in mine[d] else "—"
                            for d in detectors
                        ],
                    )
                )
        elif layout.figure == "with-without":
            pairs = [
                _pair(ref, layout, "paper"),
                *(_pair(r, layout, "ours") for r in ours.values()),
            ]
            lines.append(
                (
                    protocol,
                    "mean change without explicit training (points)",
                    [f"{v[0]:+.1f}" if np.isfinite(v[0]) else "—" for v in pairs],
                )
            )
            lines.append(
                (
                    protocol,
                    f"the {(layout.title or layout.column).lower()} losing most without it",
                    [v[1] or "—" for v in pairs],
                )
            )
        else:
            penalties = [
                _matrix(ref, layout, "paper"),
                *(_matrix(r, layout, "ours") for r in ours.values()),
            ]
            lines.append(
                (
                    protocol,
                    "transfer penalty: the unit trained on minus other units (points)",
                    [f"{v:+.1f}" if np.isfinite(v) else "—" for v in penalties],
                )
            )
    if not lines:
        return None
    return Table(
        "The paper's findings and ours: each contrast on the published table (the paper's LSTM) and on each "
        "detector's results.",
        ["Protocol", "Finding"],
        "",
        ["paper (LSTM)", *detectors],
        [(p, f) for p, f, _ in lines],
        [c for _, _, c in lines],
        "tab:findings",
        # value columns wrap too ("Neoprene (-9.1)"): six of them in a line overran the page by 143 pt
        wrap={
            0: 0.1,
            1: 0.2,
            **{2 + i: 0.56 / (len(detectors) + 1) for i in range(len(detectors) + 1)},
        },
        notes=[
            "Means over units (sensor and finger) of each unit's figure; a curve from the paper's smallest "
            "to its largest x (windows of 5 and 200 samples; the lowest and the full sampling rate), — where "
            "the results lack either; a layout split into several tables is read at its first (plain "
            "decimation, no anti-aliasing)."
        ],
    )


# ----------------------------------------------------------------------------- does ours show it?
PAPER_MODEL = "lstm"  # the detector behind the published tables


def _per_sensor(rows: pd.DataFrame, column: str, values: str) -> pd.DataFrame:
    """Mean accuracy (%) per sensor type and ``column`` value, over units (and seeds)."""
    m = _means(rows, ["sensor_type", "sensor_instance", column], values)
    return 100 * m.groupby(["sensor_type", column])["mean"].mean().unstack(column)


def _by_sensor(values: dict[str, float]) -> str:
    return (
        ", ".join(
            f"{label('sensor_type', s)} {values[s]:+.1f}"
            for s in ordered(list(values), "sensor_type")
            if np.isfinite(values[s])
        )
        or "—"
    )


def _verdict(flags: list[bool]) -> str:
    return "—" if not flags else "yes" if all(flags) else "partly" if any(flags) else "no"


def _window_findings(ours: pd.DataFrame, paper: pd.DataFrame) -> list[list[str]]:
    lines: list[list[_Shown]] = [[], []]
    for what, values in (("paper", paper), ("ours", ours)):
        t = _per_sensor(values, "window", what)
        rise = {s: t.loc[s, 200] - t.loc[s, 5] for s in t.index if {5, 200} <= set(t.columns)}
        late = {s: t.loc[s, 200] - t.loc[s, 50] for s in t.index if {5, 50, 200} <= set(t.columns)}
        early = {s: t.loc[s, 50] - t.loc[s, 5] for s in late}
        lines[0].append((_by_sensor(rise), [v >= 2 for v in rise.values()]))
        lines[1].append((_by_sensor(late), [late[s] < early[s] / 2 for s in late]))
    return [
        [
            "Accuracy rises with the window (window 5 → 200, points)",
            *_texts(lines[0]),
            "each sensor gains ≥ 2 points",
        ],
        [
            "… and levels off beyond window 50 (50 → 200, points)",
            *_texts(lines[1]),
            "the gain beyond 50 is under half the gain from 5 to 50",
        ],
    ]


def _texts(pair: list[_Shown]) -> list[str]:
    """[paper's numbers, ours, whether ours show it]."""
    return [pair[0][0], pair[1][0], _verdict(pair[1][1])]


def _rate_findings(ours: pd.DataFrame, paper: pd.DataFrame) -> list[list[str]]:
    lines: list[list[_Shown]] = [[], []]
    for what, values in (("paper", paper), ("ours", ours)):
        t = _per_sensor(values, "rate_hz", what)
        rise = {
            s: t.loc[s].dropna().iloc[-1] - t.loc[s].dropna().iloc[0]
            for s in t.index
            if t.loc[s].notna().sum() > 1
        }
        lines[0].append((_by_sensor(rise), [v >= 2 for v in rise.values()]))
        bio = t.loc["BioTacSP"].dropna() if "BioTacSP" in t.index else pd.Series(dtype=float)
        low, high = bio[bio.index <= 212.5], bio[bio.index >= 425]
        drop = float(low.mean() - high.mean()) if len(low) and len(high) else np.nan
        text = f"{high.mean():.1f} → {low.mean():.1f} ({drop:+.1f})" if np.isfinite(drop) else "—"
        lines[1].append((text, [drop <= -10] if np.isfinite(drop) else []))
    return [
        [
            "Accuracy rises with the sampling rate (lowest → full rate, points)",
            *_texts(lines[0]),
            "each sensor gains ≥ 2 points",
        ],
        [
            "BioTac SP collapses at 212.5 Hz and below (mean at ≥ 425 Hz → at ≤ 212.5 Hz, %)",
            *_texts(lines[1]),
            "a drop of ≥ 10 points",
        ],
    ]


def _speed_findings(ours: pd.DataFrame, paper: pd.DataFrame) -> list[list[str]]:
    line: list[_Shown] = []
    for what, values in (("paper", paper), ("ours", ours)):
        m = (
            _means(values[values["training"] == "without"], ["speed_mm_s"], what)
            if len(values)
            else pd.DataFrame()
        )
        if m.empty:
            line.append(("—", []))
            continue
        by = (100 * m.groupby("speed_mm_s")["mean"].mean()).sort_values()
        line.append((", ".join(f"{s:g} mm/s {v:.1f}" for s, v in by.items()), [by.index[0] == 5.0]))
    return [
        [
            "5 mm/s is the hardest speed (mean accuracy without that speed in training, %, lowest first)",
            *_texts(line),
            "5 mm/s lowest",
        ]
    ]


def _material_findings(ours: pd.DataFrame, paper: pd.DataFrame, layout: Layout) -> list[list[str]]:
    line: list[_Shown] = []
    worst = {}
    for what, values in (("paper", paper), ("ours", ours)):
        change, text = _pair(values, layout, what) if len(values) else (np.nan, "")
        worst[what] = text.split(" (")[0]
        line.append((f"{change:+.1f}; most: {text}" if np.isfinite(change) else "—", []))
    line[1] = (line[1][0], [worst["ours"] == worst["paper"]] if worst["ours"] else [])
    return [
        [
            "Materials: the mean change without the material in training (points), and the material losing most",
            *_texts(line),
            "the same material loses most",
        ]
    ]


def _transfer_findings(ours: pd.DataFrame, paper: pd.DataFrame, layout: Layout) -> list[list[str]]:
    line: list[_Shown] = []
    for what, values in (("paper", paper), ("ours", ours)):
        penalty = _matrix(values, layout, what) if len(values) else np.nan
        line.append(
            (
                f"{penalty:+.1f}" if np.isfinite(penalty) else "—",
                [penalty >= 2] if np.isfinite(penalty) else [],
            )
        )
    return [
        [
            "Another unit of the same type tests worse (the unit trained on minus other units, points)",
            *_texts(line),
            "≥ 2 points",
        ]
    ]


def _lead_findings(window_rows: pd.DataFrame, holweg: pd.DataFrame) -> list[list[str]]:
    """The LSTM ahead of Holweg at window 50 (paper: section VI.A), and its TP/TN balance."""
    paper_lead = {
        s: 100 * (_sensor_mean(paper_frame("window-size"), s, "paper") - a)
        for s, a in paper_frame("holweg").set_index("sensor_type")["accuracy"].items()
    }
    at50 = (
        window_rows[window_rows["window"] == 50]
        if "window" in window_rows
        else window_rows.iloc[:0]
    )
    h50 = holweg[holweg["window"] == 50] if "window" in holweg else holweg.iloc[:0]
    ours_lead = {
        s: 100 * (_sensor_mean(at50, s, "ours") - _sensor_mean(h50, s, "ours"))
        for s in SENSOR_ORDER
    }
    ours_lead = {s: v for s, v in ours_lead.items() if np.isfinite(v)}
    rates = paper_frame("rates_window_50").set_index("sensor_type")
    paper_gap = {s: 100 * (r["tp_rate"] - r["tn_rate"]) for s, r in rates.iterrows()}
    ok = at50[at50["status"] == "ok"] if "status" in at50 else at50
    ours_gap = (
        {s: 100 * float((g["tp_rate"] - g["tn_rate"]).mean()) for s, g in ok.groupby("sensor_type")}
        if {"tp_rate", "tn_rate"} <= set(ok.columns)
        else {}
    )
    mean = float(np.mean(list(ours_lead.values()))) if ours_lead else np.nan
    lead = "—" if not ours_lead else "yes" if 10 <= mean <= 20 else "partly" if mean > 0 else "no"
    return [
        [
            "The LSTM is ahead of Holweg by 10-20 points at window 50 (points; mean over sensors)",
            f"{_by_sensor(paper_lead)}; mean {np.mean(list(paper_lead.values())):+.1f}",
            f"{_by_sensor(ours_lead)}; mean {mean:+.1f}" if ours_lead else "—",
            lead,
            "the mean lead is 10 to 20 points ('partly': ahead by less)",
        ],
        [
            "TP and TN rates balance at window 50 (TP − TN rate, points)",
            _by_sensor(paper_gap),
            _by_sensor(ours_gap),
            _verdict([abs(v) <= 5 for v in ours_gap.values()]),
            "within ±5 points",
        ],
    ]


def _sensor_mean(rows: pd.DataFrame, sensor: str, values: str) -> float:
    part = (
        rows[(rows["sensor_type"] == sensor) & (rows["window"] == 50)]
        if "window" in rows
        else rows.iloc[:0]
    )
    if values == "paper":
        return float(part["accuracy"].mean()) if len(part) else np.nan
    m = _means(part, ["sensor_instance"], values) if len(part) else pd.DataFrame(columns=["mean"])
    return float(m["mean"].mean()) if len(m) else np.nan


def paper_findings_table(rows: pd.DataFrame, found: dict[str, tuple[Layout, str]]) -> Table | None:
    """Each of the paper's findings: its numbers (the published tables), ours (the LSTM's rows,
    and Holweg's for the comparison of the two), whether ours show it, and the criterion."""
    model = rows[rows["detector"] == PAPER_MODEL]
    if model.empty:
        return None
    by_table = {
        layout.paper_table: (protocol, layout)
        for protocol, (layout, _) in found.items()
        if layout.paper_table
    }

    def part(
        table: str, detector: str = PAPER_MODEL
    ) -> tuple[pd.DataFrame, pd.DataFrame, Layout | None]:
        if table not in by_table:
            return rows.iloc[:0], paper_frame(table), None
        protocol, layout = by_table[table]
        mine = rows[(rows["protocol"] == protocol) & (rows["detector"] == detector)]
        return (_first_table(mine, layout) if len(mine) else mine), paper_frame(table), layout

    lines = []
    ws, ws_paper, _ = part("window-size")
    if len(ws):
        lines += _window_findings(ws, ws_paper)
    sr, sr_paper, _ = part("sampling-rate")
    if len(sr):
        lines += _rate_findings(sr, sr_paper)
    sp, sp_paper, _ = part("speed-holdout")
    if len(sp):
        lines += _speed_findings(sp, sp_paper)
    mh, mh_paper, layout = part("material-holdout")
    if len(mh) and layout is not None:  # rows come with their layout
        lines += _material_findings(mh, mh_paper, layout)
    ci, ci_paper, layout = part("cross-instance")
    if len(ci) and layout is not None:
        lines += _transfer_findings(ci, ci_paper, layout)
    if len(ws):
        lines += _lead_findings(ws, part("window-size", "holweg")[0])
    if not lines:
        return None
    return Table(
        "Does the reproduction show the paper's findings? The paper's numbers (its LSTM), ours (the LSTM; "
        "Holweg's detector where compared with it), and whether ours show the finding by the criterion.",
        ["Finding"],
        "",
        ["Paper", "Ours", "Shown", "Criterion"],
        [(f,) for f, *_ in lines],
        [c for _, *c in lines],
        "tab:paper-findings",
        wrap={0: 0.28, 1: 0.2, 2: 0.2, 4: 0.14},
        notes=[
            "Means over units (sensor and finger); 'partly': some sensors show it, not all. A layout split "
            "into several tables (decimation, anti-aliasing) is read at its first (plain decimation, no "
            "anti-aliasing)."
        ],
    )
