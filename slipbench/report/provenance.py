"""What a report stands on, said first: the data's source, fingerprint, split, labels, seeds,
each detector's parameters, the cells (ok / skipped / failed), the smallest test set behind any
cell, and what fitting chose (bands, thresholds) with its warnings. Reads result rows only,
plus the ``source`` column of a dataset's ``recordings.parquet`` where the rows' path is
readable (results do not copy it).
"""

from __future__ import annotations

import json
import os
import re
from collections import Counter
from functools import cache
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa

from slipbench.atomic import open_parquet
from slipbench.errors import DataError
from slipbench.report.blocks import LOW_MARK, Table
from slipbench.report.order import ordered
from slipbench.report.tables import low_n
from slipbench.stats.bootstrap import DEFAULT_METHOD, FIGURES_AS
from slipbench.store.columns import overridden
from slipbench.vocabulary import SENSOR_TYPE, cell_label, label

STATUSES = ("ok", "skipped", "failed", "timeout")
SYNTH_SOURCE = re.compile(
    r"slipbench\.synth v(?P<version>\S+) seed=(?P<seed>\d+) scale=(?P<scale>[0-9.e+-]+)"
)
SYNTH_FOLDER = re.compile(r"synth-v(?P<version>\w+)-scale(?P<scale>[0-9.e+-]+)-seed(?P<seed>\d+)$")
SPLIT_TEXTS = {
    "paper": "paper: the balanced windows shuffled and halved (windows of one recording on both sides, which "
    "flatters every detector)",
    "grouped": "grouped: whole trials on one side, the same for every unit",
    "datasets": "datasets: trained on one dataset, tested on another",
}
LABEL_TEXTS = {
    "scenario": "scenario: a window's class is its recording's scenario (the paper)",
    "majority": "majority: at least half the window's samples slip",
    "any": "any: a sample of the window slips",
    "last": "last: the window's last sample slips",
}
BALANCE_TEXTS = {
    "within": "within material (the paper): slip equal per material and speed, non-slip per material",
    "across": "across materials: slip equal per speed, non-slip pooled over materials",
}
#: a side and class's windows used, and those the side could hold before balancing
KEPT = [
    (f"{side} {name}", f"{side}_{cls}_windows", f"{side}_{cls}_available")
    for side in ("train", "test")
    for cls, name in (("slip", "slip"), ("nonslip", "non-slip"))
]
NORMALIZATION_TEXTS = {
    "none": "none: the signal as measured (the paper)",
    "recording": "recording: each recording's signal minus its median, over 1.4826 x its median absolute "
    "deviation (its own statistics, the test side's too; this also evens out the amplitude that tells "
    "slip from pressing recordings)",
    "unit": "unit: each sensor unit's signal minus its median, over 1.4826 x its median absolute deviation, "
    "taken on the unit's training-side recordings (a test dataset's unit: on its own recordings)",
}
TOP_VALUES = 2  # fitted values listed per unit before "k more"
MAX_SOURCE_CHARS = 200  # a dataset's sources beyond this are summed up
MAX_WARNINGS = 12


def _simulated(match: re.Match) -> str:
    scale = float(match["scale"])
    return (
        f"simulated (slipbench.synth model v{match['version']}, scale {scale:g}, seed {match['seed']}; "
        f"scale 1.0 is about the paper's size, 8 M samples per unit)"
    )


def _sources(path: str) -> list[str]:
    """The distinct values of the ``source`` column of the dataset at ``path``, sorted."""
    column = (
        open_parquet(Path(path) / "recordings.parquet", page_checksum_verification=True)
        .read(columns=["source"])
        .column("source")
    )
    return sorted({str(s) for s in column.to_pylist() if s is not None})


def _sources_text(sources: list[str]) -> str:
    """The sources of a dataset's recordings, in at most about :data:`MAX_SOURCE_CHARS`
    characters however many there are: listed whole, else what they share said once
    (``BioTacSP-DoS ..., direction {aw, cw, e, n, s, t, w}``), else their count with the first
    and the last (a lab's 1,000 files each naming its own made a 72,000-character line)."""
    whole = "; ".join(sources)
    if len(sources) == 1 or len(whole) <= MAX_SOURCE_CHARS:
        return f"source {whole}"
    shared = re.sub(r"[\w.]*$", "", os.path.commonprefix(sources))  # up to a word's start
    grouped = shared + "{" + ", ".join(s[len(shared) :] for s in sources) + "}"
    if shared and len(grouped) <= MAX_SOURCE_CHARS:
        return f"sources {grouped}"
    return f"{len(sources):,} sources, {sources[0]} … {sources[-1]}"


def dataset_source(path: str) -> str:
    """What the dataset at ``path`` is: simulated with its model, scale and seed, or the values
    of its ``source`` column; from its ``recordings.parquet`` where readable, else from the
    folder's name."""
    if not path:
        return "a dataset built in memory (no path recorded)"
    try:
        sources = _sources(path)
    except (OSError, pa.ArrowException, KeyError, DataError):
        sources = None
    if sources:
        simulated = [m for m in map(SYNTH_SOURCE.search, sources) if m]
        if len(simulated) == len(sources) and len({m[0] for m in simulated}) == 1:
            return _simulated(simulated[0])
        return f"recorded: {_sources_text(sources)} (at {path})"
    folder = SYNTH_FOLDER.search(Path(path).name)
    if folder:
        return _simulated(folder) + " (from its folder's name; the dataset is not readable here)"
    state = "no source column" if sources == [] else "not readable here"
    return f"the dataset at {path} ({state})"


# the first model version whose pressing carries shear inside the friction cone (docs/explanation/simulation.md)
SHEAR_WITHOUT_SLIP = 4


def _gives_slip_away(match: re.Match | None) -> bool:
    version = match["version"] if match else ""
    return version.isdigit() and int(version) < SHEAR_WITHOUT_SLIP


@cache
def simulated(path: str) -> bool:
    """Whether the dataset at ``path`` is slipbench's simulation from a model before
    :data:`SHEAR_WITHOUT_SLIP`, whose force direction alone separates slip from pressing: every
    value of its ``source`` column says so, or, where it is not readable here, its folder's
    name does."""
    if not path:
        return False
    try:
        sources = _sources(path)
    except (OSError, pa.ArrowException, KeyError, DataError):
        return _gives_slip_away(SYNTH_FOLDER.search(Path(path).name))
    return bool(sources) and all(_gives_slip_away(SYNTH_SOURCE.search(s)) for s in sources)


def on_simulation(rows: pd.DataFrame) -> pd.Series:
    """(n_rows,) bool: rows whose test data is a simulation whose force direction gives slip
    away (:func:`simulated`; the test dataset's path where the row trained on another, else the
    dataset's)."""
    path = pd.Series("", index=rows.index, dtype=object)
    for column in ("dataset_path", "test_dataset_path"):  # the test dataset's wins
        if column in rows:
            given = rows[column].notna() & rows[column].astype(str).ne("")
            path[given] = rows.loc[given, column].astype(str)
    return path.map(simulated).astype(bool)


NO_UNIT = {"", "na", "nan", "none", "null"}  # how a missing unit may be spelled in a dataset


def sensor_units(path: str) -> str:
    """The sensors of the dataset at ``path`` as it spells them: each sensor type with its
    instances and its channels' units ("unitless" where the dataset gives none); "" where the
    dataset is not readable here."""
    if not path:
        return ""
    try:
        table = (
            open_parquet(Path(path) / "recordings.parquet", page_checksum_verification=True)
            .read(columns=[SENSOR_TYPE, "sensor_instance", "units"])
            .to_pydict()
        )
    except (OSError, pa.ArrowException, KeyError, DataError):
        return ""
    if not {SENSOR_TYPE, "sensor_instance", "units"} <= table.keys():  # read skips what lacks
        return ""
    sensors: dict[str, tuple[dict, dict]] = {}  # type -> (instances, units), in first-seen order
    for kind, instance, units in zip(table[SENSOR_TYPE], table["sensor_instance"], table["units"]):
        instances, found = sensors.setdefault(str(kind), ({}, {}))
        instances[str(instance)] = None
        for unit in units or [None]:
            text = "" if unit is None else str(unit).strip()
            found["unitless" if text.lower() in NO_UNIT else text] = None
    return "; ".join(
        f"{kind} ({', '.join(instances)}): {', '.join(found)}"
        for kind, (instances, found) in sensors.items()
    )


def _described(rows: pd.DataFrame, describe) -> list[str]:
    """``describe(path)`` once per dataset of ``rows`` (by fingerprint, so that one dataset
    reached by two paths, as two results folders may name it, reads once), each text once."""
    if "dataset_path" not in rows:
        return []
    paths = rows[["dataset_path"]].assign(
        fp=rows["dataset_fingerprint"] if "dataset_fingerprint" in rows else rows["dataset_path"]
    )
    paths = paths.dropna(subset=["dataset_path"]).astype(str)
    texts: dict[str, None] = {}
    for _, group in sorted(paths.groupby("fp", sort=False), key=lambda g: str(g[0])):
        candidates = sorted(group["dataset_path"].unique())
        # the first path that reads, else the first: a folder moved since the run still names one
        described = [describe(p) for p in candidates]
        readable = [t for p, t in zip(candidates, described) if t and Path(p).exists()]
        text = (readable or described)[0]
        if text:
            texts[text] = None
    return list(texts)


def _data_lines(rows: pd.DataFrame) -> list[tuple[str, str]]:
    """The header's lines on the data: its source and fingerprint; for rows trained on one
    dataset and tested on another, both datasets (source, path, fingerprint) and how the test
    dataset's units were matched to the training dataset's."""
    crossed = (
        rows["train_dataset_path"].notna().to_numpy()
        if "train_dataset_path" in rows
        else np.zeros(len(rows), bool)
    )
    across, within = rows[crossed], rows[~crossed]
    lines = []
    if len(within) or not len(across):
        lines += [
            (
                "Data",
                "; ".join(_described(within, dataset_source)) or "unknown (the rows do not say)",
            ),
            *(
                [("Sensors (units)", " | ".join(sensors))]
                if (sensors := _described(within, sensor_units))
                else []
            ),
            (
                "Dataset fingerprint",
                ", ".join(map(str, _values(within, "dataset_fingerprint"))) or "unknown",
            ),
        ]
    pairs = (
        across[
            [
                "train_dataset_path",
                "train_dataset_fingerprint",
                "test_dataset_path",
                "test_dataset_fingerprint",
            ]
        ]
        .drop_duplicates()
        .itertuples(index=False, name=None)
        if len(across)
        else []
    )
    for train_path, train_fp, test_path, test_fp in pairs:
        lines += [
            ("Trained on", f"{dataset_source(str(train_path))}; fingerprint {train_fp}"),
            ("Tested on", f"{dataset_source(str(test_path))}; fingerprint {test_fp}"),
        ]
    for text in _values(across, "sensor_map"):
        try:
            pairs_ = json.loads(text)
        except (TypeError, json.JSONDecodeError):
            pairs_ = {"?": str(text)}
        lines.append(
            (
                "Sensor map (test unit → training unit)",
                ", ".join(f"{a} → {b}" for a, b in pairs_.items()) or "(none)",
            )
        )
    return lines


def _params(text: str) -> str:
    """``{"band": null, "keep": 0.8}`` as ``band=null; keep=0.8``."""
    try:
        params = json.loads(text)
    except (TypeError, json.JSONDecodeError):
        return str(text)
    return (
        "; ".join(f"{k}={json.dumps(v, separators=(', ', ': '))}" for k, v in params.items())
        or "(none)"
    )


def _ran(text: str, rows: pd.DataFrame) -> str:
    """The parameters ``text`` (JSON) as ``rows``' finished fits ran them: a parameter a fit
    overrode (``fitted``'s ``overrides``) shows the value that ran, the one asked and why, and
    in how many cells where not in all."""
    if "fitted" not in rows:  # rows of another tool, or of a version before `fitted`
        return _params(text)
    ok = rows[(rows["status"] == "ok") & rows["fitted"].notna()]
    seen: Counter[tuple[str, str]] = Counter()
    for fitted in ok["fitted"]:
        for name, o in json.loads(fitted or "{}").get("overrides", {}).items():
            seen[(name, overridden(name, o["ran"], o["asked"], o["why"]))] += 1
    try:
        params = json.loads(text)
    except (TypeError, json.JSONDecodeError):
        params = None
    if not seen or not isinstance(params, dict):
        return _params(text)
    shown = []
    for name, value in params.items():
        mine = [(said, n) for (k, said), n in seen.items() if k == name]
        shown += [
            said + ("" if n == len(ok) else f" in {n} of {len(ok)} cells") for said, n in mine
        ]
        if not mine:
            shown.append(f"{name}={json.dumps(value, separators=(', ', ': '))}")
    return "; ".join(shown)


def _counts(rows: pd.DataFrame) -> str:
    counts = rows["status"].value_counts()
    others = [s for s in counts.index if s not in STATUSES]
    return f"{len(rows)}: " + ", ".join(
        f"{int(counts.get(s, 0))} {s}" for s in (*STATUSES, *others)
    )


def _values(rows: pd.DataFrame, column: str) -> list:
    return sorted(rows[column].dropna().unique(), key=str) if column in rows else []


def _intervals(rows: pd.DataFrame) -> str:
    """How the 95 % intervals were computed: each cell's with the method its row records (rows
    written before it was recorded took ``satterthwaite``); a mean over fingers or seeds, here,
    with today's default from the stored predictions (:mod:`slipbench.stats.joint`). Every
    interval here is a figure's, so a method whose changes alone differ names the figures' one."""
    stored = [_as_figure(str(m)) for m in _values(rows, "interval_method")]
    if "interval_method" not in rows or rows["interval_method"].isna().any():
        stored = sorted({*stored, "satterthwaite (not recorded in older rows)"})
    return (
        f"95 %, cluster bootstrap over test trials; a cell's: method {', '.join(stored)}; "
        f"a mean over fingers or seeds: bootstrapped for this report with "
        f"{_as_figure(DEFAULT_METHOD)} from the stored predictions (without them, combined from "
        "the rows, as its note says)"
    )


def _as_figure(method: str) -> str:
    """A method's name, with the method whose interval its figures take where that differs:
    ``scale-choice (a figure's interval: replicate-logit)``."""
    return (
        f"{method} (a figure's interval: {FIGURES_AS[method]})" if method in FIGURES_AS else method
    )


def _where(row: pd.Series) -> str:
    return (
        f"{row['protocol']}, {row['detector']}, {cell_label(_tested_key(row))}"
        if "cell" in row
        else str(row["protocol"])
    )


def _tested_key(row: pd.Series) -> dict | str:
    """A cell's key naming the units it tested: a row trained on one dataset and tested on
    another keys its cell by the training dataset's unit (its ``sensor_map`` says which test
    unit was tested as it), so the tested instance reads ``Vib:ff (trained as BioTacSP ff)``."""
    mapped = row.get("sensor_map")
    if not isinstance(mapped, str) or not mapped:
        return row["cell"]
    try:
        key, pairs = json.loads(row["cell"]), json.loads(mapped)
        tested: dict[str, list[str]] = {}
        for test, train in pairs.items():
            tested.setdefault(str(train), []).append(str(test))
    except (TypeError, AttributeError, json.JSONDecodeError):
        return row["cell"]  # a key or map this version cannot read: named as stored
    kind = key.get(SENSOR_TYPE)
    for column in ("sensor_instance", "test_instance"):
        names = tested.get(f"{kind}:{key.get(column)}")
        if column in key and names:
            key[column] = f"{' + '.join(names)} (trained as {kind} {key[column]})"
    return key


def _smallest(rows: pd.DataFrame) -> str:
    """The finished cell with the fewest test trials, and the one with the fewest test windows."""
    ok = rows[rows["status"] == "ok"] if "status" in rows else rows
    found: dict[int, list[str]] = {}
    for column, unit in (("n_test_trials", "test trials"), ("n_test", "test windows")):
        if column in ok and ok[column].notna().any():
            at = pd.to_numeric(ok[column], errors="coerce").idxmin()
            found.setdefault(at, []).append(f"{int(ok.loc[at, column])} {unit}")
    return (
        "; ".join(f"{', '.join(what)} ({_where(ok.loc[at])})" for at, what in found.items())
        or "unknown (the rows do not say)"
    )


def balance_kept(rows: pd.DataFrame) -> str:
    """The windows the cells used of those their sides could hold before balancing, per side
    and class, summed over the cells that record both ("" where none does)."""
    parts, cells = [], 0
    for name, used, could in KEPT:
        if used not in rows or could not in rows:
            continue
        both = rows[[used, could]].apply(pd.to_numeric, errors="coerce").dropna()
        if len(both):
            cells = max(cells, len(both))
            parts.append(f"{name} {int(both[used].sum()):,} of {int(both[could].sum()):,}")
    return f"{', '.join(parts)} (summed over {cells} cells)" if parts else ""


def grouped_warnings(rows: pd.DataFrame, limit: int = 10) -> list[str]:
    """The rows' balancing warnings, one line per cause (a unit's, after "Why: "): how many
    cells it concerns (each once, whatever its detectors), of which protocols, and one cell's
    counts as an example; at most ``limit`` lines and one counting the rest."""
    if "balance_warning" not in rows:
        return []
    flagged = rows[rows["balance_warning"].fillna("").astype(str) != ""]
    flagged = flagged.drop_duplicates(["protocol", "cell"])
    causes: dict[str, list[tuple[str, str, str]]] = {}
    for p, c, w in flagged[["protocol", "cell", "balance_warning"]].itertuples(index=False):
        kept, _, why = str(w).partition(". Why: ")
        for cause in why.split("; "):
            causes.setdefault(cause, []).append((str(p), cell_label(c), kept))
    lines = []
    for cause, cells in causes.items():
        protocols = ", ".join(dict.fromkeys(p for p, _, _ in cells))
        _, cell, kept = cells[0]
        lines.append(
            f"balancing kept under half of a class in {len(cells)} {'cell' if len(cells) == 1 else 'cells'} of {protocols} (e.g. {cell}: "
            f"{kept.removeprefix('balancing ')})" + (f". Why: {cause}" if cause else "")
        )
    if len(lines) > limit:
        return lines[:limit] + [f"{len(lines) - limit} more causes (the rows' balance_warning)"]
    return lines


def _balancing(rows: pd.DataFrame) -> list[tuple[str, str]]:
    """The run table's lines on balancing: how, what it kept, and where it kept under half."""
    how = [BALANCE_TEXTS.get(b, b) for b in _values(rows, "balance")] or (
        [BALANCE_TEXTS["within"]] if len(rows) else []
    )
    kept = balance_kept(rows)
    lines = [
        (
            "Balancing",
            "; ".join(how) + (f"; windows used of those available: {kept}" if kept else ""),
        )
    ]
    warned = grouped_warnings(rows, limit=3)
    if warned:
        lines.append(("Balancing kept under half of a class", "; ".join(warned)))
    return lines


def header_tables(
    rows: pd.DataFrame,
    metric: str = "accuracy",
    protocols: list[str] | None = None,
    benchmark: str = "",
    superseded: int = 0,
) -> list[Table]:
    """The report's opening tables: the run (data, split, labels, seeds, cells, smallest test
    set, ``superseded`` rows left out), the detectors with their parameters, and the protocols
    (in the order ``protocols``, default as the rows first name them) with their options."""
    low = low_n(rows) & rows["status"].eq("ok")
    run = [
        *_data_lines(rows),
        *(
            [
                (
                    "Normalization",
                    "; ".join(NORMALIZATION_TEXTS.get(s, s) for s in _values(rows, "normalize")),
                )
            ]
            if _values(rows, "normalize")
            else []
        ),
        ("Split", "; ".join(SPLIT_TEXTS.get(s, s) for s in _values(rows, "split")) or "unknown"),
        ("Labels", "; ".join(LABEL_TEXTS.get(s, s) for s in _values(rows, "labels")) or "unknown"),
        *_balancing(rows),
        ("Seeds", ", ".join(str(int(s)) for s in _values(rows, "seed")) or "unknown"),
        ("Cells", _counts(rows)),
        *(
            [
                (
                    "Cells run again",
                    f"{superseded} earlier {'row' if superseded == 1 else 'rows'} of a cell and "
                    "seed run again later (other code into the same folder) left out: the latest "
                    "run of each is reported",
                )
            ]
            if superseded
            else []
        ),
        ("Smallest test set", _smallest(rows)),
        (
            f"Few test trials ({LOW_MARK})",
            f"{int(low.sum())} finished cells" + (" (marked in every table)" if low.any() else ""),
        ),
        ("Metric", metric),
        ("Intervals", _intervals(rows)),
        ("slipbench", ", ".join(map(str, _values(rows, "slipbench_version"))) or "unknown"),
    ]
    if benchmark:
        run.insert(0, ("Benchmark file", benchmark))
    if "finished_at" in rows and rows["finished_at"].notna().any():
        times = rows["finished_at"].dropna().astype(str)
        run.append(("Cells finished", f"{times.min()[:19]} to {times.max()[:19]} (UTC)"))
    tables = [
        Table(
            "The run: data, split, seeds, cells.",
            ["What"],
            "",
            ["Value"],
            [(a,) for a, _ in run],
            [[b] for _, b in run],
            "tab:provenance",
            wrap={1: 0.7},
        )
    ]
    det_rows: list[tuple[str, ...]] = []
    det_cells: list[list[str]] = []
    for (det, params), part in rows.groupby(
        ["detector", rows.get("detector_params", pd.Series("", index=rows.index))],
        sort=False,
        dropna=False,
    ):
        det_rows.append((str(det),))
        det_cells.append(
            [
                _ran(params, part) if isinstance(params, str) and params else "(not recorded)",
                _counts(part),
            ]
        )
    tables.append(
        Table(
            "Detectors and their parameters.",
            ["Detector"],
            "",
            ["Parameters", "Cells"],
            det_rows,
            det_cells,
            "tab:detectors",
            wrap={1: 0.5, 2: 0.25},
        )
    )
    pro_rows: list[tuple[str, ...]] = []
    pro_cells: list[list[str]] = []
    for protocol in protocols or list(dict.fromkeys(rows["protocol"])):
        part = rows[rows["protocol"] == protocol]
        params = _values(part, "protocol_params")
        pro_rows.append((str(protocol),))
        pro_cells.append(
            [
                "; ".join(_params(p) for p in params) or "(not recorded)",
                _counts(part),
                _smallest(part),
            ]
        )
    tables.append(
        Table(
            "Protocols and their options.",
            ["Protocol"],
            "",
            ["Options", "Cells", "Smallest test set"],
            pro_rows,
            pro_cells,
            "tab:protocols",
            wrap={1: 0.22, 2: 0.2, 3: 0.33},
        )
    )
    return tables


def _unit(row: dict) -> tuple[str, str]:
    instance = row.get("sensor_instance")
    if not isinstance(instance, str):
        instance = row.get("train_instance")
    return str(row.get(SENSOR_TYPE, "")), str(instance if isinstance(instance, str) else "")


def _hz(f: float) -> str:
    """A band edge: whole hertz, or two digits below 10 Hz (a slow sensor's band)."""
    return f"{f:.0f}" if abs(f) >= 10 or f == 0 else f"{f:.2g}"


def _summary(values: list) -> str:
    """Values fitting chose over several cells, in a few words."""
    if all(isinstance(v, bool) for v in values):
        return f"true in {sum(values)} of {len(values)}"
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        x = np.asarray(values, dtype=float)
        return f"{np.median(x):.3g}" + (
            f" ({x.min():.3g} to {x.max():.3g})" if x.min() != x.max() else ""
        )
    if all(isinstance(v, list) and len(v) == 2 for v in values):
        counted = Counter(f"{_hz(v[0])}–{_hz(v[1])}" for v in values).most_common()
        text = ", ".join(f"{b} ({n})" for b, n in counted[:TOP_VALUES])
        return text + (f", {len(counted) - TOP_VALUES} more" if len(counted) > TOP_VALUES else "")
    counted = Counter(json.dumps(v) for v in values).most_common()
    return ", ".join(f"{v} ({n})" for v, n in counted[:TOP_VALUES]) + (
        f", {len(counted) - TOP_VALUES} more" if len(counted) > TOP_VALUES else ""
    )


def fitted_tables(rows: pd.DataFrame) -> list[Table]:
    """Per detector, what fitting chose on each unit (rows' ``fitted`` JSON: bands in Hz,
    thresholds) summarized over the unit's finished cells; then every warning about it (a band
    from 0 Hz thresholds drift, not vibration) with the cells it concerns."""
    if "fitted" not in rows:
        return []
    ok = rows[(rows["status"] == "ok") & rows["fitted"].notna()]
    tables = []
    for det, part in ok.groupby("detector", sort=False):
        per_unit: dict[tuple[str, str], list[dict]] = {}
        for row in part.to_dict("records"):
            choices = json.loads(row["fitted"] or "{}")
            if choices:
                per_unit.setdefault(_unit(row), []).append(choices)
        if not per_unit:
            continue
        # what overrode a parameter shows in the parameters table and the warnings
        keys = list(
            dict.fromkeys(k for cs in per_unit.values() for c in cs for k in c if k != "overrides")
        )
        units = sorted(
            per_unit,
            key=lambda u: (
                ordered([x[0] for x in per_unit], SENSOR_TYPE).index(u[0]),
                ordered([x[1] for x in per_unit], "sensor_instance").index(u[1]),
            ),
        )
        cells = [
            [_summary([c[k] for c in per_unit[u] if k in c]) for k in keys]
            + [str(len(per_unit[u]))]
            for u in units
        ]
        columns = [f"{k[:-3]} (Hz)" if k.endswith("_hz") else k for k in keys] + ["cells"]
        tables.append(
            Table(
                f"What fitting chose: {det}.",
                ["Sensor", "Finger"],
                "",
                columns,
                [(label(SENSOR_TYPE, u[0]), label("sensor_instance", u[1])) for u in units],
                cells,
                f"tab:fitted-{det}",
                wrap={2 + i: 0.55 / len(keys) for i in range(len(keys))},
                notes=[
                    "Over each unit's finished cells of every protocol (a cross-instance cell counts for the "
                    "unit it trained on): numbers as median (range); bands as the most frequent [low, high] "
                    "with their number of cells."
                ],
            )
        )
    if "warnings" in rows:
        tables += _warnings_table(ok)
    return tables


def _warning_kinds(flagged: pd.DataFrame) -> list[tuple[tuple[str, str], list[tuple[str, dict]]]]:
    """(detector, the warning up to its numbers) -> its (text, row) of each cell, most cells
    first."""
    kinds: dict[tuple[str, str], list[tuple[str, dict]]] = {}
    for row in flagged.to_dict("records"):
        for text in str(row["warnings"]).split("; "):
            kinds.setdefault((str(row["detector"]), re.sub(r"\d+(\.\d+)?", "#", text)), []).append(
                (text, row)
            )
    return sorted(kinds.items(), key=lambda kv: (-len(kv[1]), kv[0]))


def _warning_cells(found: list[tuple[str, dict]]) -> tuple[str, str, str]:
    """One kind of warning: its most frequent wording, its number of cells, its units."""
    wording = Counter(t for t, _ in found).most_common()
    others = len(wording) - 1
    text = wording[0][0] + (f" (and {others} other value{'s' * (others > 1)})" if others else "")
    units = list(dict.fromkeys(_unit(r) for _, r in found))
    return (
        text,
        str(len(found)),
        ", ".join(f"{label('sensor_type', s)} {label('sensor_instance', i)}" for s, i in units),
    )


def fitting_warnings(rows: pd.DataFrame, limit: int = 10) -> list[str]:
    """The finished rows' warnings about fitting (a detector that ran another setting than it
    was given, a model that did not learn, ...), one line per detector and kind, as the
    report's table of them: its wording, the cells of the finished ones and the units; at most
    ``limit`` lines and one counting the rest."""
    if "warnings" not in rows:
        return []
    ok = rows[rows["status"] == "ok"]
    lines = _warning_kinds(ok[ok["warnings"].fillna("") != ""])
    out = []
    for (detector, _), found in lines[:limit]:
        text, n, units = _warning_cells(found)
        out.append(f"{detector}: {text} (in {n} of {len(ok)} finished cells: {units})")
    if len(lines) > limit:
        out.append(f"{len(lines) - limit} more kinds of warning about fitting (the rows' warnings)")
    return out


def _warnings_table(ok: pd.DataFrame) -> list[Table]:
    """Warnings about fitting, one line per detector and kind of warning (the same text up to
    its numbers): its most frequent wording, the cells and the units it concerns. A model that
    "did not learn" is one whose balanced accuracy on its training windows, or on the validation
    windows it held out, cannot be told from chance
    (:func:`slipbench.stats.metrics.chance_interval`); a note says so where one is shown."""
    flagged = ok[ok["warnings"].fillna("") != ""]
    lines = _warning_kinds(flagged)
    if not lines:
        return []
    cells = [list(_warning_cells(found)) for _, found in lines[:MAX_WARNINGS]]
    kinds = dict(lines)
    notes = (
        [f"{len(lines) - MAX_WARNINGS} further kinds of warning not shown."]
        if len(lines) > MAX_WARNINGS
        else []
    )
    if any(kind.startswith("did not learn") for _, kind in kinds):
        notes.append(
            "Did not learn: the 95 % Wilson interval of the balanced accuracy the fitted model scores "
            "on its own training windows, or on the validation windows it held out from them (threshold "
            "0.5, over 4 / (1/n_slip + 1/n_non-slip) windows), reaches 0.5; its test figures then say "
            "nothing about generalizing."
        )
    return [
        Table(
            f"Warnings about fitting ({len(flagged)} of {len(ok)} finished cells).",
            ["Detector"],
            "",
            ["Warning", "Cells", "Units"],
            [(d,) for (d, _), _ in lines[:MAX_WARNINGS]],
            cells,
            "tab:warnings",
            notes=notes,
            wrap={1: 0.45, 3: 0.3},
        )
    ]
