"""A long history: loading it and finding its steps, its site's size, its pages in Chromium.

A history of ``--runs`` runs (one per commit, each its own code identity: the worst case) of
``--cells`` cells (two detectors, half the cells each), every figure drawn about its cell's
value with 1 point of noise, and a 3-point drop of one detector's cells at a few commits. Timed:
``read_history`` of the steps' columns, then ``find_steps`` with ``--jobs`` processes; then the
site is written, its size counted and, where selenium and Chromium are here, its pages opened
headless and their console read.

    python benchmarks/bench_history.py [--runs 10000] [--cells 300] [--jobs 2] [--out FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import tempfile
import time
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np
import pandas as pd

from slipbench.atomic import write_atomic
from slipbench.gate.gate import Gate
from slipbench.history.steps import STEP_COLUMNS, find_steps
from slipbench.report.site import write_site
from slipbench.seeding import rng_for
from slipbench.store.history import Run, add_run, read_history, run_path, run_table

FIGURES = ("accuracy", "tn_rate", "tp_rate")
STEPS_AT = (2500, 6000, 9000)  # runs where the second detector drops 3 points (of 10,000)
START = datetime(2025, 1, 1, tzinfo=timezone.utc)


def run_rows(
    i: int, cells: int, base: np.ndarray, rng: np.random.Generator, n_runs: int
) -> pd.DataFrame:
    detector = np.where(np.arange(cells) < cells // 2, "holweg", "bandpass")
    drop = 0.03 * sum(i >= int(at * n_runs / 10_000) for at in STEPS_AT)
    out = {
        "series": [f"{c:016x}" for c in range(cells)],
        "series_label": [f"window-size · {d} · cell {c}" for c, d in zip(range(cells), detector)],
        "key": [f"{i:08x}{c:04x}" for c in range(cells)],
        "row_digest": "",
        "proven": True,
        "code_identity": f"code-{i}",
        "protocol": "window-size",
        "protocol_params": "{}",
        "detector": detector,
        "detector_id": detector,
        "detector_params": "{}",
        "split": "grouped",
        "labels": "scenario",
        "input": "univariate",
        "normalize": "none",
        "cell": [json.dumps({"cell": c % (cells // 2)}) for c in range(cells)],
        "dataset_fingerprint": "f00d",
        "seed": i,
        "status": "ok",
        "low_n": False,
        "df": 30.0,
        "n_test_trials": 40,
    }
    for f in FIGURES:
        value = base + 0.01 * rng.standard_normal(cells) - drop * (detector == "bandpass")
        out |= {f: value, f"{f}_se": np.full(cells, 0.01), f"{f}_lo": value - 0.02}
        out[f"{f}_hi"] = value + 0.02
    return pd.DataFrame(out)


def build(history: Path, runs: int, cells: int) -> None:
    """Write the run files directly (one add rebuilds the index from all of them at the end)."""
    base = rng_for(0, "bench-history").uniform(0.7, 0.9, cells)
    for i in range(runs):
        date = (START + timedelta(hours=i)).strftime("%Y-%m-%dT%H:%M:%SZ")  # a commit an hour
        run = Run(
            f"c{i:05d}",
            date,
            "bench",
        )
        rows = run_rows(i, cells, base, rng_for(i, "bench-history"), runs)
        if i < runs - 1:
            write_atomic(run_table(rows, run), run_path(history, run))
        else:
            add_run(history, rows, run)


def browse(site: Path) -> str:
    """Each plotted page opened in headless Chromium: its plots and console errors."""
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
        from selenium.webdriver.common.by import By
        from selenium.webdriver.support.ui import WebDriverWait
    except ImportError:
        return "not opened: selenium is not installed"
    if not (shutil.which("chromium") and shutil.which("chromedriver")):
        return "not opened: no chromium and chromedriver here"
    options = webdriver.ChromeOptions()
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"):
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    chrome = webdriver.Chrome(service=Service(shutil.which("chromedriver")), options=options)
    found = []
    try:
        for name in ("index.html", "compare.html", "series.html"):
            start = time.perf_counter()
            chrome.get((site / name).as_uri())
            WebDriverWait(chrome, 120).until(
                lambda d: d.find_element(By.TAG_NAME, "body").get_attribute("data-drawn") == "yes"
            )
            plots = len(chrome.find_elements(By.CSS_SELECTOR, ".js-plotly-plot"))
            errors = [e for e in chrome.get_log("browser") if e["level"] == "SEVERE"]
            found.append(
                f"{name}: {plots} plot(s), {len(errors)} console error(s), drawn in "
                f"{time.perf_counter() - start:.1f} s"
            )
    finally:
        chrome.quit()
    return "; ".join(found)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10_000)
    parser.add_argument("--cells", type=int, default=300)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--out", type=Path)
    a = parser.parse_args()
    root = Path(tempfile.mkdtemp(prefix="bench-history-"))
    try:
        start = time.perf_counter()
        build(root / "history", a.runs, a.cells)
        built = time.perf_counter() - start
        start = time.perf_counter()
        frame = read_history(root / "history", STEP_COLUMNS)
        loaded = time.perf_counter() - start
        start = time.perf_counter()
        found = find_steps(frame, Gate.of(FIGURES), jobs=a.jobs)
        stepped = time.perf_counter() - start
        latest = frame[frame["run"] == frame["run"].max()]
        start = time.perf_counter()
        write_site(root / "site", latest, found)
        paged = time.perf_counter() - start
        size = sum(p.stat().st_size for p in (root / "site").rglob("*") if p.is_file())
        confirmed = found.confirmed
        at = sorted(set(confirmed.loc[confirmed["kind"] == "pooled", "commit"]))
        text = (
            f"# A history of {a.runs} runs x {a.cells} cells\n\n"
            f"- load (index, the steps' columns): {loaded:.1f} s; find and confirm steps "
            f"({found.series} series, {len(found.steps)} proposed, {len(confirmed)} confirmed; "
            f"pooled steps at {', '.join(at)}) at --jobs {a.jobs}: {stepped:.1f} s; "
            f"together {loaded + stepped:.1f} s;\n"
            f"- site: {size / 1e6:.2f} MB, written in {paged:.1f} s;\n"
            f"- in headless Chromium: {browse(root / 'site')};\n"
            f"- building the history (not timed against anything): {built:.0f} s.\n\n"
            f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at the end.\n"
        )
        print(text)
        if a.out:
            a.out.write_text(text)
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
