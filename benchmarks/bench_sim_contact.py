"""Does force direction alone give slip away in the simulation, and how do the simulated BioTac
SP's electrodes compare with real ones? The study behind ``docs/explanation/simulation.md``.

Force sensors (Nano17, OptoForce20): per slip or pressing recording, the median of |f_t| / |f_n|
over its loaded samples (|f_n| > ``LOADED_N``), the force recovered from the channels by the
unit's calibration (``synth.calibrated_forces``; the units' draws are the same in model
versions 2-4, so an earlier model's dataset reads through them too); the AUROC of that one
number for slip against pressing, per sensor type (units pooled) and per unit.

Electrodes (BioTac SP; the simulated ones resampled from 850 to 100 Hz, the real rate), per
recording, on its electrodes with their means removed:

- ``co-movement``: the median correlation over the 276 pairs of electrodes;
- ``PC1 share``: the share of the variance on the first principal component (1: every
  electrode moves in one fixed proportion, as a varying load on a fixed direction gives);
- ``PC1``: that component's direction, a unit vector in electrode space (sign-free): the
  pattern the contact's changes push the electrodes along. The ``spread`` of a class is
  1 - the largest eigenvalue of its recordings' mean ``PC1 PC1^T`` (0: one shared direction;
  23/24: none), and ``AUROC(direction)`` scores each recording by how much nearer its PC1 lies
  to the slip class's mean tensor than to the other class's (each left out of its own class):
  whether the direction of the electrodes' change alone separates the classes.

All three are unchanged by reordering the electrodes, so the simulated grid and the real
SP's layout (not reproduced here) compare. Classes: slip against pressing (simulation; units
apart, and their median), slip (six directions) against touch (BioTacSP-DoS).

Detectors: with ``--results``, each detector and input's mean accuracy per sensor type in each
results folder (``slipbench evaluate`` on each model's dataset), and the last minus the first.

    python benchmarks/bench_sim_contact.py --real DOS [--sim LABEL=DATASET ...] [--scale S]
        [--seed N] [--results LABEL=RESULTS ...] [--out docs/explanation/simulation.md]

``--real``: the folder ``slipbench dataset import biotacsp-dos`` writes. ``--sim``: a simulated
dataset folder and its label (e.g. one written by an earlier model version); the current model
is generated in memory at ``--scale`` and ``--seed`` unless ``--scale 0``. ``--out``: write the
tables into that Markdown file between its ``<!-- bench_sim_contact -->`` markers.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.signal import resample_poly
from sklearn.metrics import roc_auc_score

from slipbench.data.format import Dataset
from slipbench.data.read import read_dataset
from slipbench.data.synth import (
    MODEL_VERSION,
    SENSORS,
    Physics,
    calibrated_forces,
    generate,
    make_unit,
)
from slipbench.store.results import read_results

LOADED_N = 0.05  # N: a sample carries load (8 x the Nano17's noise floor, 20 x the OptoForce20's)
MARK = "<!-- bench_sim_contact -->"
FORCE_SENSORS = ("Nano17", "OptoForce20")


def _seed(ds: Dataset) -> int:
    """The seed a simulated dataset was generated with (its ``source`` says)."""
    found = re.search(r"seed=(\d+)", str(ds.recordings["source"].iloc[0]))
    return int(found.group(1)) if found else 0


def force_ratios(ds: Dataset) -> pd.DataFrame:
    """One row per slip or pressing recording of a force sensor: its median |f_t| / |f_n|."""
    seed, rows = _seed(ds), []
    rec = ds.recordings
    mine = rec[rec["sensor_type"].isin(FORCE_SENSORS) & rec["scenario"].isin(["slip", "press"])]
    for r in mine.itertuples():
        unit = make_unit(seed, r.sensor_type, r.sensor_instance, Physics())
        f = calibrated_forces(ds.samples[r.recording_id], SENSORS[r.sensor_type], unit)
        tangential, normal = np.hypot(f[0], f[1]), np.abs(f[2])
        loaded = normal > LOADED_N
        if loaded.sum() >= 10:
            ratio = float(np.median(tangential[loaded] / normal[loaded]))
            rows.append((r.sensor_type, r.sensor_instance, r.scenario, ratio))
    return pd.DataFrame(rows, columns=["sensor_type", "instance", "scenario", "ratio"])


def _auroc(frame: pd.DataFrame) -> float:
    slip = frame["scenario"] == "slip"
    return float(roc_auc_score(slip, frame["ratio"])) if 0 < slip.sum() < len(frame) else np.nan


def ratio_table(ratios: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """Per dataset and force sensor: the AUROC pooled and per unit, and each class's quartiles."""
    out = []
    for label, df in ratios.items():
        for sensor, g in df.groupby("sensor_type"):
            units = [_auroc(u) for _, u in g.groupby("instance")]
            q = {
                s: np.percentile(g.loc[g["scenario"] == s, "ratio"], [25, 50, 75])
                for s in ("slip", "press")
            }
            out.append(
                {
                    "data": label,
                    "sensor": sensor,
                    "recordings (slip / press)": f"{(g['scenario'] == 'slip').sum()} / "
                    f"{(g['scenario'] == 'press').sum()}",
                    "AUROC": f"{_auroc(g):.2f}",
                    "AUROC per unit": ", ".join(f"{a:.2f}" for a in units),
                    "slip: median [IQR]": "{1:.2f} [{0:.2f}, {2:.2f}]".format(*q["slip"]),
                    "press: median [IQR]": "{1:.2f} [{0:.2f}, {2:.2f}]".format(*q["press"]),
                }
            )
    return pd.DataFrame(out)


def _electrodes(ds: Dataset, r) -> np.ndarray:
    """A recording's electrodes at 100 Hz, their means removed, (n, 24) float64."""
    names = [c for c in r.channels if re.fullmatch(r"(ff_)?e\d+", c)]
    x = ds.samples[r.recording_id][:, [r.channels.index(c) for c in names]].astype(np.float64)
    x = x - x.mean(axis=0)  # resample_poly pads with zeros: an offset would ring at the ends
    if round(r.sampling_rate_hz) == 850:  # the simulation's rate: 850 x 2 / 17 = 100 Hz
        x = resample_poly(x, 2, 17, axis=0)
    return x


def electrode_rows(ds: Dataset) -> pd.DataFrame:
    """Per slip, press (touch) recording with electrodes: co-movement, PC1 share, PC1."""
    rows = []
    rec = ds.recordings[ds.recordings["scenario"].isin(["slip", "press"])]
    for r in rec.itertuples():
        x = _electrodes(ds, r)
        if x.shape[1] != 24 or len(x) < 50:
            continue
        moving = x.std(axis=0) > 0
        corr = np.corrcoef(x[:, moving].T)
        _, sv, vt = np.linalg.svd(x, full_matrices=False)
        rows.append(
            {
                "unit": r.sensor_instance,
                "slip": r.scenario == "slip",
                "co-movement": float(np.median(corr[np.triu_indices_from(corr, 1)])),
                "PC1 share": float(sv[0] ** 2 / (sv**2).sum()),
                "pc1": vt[0],
            }
        )
    return pd.DataFrame(rows)


def _spread(pc1: np.ndarray) -> float:
    """1 - the largest eigenvalue of the mean orientation tensor of unit vectors (k, 24)."""
    return float(1.0 - np.linalg.eigvalsh(pc1.T @ pc1 / len(pc1))[-1])


def direction_auroc(frame: pd.DataFrame) -> float:
    """AUROC of d' (T_slip - T_other) d, each recording left out of its own class's tensor."""
    d, slip = np.stack(frame["pc1"].to_numpy()), frame["slip"].to_numpy()
    outer = np.einsum("ki,kj->kij", d, d)
    sums = {c: outer[slip == c].sum(axis=0) for c in (True, False)}
    score = []
    for k in range(len(d)):
        t = {
            c: (sums[c] - outer[k] * (slip[k] == c)) / ((slip == c).sum() - (slip[k] == c))
            for c in sums
        }
        score.append(d[k] @ (t[True] - t[False]) @ d[k])
    return float(roc_auc_score(slip, score))


def electrode_table(frames: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """Per dataset and unit: each class's co-movement, PC1 share and direction spread, and the
    AUROC of the direction alone."""
    out = []
    for label, df in frames.items():
        for unit, g in df.groupby("unit"):
            row = {"data": label, "unit": unit, "AUROC(direction)": f"{direction_auroc(g):.2f}"}
            for cls, name in ((True, "slip"), (False, "press/touch")):
                c = g[g["slip"] == cls]
                row[f"{name}: n"] = len(c)
                row[f"{name}: co-movement"] = f"{c['co-movement'].median():.2f}"
                row[f"{name}: PC1 share"] = f"{c['PC1 share'].median():.2f}"
                row[f"{name}: spread"] = f"{_spread(np.stack(c['pc1'].to_numpy())):.2f}"
            out.append(row)
    return pd.DataFrame(out)


CELL = ["detector", "input", "sensor_type", "sensor_instance", "window"]


def _finished(folder: Path) -> pd.DataFrame:
    rows = read_results(folder)
    return rows[rows["status"] == "ok"]


def _run_of(rows: pd.DataFrame) -> str:
    """What a results folder holds: protocols, split, seeds and the data's fingerprint."""
    return "; ".join(
        f"{c} " + ", ".join(sorted(map(str, rows[c].unique())))
        for c in ("protocol", "split", "seed", "dataset_fingerprint")
    )


def detector_table(results: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """Mean accuracy (%) of each detector and input per sensor type over the cells (unit,
    window) that every results folder finished (one column per label), the last minus the
    first, and the units and windows compared."""
    cells = [set(map(tuple, r[CELL].to_numpy())) for r in results.values()]
    common = set.intersection(*cells)
    means = {}
    for label, rows in results.items():
        rows = rows[[tuple(c) in common for c in rows[CELL].to_numpy()]]
        means[label] = 100 * rows.groupby(CELL[:3])["accuracy"].mean()
    by = rows.groupby(CELL[:3])
    table = pd.DataFrame(means).round(1)
    first, last = table.columns[0], table.columns[-1]
    table[f"{last} - {first}"] = (table[last] - table[first]).round(1) + 0.0  # + 0.0: no "-0"
    table["units"] = by["sensor_instance"].agg(lambda u: ", ".join(sorted(set(u))))
    table["windows"] = by["window"].agg(lambda w: ", ".join(map(str, sorted(set(w)))))
    return table.reset_index()


def _datasets(args) -> dict[str, Dataset]:
    sims = {}
    for item in args.sim:
        label, _, path = item.partition("=")
        sims[label] = read_dataset(path)
    if args.scale > 0:
        rec, samples, labels = generate(scale=args.scale, seed=args.seed)
        sims[f"v{MODEL_VERSION} scale {args.scale:g}"] = Dataset(rec, samples, labels)
    return sims


def report(args) -> str:
    """The Markdown the study writes: both tables and what stands behind them."""
    sims = _datasets(args)
    ratios = ratio_table({k: force_ratios(ds) for k, ds in sims.items()})
    frames = {k: electrode_rows(ds) for k, ds in sims.items()}
    frames["BioTacSP-DoS (real)"] = electrode_rows(read_dataset(args.real))
    electrodes = electrode_table(frames)
    results = {k: _finished(Path(v)) for k, _, v in (r.partition("=") for r in args.results)}
    sources = "; ".join(
        f"{k}: {ds.recordings['source'].iloc[0]} ({ds.fingerprint})" for k, ds in sims.items()
    )
    return "\n".join(
        [
            f"Written by `benchmarks/bench_sim_contact.py` (seed {args.seed}). Data: {sources}.",
            "",
            "**Force direction of the force sensors** (median |f_t| / |f_n| per recording):",
            "",
            ratios.to_markdown(index=False),
            "",
            "**Electrodes, simulated and real** (medians over a class's recordings):",
            "",
            electrodes.to_markdown(index=False),
        ]
        + (
            [
                "",
                "**Built-in detectors, before and after** (accuracy %, mean over each sensor "
                "type's units and the windows both sides finished; "
                + "; ".join(f"{k}: {_run_of(v)}" for k, v in results.items())
                + "):",
                "",
                detector_table(results).to_markdown(index=False),
            ]
            if results
            else []
        )
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--real", required=True, help="BioTacSP-DoS dataset folder")
    parser.add_argument("--sim", action="append", default=[], help="LABEL=DATASET")
    parser.add_argument("--scale", type=float, default=0.05)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--results", action="append", default=[], help="LABEL=RESULTS")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    text = report(args)
    if args.out is None:
        print(text)
        return
    doc = args.out.read_text()
    head, _, rest = doc.partition(MARK)
    _, found, tail = rest.partition(MARK)
    if not found:
        raise SystemExit(f"{args.out}: two {MARK} markers expected")
    args.out.write_text(f"{head}{MARK}\n{text}\n{MARK}{tail}")


if __name__ == "__main__":
    main()
