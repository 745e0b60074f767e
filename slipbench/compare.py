"""Two result sets -> per-cell changes with paired intervals, significance, and a CI verdict.

Cells are paired on (protocol, cell key, split, seed), and on the detector as well when both
sides hold the same detectors (comparing one detector's two versions); when each side holds a
single detector, they are compared with each other (comparing two detectors). Where both sides
stored their test predictions (``predictions/<key>.parquet``), the windows are joined on
(recording_id, window_index) and compared pairwise: McNemar's test and a paired cluster
bootstrap of the change. Otherwise the change is judged from the two rows alone (unpaired: the
intervals' half-widths combined as independent errors), and the output says so.

A cell *regressed* when its accuracy fell by more than the margin and the fall is significant
after Holm's correction across the cells of its table (one protocol, detector, split).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
from scipy.stats import norm

from .errors import DataError, UsageError
from .metrics import LEVEL, holm, paired_comparison
from .report import layouts, protocol_order
from .tables import ORDERS
from .results import read_results

ALPHA = 1 - LEVEL
FIGURES = ("accuracy", "tp_rate", "tn_rate")
KEY_ORDER = ("sensor_type", "sensor_instance", "train_instance", "test_instance")
MARKS = {"regressed": "▼ regressed", "improved": "▲ improved", "within margin": "≈ within margin",
         "no significant change": "= no significant change"}


@dataclass
class Comparison:
    """The outcome of :func:`compare`."""

    cells: pd.DataFrame  # one row per paired cell: deltas, intervals, p-values, verdict
    only_base: pd.DataFrame  # cells in BASE only: protocol, detector, split, seed, cell
    only_candidate: pd.DataFrame
    base: str
    candidate: str
    margin: float  # percentage points
    notes: list[str] = field(default_factory=list)

    @property
    def regressions(self) -> pd.DataFrame:
        return self.cells[self.cells["verdict"] == "regressed"]

    @property
    def exit_code(self) -> int:
        """0 when nothing regressed beyond the margin, 1 when something did."""
        return int(len(self.regressions) > 0)


def _folder(path: str | os.PathLike) -> Path:
    path = Path(path)
    return path if path.is_dir() else path.parent


def _predictions(folder: Path, key: str) -> pd.DataFrame | None:
    path = folder / "predictions" / f"{key}.parquet"
    if not path.is_file():
        return None
    try:
        return pq.read_table(path, columns=["recording_id", "window_index", "y_true", "score"]).to_pandas()
    except Exception as exc:  # a torn or foreign file is a data error naming the file
        raise DataError(f"{path}: not a readable predictions file ({exc})") from None


def _cell_items(cell: str) -> list[tuple[str, object]]:
    """A cell's key items, sensor first (the JSON is stored with sorted keys)."""
    try:
        items = json.loads(cell).items()
    except (TypeError, json.JSONDecodeError):
        return [("cell", cell)]
    return sorted(items, key=lambda kv: (KEY_ORDER.index(kv[0]) if kv[0] in KEY_ORDER else len(KEY_ORDER), kv[0]))


def cell_name(cell: str) -> str:
    """``sensor_type=Nano17, sensor_instance=index, window=50`` from a cell's JSON key."""
    return ", ".join(f"{k}={v}" for k, v in _cell_items(cell))


def _cell_rank(cell: str) -> tuple:
    """Sort key of a cell in the paper's order: sensors, fingers, materials as the tables list them."""
    out = []
    for k, v in _cell_items(cell):
        order = ORDERS.get(k, ())
        out.append((0, order.index(v), "") if v in order else
                   (1, float(v), "") if isinstance(v, (int, float)) else (2, 0.0, str(v)))
    return tuple(out)


def _pairing(base: pd.DataFrame, cand: pd.DataFrame) -> list[str]:
    on = ["protocol", "cell", "split", "seed"]
    for side, rows in (("BASE", base), ("CANDIDATE", cand)):
        missing = set(on) - set(rows.columns)
        if missing:
            raise DataError(f"{side}: results lack the columns {', '.join(sorted(missing))}")
    b, c = set(base["detector"]), set(cand["detector"])
    if b == c:
        return [*on, "detector"]
    if len(b) == 1 and len(c) == 1:
        return on
    raise UsageError(
        f"cannot pair detectors: BASE holds {', '.join(sorted(b))}, CANDIDATE holds {', '.join(sorted(c))}; "
        "compare results of the same detectors, or of one detector on each side")


def _unique(rows: pd.DataFrame, on: list[str], side: str) -> pd.DataFrame:
    dup = rows.duplicated(on, keep=False)
    if dup.any():
        first = rows[dup].iloc[0]
        raise DataError(
            f"{side} holds {int(dup.sum())} rows for one cell ({first['protocol']}, {first['detector']}, "
            f"{cell_name(first['cell'])}, seed {first['seed']}): runs with different parameters or datasets "
            "share the folder; compare folders that hold one run per cell")
    return rows


def _paired(base_row, cand_row, folders: tuple[Path, Path], seed: int) -> dict | None:
    """Paired figures from the two cells' predictions, or None when they cannot be joined."""
    preds = [_predictions(f, r["key"]) for f, r in zip(folders, (base_row, cand_row))]
    if any(p is None for p in preds):
        return None
    joined = preds[0].merge(preds[1], on=["recording_id", "window_index"], suffixes=("_b", "_c"))
    if joined.empty or (joined["y_true_b"] != joined["y_true_c"]).any():
        return None
    out = paired_comparison(joined["y_true_b"].to_numpy(), joined["score_b"].to_numpy() >= 0.5,
                            joined["score_c"].to_numpy() >= 0.5, joined["recording_id"].to_numpy(), seed)
    out["p"] = out.pop("mcnemar_p")
    out["method"] = "paired" if len(joined) == len(preds[0]) == len(preds[1]) else f"paired ({len(joined)} shared windows)"
    return out


def _unpaired(base_row, cand_row) -> dict:
    """Change judged from the two rows: their interval half-widths combined as independent."""
    out: dict = {"method": "unpaired"}
    z = norm.ppf(1 - ALPHA / 2)
    for name in FIGURES:
        d = float(cand_row[name]) - float(base_row[name])
        half = np.hypot(*[(float(r.get(f"{name}_hi", np.nan)) - float(r.get(f"{name}_lo", np.nan))) / 2
                          for r in (base_row, cand_row)])
        out[f"d_{name}"], out[f"d_{name}_lo"], out[f"d_{name}_hi"] = d, d - half, d + half
        if name == "accuracy":  # two-sided normal test of the change
            out["p"] = float(2 * norm.sf(abs(d) / (half / z))) if half > 0 else float(d == 0)
    return out


def compare(base_path: str | os.PathLike, candidate_path: str | os.PathLike, margin: float = 0.0,
            seed: int = 0) -> Comparison:
    """Compare CANDIDATE against BASE cell by cell.

    Parameters
    ----------
    base_path, candidate_path
        Results files or folders (as ``evaluate --out`` writes them).
    margin : float
        Percentage points of accuracy a cell may lose without counting as a regression.
    seed : int
        Seeds the paired bootstraps.
    """
    if margin < 0:
        raise UsageError(f"--margin must be >= 0 percentage points, got {margin}")
    base, cand = read_results(base_path), read_results(candidate_path)
    on = _pairing(base, cand)
    base, cand = _unique(base, on, "BASE"), _unique(cand, on, "CANDIDATE")
    merged = base.merge(cand, on=on, how="outer", suffixes=("_b", "_c"), indicator=True)
    ident = ["protocol", "detector", "split", "seed", "cell"]
    sides = []
    for tag, suffix in (("left_only", "_b"), ("right_only", "_c")):
        rows = merged[merged["_merge"] == tag]
        sides.append((rows if "detector" in on else rows.assign(detector=rows[f"detector{suffix}"]))[ident])
    only_base, only_cand = sides
    both = merged[merged["_merge"] == "both"]
    if both.empty:
        raise DataError(f"BASE {base_path} and CANDIDATE {candidate_path} share no cell "
                        f"(protocols {sorted(set(base['protocol']))} vs {sorted(set(cand['protocol']))})")
    folders = (_folder(base_path), _folder(candidate_path))
    notes = []
    fb, fc = (set(r.get("dataset_fingerprint", pd.Series(dtype=str)).dropna()) for r in (base, cand))
    if fb and fc and fb != fc:
        notes.append(f"The datasets differ (fingerprints {', '.join(sorted(fb))} vs {', '.join(sorted(fc))}): "
                     "cells were compared on the windows they share, or unpaired.")
    out = []
    for _, row in both.iterrows():
        b = {k[:-2]: v for k, v in row.items() if k.endswith("_b")} | {k: row[k] for k in on}
        c = {k[:-2]: v for k, v in row.items() if k.endswith("_c")} | {k: row[k] for k in on}
        entry = {k: row[k] for k in on}
        entry["detector"] = row["detector"] if "detector" in on else f"{row['detector_b']} → {row['detector_c']}"
        entry["base_accuracy"], entry["candidate_accuracy"] = b["accuracy"], c["accuracy"]
        entry["base_status"], entry["candidate_status"] = b.get("status", "ok"), c.get("status", "ok")
        if entry["base_status"] == "ok" and entry["candidate_status"] == "ok":
            entry |= _paired(b, c, folders, seed) or _unpaired(b, c)
        else:
            entry["method"] = f"status {entry['base_status']} → {entry['candidate_status']}"
        out.append(entry)
    cells = pd.DataFrame(out)
    order = protocol_order(layouts(pd.concat([base, cand], ignore_index=True)))
    rank = [(order.index(p), p, d, sp, _cell_rank(c), s)
            for p, d, sp, c, s in cells[["protocol", "detector", "split", "cell", "seed"]].itertuples(index=False)]
    cells = cells.iloc[sorted(range(len(cells)), key=rank.__getitem__)].reset_index(drop=True)
    for col in ("p", *(f"d_{n}{s}" for n in FIGURES for s in ("", "_lo", "_hi"))):
        if col not in cells:
            cells[col] = np.nan
    # Holm across the cells of one table: one protocol, detector (pair) and split.
    cells["p_holm"] = np.nan
    for _, idx in cells.groupby(["protocol", "detector", "split"], sort=False).groups.items():
        cells.loc[idx, "p_holm"] = holm(cells.loc[idx, "p"])
    cells["verdict"] = [_verdict(r, margin) for r in cells.to_dict("records")]
    return Comparison(cells, only_base, only_cand, str(base_path), str(candidate_path), margin, notes)


def _verdict(r: dict, margin: float) -> str:
    if r["base_status"] != r["candidate_status"]:
        if r["base_status"] == "ok":
            return "regressed"  # the candidate no longer finishes a cell the base finished
        if r["candidate_status"] == "ok":
            return "improved"
        return "no significant change"
    d = r["d_accuracy"]
    if pd.isna(d) or pd.isna(r["p_holm"]) or r["p_holm"] >= ALPHA:
        return "no significant change"
    if abs(d) * 100 <= margin:
        return "within margin"
    return "regressed" if d < 0 else "improved"


# ----------------------------------------------------------------------------- Markdown
def _delta(r: dict, name: str) -> str:
    d, lo, hi = r.get(f"d_{name}"), r.get(f"d_{name}_lo"), r.get(f"d_{name}_hi")
    if d is None or pd.isna(d):
        return "—"
    text = f"{100 * d:+.1f}"
    return text + (f" [{100 * lo:+.1f}, {100 * hi:+.1f}]" if not (pd.isna(lo) or pd.isna(hi)) else "")


def _p(p: float) -> str:
    return "—" if pd.isna(p) else ("<0.001" if p < 1e-3 else f"{p:.3f}")


def _cells_table(cells: pd.DataFrame) -> str:
    lines = []
    for r in cells.to_dict("records"):
        lines.append({
            "protocol": r["protocol"], "detector": r["detector"], "cell": cell_name(r["cell"]),
            "seed": r["seed"],
            "accuracy": f"{100 * r['base_accuracy']:.1f} → {100 * r['candidate_accuracy']:.1f}"
            if r["base_status"] == r["candidate_status"] == "ok" else f"{r['base_status']} → {r['candidate_status']}",
            "Δ accuracy [95 % CI]": _delta(r, "accuracy"), "Δ TP rate": _delta(r, "tp_rate"),
            "Δ TN rate": _delta(r, "tn_rate"), "p (Holm)": _p(r["p_holm"]), "method": r["method"],
            "": MARKS[r["verdict"]],
        })
    return pd.DataFrame(lines).to_markdown(index=False, disable_numparse=True)


def _side_list(rows: pd.DataFrame) -> list[str]:
    return [f"- {r['protocol']}, {r['detector']}, {cell_name(r['cell'])}, split {r['split']}, seed {r['seed']}"
            for r in rows.to_dict("records")]


def to_markdown(cmp: Comparison) -> str:
    """A pull-request comment: the verdict, the changed cells, then every cell folded away."""
    cells = cmp.cells
    counts = cells["verdict"].value_counts()
    n_reg = int(counts.get("regressed", 0))
    head = ["## slipbench compare", "",
            f"BASE `{cmp.base}` → CANDIDATE `{cmp.candidate}`; {len(cells)} cells paired; margin {cmp.margin:g} points.", ""]
    if n_reg:
        head.append(f"**{n_reg} cell{'s' * (n_reg > 1)} regressed** beyond the margin:")
    else:
        head.append("**No regression** beyond the margin.")
    head.append("")
    head.append(", ".join(f"{MARKS[v]}: {int(counts.get(v, 0))}" for v in MARKS))
    parts = ["\n".join(head)]
    changed = cells[cells["verdict"].isin(["regressed", "improved"])]
    if len(changed):
        order = changed.assign(_o=changed["verdict"].map({"regressed": 0, "improved": 1})).sort_values("_o", kind="stable")
        parts.append(_cells_table(order.drop(columns="_o")))
    parts.append("<details><summary>All paired cells</summary>\n\n" + _cells_table(cells) + "\n\n</details>")
    for title, rows in (("Cells only in BASE", cmp.only_base), ("Cells only in CANDIDATE", cmp.only_candidate)):
        if len(rows):
            parts.append(f"**{title}** ({len(rows)}), not compared:\n\n" + "\n".join(_side_list(rows)))
    parts.append("_Δ: candidate − base, percentage points, with a 95 % paired cluster-bootstrap interval over "
                 "recordings. p: McNemar's test on the shared test windows, Holm-corrected across the cells of "
                 "each table. A cell regresses when its accuracy falls by more than the margin, significantly._")
    parts += [f"_{n}_" for n in cmp.notes]
    return "\n\n".join(parts) + "\n"

