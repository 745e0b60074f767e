"""The across-datasets report on real data (issue 36): a few fast detectors on the simulation
and on the BioTac SP DoS recordings at one shared protocol setting, then ``slipbench report A B``
of the two results folders. Writes the report's "Leaderboard" (with "vs baseline") and
"Across datasets" sections to ``docs/studies/across-datasets/summary.txt`` and the forest plot to
``docs/studies/across-datasets/forest.png``; ``docs/studies/across-datasets.md`` embeds both.

    nice python benchmarks/bench_across_datasets.py --dos PATH/biotacsp-dos/csvs

Setting: protocol window-size with ``windows=["500ms"]`` (500 samples at the simulation's
1000 Hz, 425 at its BioTac SP's 850 Hz, 50 at DoS's 100 Hz), ``--split grouped``, univariate
input, seeds 0 to ``--seeds`` - 1, detectors ``--detectors``. The simulation: the default
dataset at ``--scale``, seed 0. DoS: ``slipbench dataset import biotacsp-dos`` of ``--dos``
into ``--work`` (read in place, never copied into the repository). Each dataset's results go
to a folder of ``--work`` named by slipbench's code identity: a rerun of the same code resumes
there, a changed one starts afresh.
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

import slipbench
from slipbench.data.defaults import default_dataset
from slipbench.data.format import Dataset
from slipbench.data.importers.biotacsp import biotacsp_dos
from slipbench.data.read import read_dataset
from slipbench.engine.plan import Run
from slipbench.engine.registry import protocols
from slipbench.engine.runner import evaluate
from slipbench.store.keys import code_identity
from slipbench.store.results import ResultsStore

ROOT = Path(__file__).resolve().parents[1]
# where the shared recordings sit beside the checkouts (as tests/data/test_cards.py finds them)
DOS = ROOT.parent / "shared" / "datasets" / "biotacsp-dos" / "csvs"
DETECTORS = ("features", "holweg", "bandpass", "wavelet-svm")
WINDOW = "500ms"
SECTIONS = ("Leaderboard", "Across datasets")  # the report's sections the page shows


def runs_of(detectors: list[str], seeds: int) -> list[Run]:
    """Window-size at ``WINDOW``, grouped split: one run per detector and seed."""
    out = []
    for name in detectors:
        for seed in range(seeds):
            protocol = protocols.get("window-size")(windows=[WINDOW])
            out.append(Run(name, protocol, split="grouped", seed=seed))
    return out


def run_both(datasets: dict[str, Dataset], work: Path, runs: list[Run]) -> dict[str, Path]:
    """Each dataset's cells into its own results folder under ``work``; the folders."""
    folders = {}
    for name, dataset in datasets.items():
        # a folder per code version: cells of two versions in one folder would pair twice
        folders[name] = work / f"{name}-{code_identity(slipbench)[:12]}"
        rows = evaluate(dataset, runs, ResultsStore(folders[name]), jobs=1, progress=True)
        bad = rows[rows["status"] != "ok"]
        for r in bad.to_dict("records"):  # said, never hidden: the report counts them too
            print(f"{name}: {r['detector']} seed {r['seed']}: {r['status']}: {r['reason']}")
    return folders


def report(folders: dict[str, Path], work: Path) -> tuple[str, Path]:
    """``slipbench report`` of the folders (Markdown, figures): its text and figure folder."""
    out, figures = work / "report.md", work / "figures"
    shutil.rmtree(figures, ignore_errors=True)
    command = [sys.executable, "-m", "slipbench", "report", *map(str, folders.values())]
    subprocess.run([*command, "--out", str(out), "--plots", str(figures)], check=True)
    return out.read_text(), figures


def sections(text: str, titles: tuple[str, ...]) -> str:
    """The report's level-2 sections named ``titles``, one level down, without their figures
    (image and caption: the page shows the forest plot itself)."""
    parts = re.split(r"(?m)^(?=## )", text)
    kept = "".join(p for p in parts if p.startswith(tuple(f"## {t}\n" for t in titles)))
    captions = {f"_{c}_" for c in re.findall(r"(?m)^!\[(.*)\]\(", kept)}
    lines = [x for x in kept.splitlines() if not x.startswith("![") and x not in captions]
    text = re.sub(r"(?m)^## ", "### ", "\n".join(lines))
    return re.sub(r"\n{3,}", "\n\n", text).strip() + "\n"


def provenance(args: argparse.Namespace, datasets: dict[str, Dataset], load: str) -> str:
    commit = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=False
    ).stdout.strip()
    prints = ", ".join(
        f"{Path(str(d.path)).name} ({n}) {d.fingerprint}" for n, d in datasets.items()
    )
    return (
        f"Written by `benchmarks/bench_across_datasets.py` (its docstring gives every setting); "
        f"do not edit by hand. slipbench {slipbench.__version__} (commit {commit or 'unknown'}), "
        f"Python {platform.python_version()}; {os.cpu_count()} cores, load average {load} at "
        f"the start; {datetime.now(timezone.utc):%Y-%m-%d}. Window-size at {WINDOW}, grouped "
        f"split, univariate input, seeds 0-{args.seeds - 1}; detectors "
        f"{', '.join(args.detectors)}; the simulation at scale {args.scale:g}, seed 0. "
        f"Datasets (fingerprints): {prints}."
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dos", type=Path, default=DOS, help="BioTacSP-DoS's csvs folder")
    parser.add_argument("--docs", type=Path, default=ROOT / "docs" / "studies" / "across-datasets")
    parser.add_argument(
        "--work", type=Path, default=Path(tempfile.gettempdir()) / "bench_across_datasets"
    )
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--scale", type=float, default=0.05)
    parser.add_argument("--detectors", type=lambda s: s.split(","), default=list(DETECTORS))
    args = parser.parse_args()
    load = ", ".join(f"{v:.1f}" for v in os.getloadavg())
    start = time.perf_counter()
    if not (args.work / "biotacsp-dos").is_dir():
        biotacsp_dos(args.dos, args.work / "biotacsp-dos")
    datasets = {
        "simulation": default_dataset(args.scale, 0, echo=print),
        "dos": read_dataset(args.work / "biotacsp-dos"),
    }
    folders = run_both(datasets, args.work, runs_of(args.detectors, args.seeds))
    text, figures = report(folders, args.work)
    if not (figures / "meta.png").is_file():  # fewer than two datasets share a pair
        raise SystemExit(f"the report drew no forest plot; {args.work / 'report.md'} says why")
    args.docs.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(figures / "meta.png", args.docs / "forest.png")
    summary = f"{provenance(args, datasets, load)}\n\n{sections(text, SECTIONS)}"
    (args.docs / "summary.txt").write_text(summary)
    print(summary)
    print(f"took {time.perf_counter() - start:.0f} s (wall, shared machine)")


if __name__ == "__main__":
    main()
