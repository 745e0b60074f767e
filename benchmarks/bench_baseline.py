"""The reference baseline ``features`` (issue 36), measured: its balanced accuracy on the BioTac SP
DoS recordings at 500 ms with the grouped split, beside every other built-in detector on the
same cells; that it runs every protocol on both inputs of the simulation and of DoS; and its
cost against holweg, bandpass and the LSTM timed in the same run. Writes ``docs/studies/baseline.md``.

    nice python benchmarks/bench_baseline.py --dos PATH/biotacsp-dos/csvs --out docs/studies/baseline.md

DoS: ``slipbench dataset import biotacsp-dos`` of ``--dos`` into ``--work``; protocol
window-size with ``windows=["500ms"]`` (50 samples at 100 Hz), split ``grouped``, seeds 0 to
``--seeds`` - 1, each seed its own balancing and split of whole recordings. The simulation: the
default dataset at ``--scale``, seed 0, every protocol with its default options, split paper.
Cells already in ``--work`` are reused (their keys hold code, data, parameters and seed), so an
interrupted run resumes.

Speed: toy windows (``slipbench.testing``) of ``--window`` samples, ``--windows`` of them (the
LSTM, at batch 1, on ``--lstm-windows``), univariate and of 6 channels (the Nano17's count);
each detector fitted in turn, best of ``--repeats`` fits (the LSTM's one) and of at least 3
scorings, on one thread (BLAS, numba): the figures are the engine's ``train_us_per_sample`` (fit seconds per window
sample) and ``infer_us_per_window``.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import tempfile
import time
from datetime import datetime, timezone
from importlib.metadata import version
from importlib.util import find_spec
from pathlib import Path

import numpy as np
import pandas as pd
import sklearn
from threadpoolctl import threadpool_limits

import slipbench
from slipbench.base import BaseDetector
from slipbench.data.defaults import default_dataset
from slipbench.data.format import Dataset
from slipbench.data.importers.biotacsp import biotacsp_dos
from slipbench.data.read import read_dataset
from slipbench.engine.plan import Run
from slipbench.engine.registry import detectors, protocols
from slipbench.engine.runner import evaluate
from slipbench.store.results import ResultsStore
from slipbench.testing import toy_channel_windows, toy_windows

# issue 36: an independent logistic regression on per-channel statistics, grouped 5-fold by
# recording, all windows of 500 ms (no balancing); not a slipbench run
INDEPENDENT_CHANNELS = 0.884
WINDOW = "500ms"


def reference_name() -> str:
    """The id of the detector marked as the reference (``BaseDetector.reference``)."""
    return next(n for n in detectors.names() if detectors.get(n).reference)


def runnable() -> tuple[list[str], list[str]]:
    """The registered detectors that can run here, and those that cannot, with why (minirocket
    needs aeon)."""
    status = {n: detectors.status(n) for n in detectors.names()}
    absent = [f"{n} ({s.state}: {s.detail})" for n, s in status.items() if s.state != "ok"]
    return [n for n, s in status.items() if s.state == "ok"], absent


def runs_of(names: list[str], protocol: str, seeds: range, **options) -> list[Run]:
    """One run per detector, input it reads, seed; ``options`` set where the protocol takes them."""
    out = []
    for name in names:
        for kind in detectors.get(name).inputs:
            for seed in seeds:
                p = protocols.get(protocol)()
                p.set_params(**{k: v for k, v in options.items() if k in p.get_params()})
                out.append(Run(name, p, split=options.get("split", "paper"), seed=seed, input=kind))
    return out


def dos_accuracy(dos: Dataset, work: Path, seeds: int) -> pd.DataFrame:
    """Balanced accuracy of every runnable detector and input at 500 ms, seed by seed."""
    runs = runs_of(runnable()[0], "window-size", range(seeds), windows=[WINDOW], split="grouped")
    return evaluate(dos, runs, ResultsStore(work / "dos-500ms"), jobs=1, progress=True)


def every_protocol(dataset: Dataset, store: Path, **options) -> pd.DataFrame:
    """The reference on every protocol and both inputs: its cells by status (with why cells
    were skipped) and its mean balanced accuracy, or detection rate where it streams."""
    runs = [
        r for p in protocols.names() for r in runs_of([reference_name()], p, range(1), **options)
    ]
    rows = evaluate(dataset, runs, ResultsStore(store), jobs=1, progress=True)
    rows = rows.reindex(columns=[*rows.columns.union(["detection_rate", "reason"])])
    return (
        rows.groupby(["protocol", "input"])
        .agg(
            cells=("status", "size"),
            ok=("status", lambda s: int((s == "ok").sum())),
            skipped=("status", lambda s: int((s == "skipped").sum())),
            failed=("status", lambda s: int(s.isin(["failed", "timeout"]).sum())),
            balanced_accuracy_pct=("balanced_accuracy", lambda s: 100 * s.mean()),
            detection_rate_pct=("detection_rate", lambda s: 100 * s.mean()),
            why_skipped=("reason", lambda s: "; ".join(sorted(set(s.dropna()) - {""}))),
        )
        .reset_index()
        .round(1)
    )


def _best(call, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        call()
        times.append(time.perf_counter() - t0)
    return min(times)


def cost(name: str, x: np.ndarray, y: np.ndarray, repeats: int) -> dict[str, object]:
    """Fit and scoring time of ``name`` on ``x``: µs per training sample and per scored window."""
    params = {"device": "cpu"} if name == "lstm" else {}
    fitted: list[BaseDetector] = []
    fit_s = _best(lambda: fitted.append(detectors.get(name)(**params).fit(x, y, seed=0)), repeats)
    score_s = _best(lambda: fitted[-1].predict_proba(x), max(repeats, 3))  # cheap beside a fit
    return {
        "detector": name,
        "input": "univariate" if x.ndim == 2 else f"{x.shape[2]} channels",
        "windows": len(x),
        "train_us_per_sample": fit_s / (x.shape[0] * x.shape[1]) * 1e6,
        "infer_us_per_window": score_s / len(x) * 1e6,
        "epochs": fitted[-1].fitted_choices().get("epochs", ""),
    }


def speed(windows: int, window: int, lstm_windows: int, repeats: int) -> pd.DataFrame:
    """The reference against holweg, bandpass and the LSTM, on one thread, one after another."""
    import numba

    numba.set_num_threads(1)
    uni, multi = toy_windows(windows, window), toy_channel_windows(windows, window, channels=6)
    few = toy_windows(lstm_windows, window)
    me = reference_name()
    cases = [("holweg", uni), ("bandpass", uni), (me, uni), (me, multi), ("lstm", few)]
    with threadpool_limits(1):
        for name, (x, y) in cases:  # warm-up: imports, numba's compilation, first calls
            cost(name, x[:200], y[:200], 1)
        table = pd.DataFrame([cost(n, x, y, 1 if n == "lstm" else repeats) for n, (x, y) in cases])
    base = table.iloc[0]
    for figure in ("train_us_per_sample", "infer_us_per_window"):
        table[f"{figure} / holweg"] = table[figure] / base[figure]
    return table


def _md(table: pd.DataFrame, digits: int = 3) -> str:
    """Markdown, "-" where a figure does not apply (a streaming cell's accuracy)."""
    shown = table.astype(object).where(table.notna(), None)
    return shown.to_markdown(index=False, floatfmt=f".{digits}g", missingval="-")


def accuracy_table(rows: pd.DataFrame) -> pd.DataFrame:
    """Per detector and input: balanced accuracy over seeds (mean, SD, range), and how far the
    reference's mean on the same input lies above it."""
    by = rows.groupby(["detector", "input"])["balanced_accuracy"]
    table = (by.agg(["mean", "std", "min", "max", "size"]) * [100, 100, 100, 100, 1]).reset_index()
    table = table.rename(columns={"std": "SD", "size": "seeds"})
    me = table[table.detector == reference_name()].set_index("input")["mean"]
    table["reference - it"] = table["input"].map(me) - table["mean"]
    table = table.sort_values(["input", "mean"], ascending=[True, False])
    return table.round(1)


def provenance(args: argparse.Namespace, dos: Dataset, sim: Dataset, load: str) -> str:
    commit = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=False
    ).stdout.strip()
    aeon = find_spec("aeon") and f"aeon {version('aeon')}, "
    return (
        f"slipbench {slipbench.__version__} (commit {commit or 'unknown'}), numpy "
        f"{np.__version__}, scikit-learn {sklearn.__version__}, {aeon or ''}Python "
        f"{platform.python_version()}; {os.cpu_count()} cores, load average {load} at the "
        f"start; {datetime.now(timezone.utc):%Y-%m-%d}. DoS: fingerprint {dos.fingerprint}; the "
        f"simulation: scale {args.scale:g}, seed 0, fingerprint {sim.fingerprint}."
    )


PAGE = """# The reference baseline: `features`

Written by `benchmarks/bench_baseline.py` (its docstring gives every setting); do not edit by
hand. {provenance}

`features` is slipbench's reference detector (`BaseDetector.reference`; `slipbench list` says
so): each channel's (or the univariate signal's) mean, least-squares slope, log standard
deviation, log mean absolute difference, log peak, zero-crossing rate and log mean power in 4
octaves below Nyquist, standardized, into an L2 logistic regression (C = 1, balanced class
weights; scikit-learn). Its docstring (`slipbench/detectors/features.py`) says why each statistic. A
detector worth its cost beats it on the same cells:

    slipbench evaluate --detector features,YOURS --protocol window-size --input both

## BioTac SP DoS at 500 ms, grouped split

Window-size at 500 ms (50 samples at 100 Hz, 24 electrodes), `--split grouped`, seeds 0-{last};
balanced accuracy (%) over the seeds (each seed its own balancing and split of whole
recordings). "reference - it": how far `features` on the same input lies above the detector.
Issue 36's independent logistic regression on per-channel statistics reached
{independent:.1f} % on channels (grouped 5-fold by recording, every window, no balancing: a
different protocol, so a guide, not a twin); `features` on channels lies {gap:+.1f} points from it.
Detectors that could not run here: {absent}.

{accuracy}

## Every protocol, both inputs

`features` with each protocol's default options; DoS with `windows=["500ms"]` where a protocol
takes it and the grouped split, the simulation with the paper's split. A skipped cell is a
protocol that the data cannot serve (the reason is the engine's); {failed} failed.

The simulation (scale {scale:g}):

{simulation}

DoS:

{dos_protocols}

## Cost

Best of {repeats} fits and of at least 3 scorings on {windows:,} toy windows of {window}
samples (the LSTM fitted once, on {lstm_windows:,}, at its defaults with early stopping), one
thread, the detectors one after another on a shared machine: read ratios, not absolute times.
Training: microseconds per window sample (`train_us_per_sample`); scoring: per window
(`infer_us_per_window`).

{speed}
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dos", type=Path, required=True, help="BioTacSP-DoS's csvs folder")
    parser.add_argument("--out", type=Path, default=Path("docs/studies/baseline.md"))
    parser.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) / "bench_baseline")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--scale", type=float, default=0.05)
    parser.add_argument("--windows", type=int, default=20_000)
    parser.add_argument("--window", type=int, default=50)
    parser.add_argument("--lstm-windows", type=int, default=2_000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    load = ", ".join(f"{v:.1f}" for v in os.getloadavg())
    if not (args.work / "dos").is_dir():
        biotacsp_dos(args.dos, args.work / "dos")
    dos, sim = read_dataset(args.work / "dos"), default_dataset(args.scale, 0, echo=print)
    accuracy = accuracy_table(dos_accuracy(dos, args.work, args.seeds))
    mine = accuracy[(accuracy.detector == reference_name()) & (accuracy.input == "channels")]
    simulation = every_protocol(sim, args.work / f"sim-{args.scale:g}")
    options = {"windows": [WINDOW], "split": "grouped"}
    on_dos = every_protocol(dos, args.work / "dos-protocols", **options)
    page = PAGE.format(
        provenance=provenance(args, dos, sim, load),
        last=args.seeds - 1,
        independent=100 * INDEPENDENT_CHANNELS,
        gap=float(mine["mean"].iloc[0]) - 100 * INDEPENDENT_CHANNELS,
        accuracy=_md(accuracy),
        absent="; ".join(runnable()[1]) or "none",
        scale=args.scale,
        failed=int(simulation["failed"].sum() + on_dos["failed"].sum()) or "none",
        simulation=_md(simulation),
        dos_protocols=_md(on_dos),
        repeats=args.repeats,
        windows=args.windows,
        window=args.window,
        lstm_windows=args.lstm_windows,
        speed=_md(speed(args.windows, args.window, args.lstm_windows, args.repeats)),
    )
    args.out.write_text(page)
    print(page)


if __name__ == "__main__":
    main()
