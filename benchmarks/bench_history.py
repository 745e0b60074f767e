"""A long history: loading it and finding its steps, its site's size, its pages in Chromium.

A history of ``--runs`` runs (one per commit, each its own code identity: the worst case) of
``--cells`` cells (two detectors, half the cells each), every figure drawn about its cell's
value with 1 point of noise, and a 3-point drop of one detector's cells at a few commits. Timed,
each in a fresh process (CPU seconds, its children's included, wall seconds and peak RSS):
``read_history`` of the steps' columns, then ``find_steps`` with ``--jobs`` processes; then the
site is written, its size counted and, where selenium and Chromium are here, its pages opened
headless and their console read.

``--before TREE`` times the same in a copy of the code before a change (``git archive <commit>
slipbench | tar -x -C TREE``), in the same run, and says whether both found the same steps and points
(exactly) and the ratios before / after. ``--history DIR`` reads (and keeps) a history built
by an earlier run instead of building one (building 10,000 runs takes most of an hour on a
loaded machine). ``--in-memory`` builds the history's rows in memory, as ``read_history``
would give them, and times ``find_steps`` alone (no files, no load, no site); ``--no-site``
times the load and the steps and writes no site.

    python benchmarks/bench_history.py [--runs 10000] [--cells 300] [--jobs 2] [--before TREE]
        [--history DIR] [--in-memory] [--no-site] [--out FILE]
"""

from __future__ import annotations

import argparse
import inspect
import json
import os
import pickle
import resource
import shutil
import subprocess
import sys
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
from slipbench.store.history import RUN_COLUMNS, Run, add_run, read_history, run_path, run_table

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


def memory_frame(runs: int, cells: int) -> pd.DataFrame:
    """The rows ``read_history(..., STEP_COLUMNS)`` gives of the history :func:`build` writes,
    made in memory (the same values; strings as pandas reads Arrow's)."""
    base = rng_for(0, "bench-history").uniform(0.7, 0.9, cells)
    parts = []
    for i in range(runs):
        rows = run_rows(i, cells, base, rng_for(i, "bench-history"), runs)
        date = (START + timedelta(hours=i)).strftime("%Y-%m-%dT%H:%M:%SZ")
        rows = rows.assign(commit=f"c{i:05d}", date=date, machine="bench", bench_digest=None)
        parts.append(rows[[c for c in dict.fromkeys([*RUN_COLUMNS, *STEP_COLUMNS]) if c in rows]])
    frame = pd.concat(parts, ignore_index=True)
    frame["run"] = np.repeat(np.arange(runs), cells)
    return frame


def measure(history: str, runs: int, cells: int, jobs: int, out: Path) -> None:
    """In this process (the tree on PYTHONPATH): load and find steps, timed; the steps and
    points pickled to ``out``, the times to ``out`` + ``.json``."""
    clock = time.process_time
    frame = memory_frame(runs, cells) if history == "memory" else None
    start, wall = clock(), time.perf_counter()
    if frame is None:
        frame = read_history(history, STEP_COLUMNS, **_coded(read_history))
    loaded, loaded_wall = clock() - start, time.perf_counter() - wall
    rss_loaded = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    start, wall = clock(), time.perf_counter()
    found = find_steps(frame, Gate.of(FIGURES), jobs=jobs)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    stepped = clock() - start + children.ru_utime + children.ru_stime
    stepped_wall = time.perf_counter() - wall
    confirmed = found.confirmed
    with out.open("wb") as f:
        pickle.dump((found.steps, found.points), f)
    times = {
        "load_cpu": loaded,
        "load_wall": loaded_wall,
        "steps_cpu": stepped,
        "steps_wall": stepped_wall,
        "rss_loaded_mb": rss_loaded,
        "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "series": found.series,
        "proposed": len(found.steps),
        "confirmed": len(confirmed),
        "pooled_at": sorted(set(confirmed.loc[confirmed["kind"] == "pooled", "commit"])),
    }
    out.with_suffix(".json").write_text(json.dumps(times))


def _coded(read: object) -> dict:
    """``categorical=True`` where this tree's ``read_history`` takes it (as `history steps`
    reads), nothing where an older tree's does not."""
    return {"categorical": True} if "categorical" in inspect.signature(read).parameters else {}


def _plain(frame: pd.DataFrame) -> pd.DataFrame:
    """Categorical columns as text: the values compared, not how they are held."""
    cats = [c for c in frame if isinstance(frame[c].dtype, pd.CategoricalDtype)]
    return frame.astype({c: "str" for c in cats}) if cats else frame


def timed(tree: Path, history: str, a: argparse.Namespace, out: Path) -> dict:
    """:func:`measure` in a fresh process that imports slipbench from ``tree``."""
    env = {**os.environ, "PYTHONPATH": str(tree)}
    args = [sys.executable, __file__, "--measure", history, str(out)]
    args += ["--runs", str(a.runs), "--cells", str(a.cells), "--jobs", str(a.jobs)]
    subprocess.run(args, env=env, check=True, cwd=tree)
    return json.loads(out.with_suffix(".json").read_text())


def same(before: Path, after: Path) -> str:
    """Whether two measurements found the same steps and points, exactly."""
    with before.open("rb") as f, after.open("rb") as g:
        (s0, p0), (s1, p1) = pickle.load(f), pickle.load(g)
    try:
        pd.testing.assert_frame_equal(_plain(s0), _plain(s1), check_exact=True)
        pd.testing.assert_frame_equal(_plain(p0), _plain(p1), check_exact=True)
    except AssertionError as e:
        return f"NOT identical: {str(e).splitlines()[0]}"
    return f"identical ({len(s1)} steps, {len(p1)} points, every value equal)"


def site(root: Path, history: Path) -> str:
    """The site of the history's latest run and its steps: size, time, its pages opened."""
    frame = read_history(history, STEP_COLUMNS)
    found = find_steps(frame, Gate.of(FIGURES), jobs=1)
    latest = frame[frame["run"] == frame["run"].max()]
    start = time.perf_counter()
    write_site(root / "site", latest, found)
    paged = time.perf_counter() - start
    size = sum(p.stat().st_size for p in (root / "site").rglob("*") if p.is_file())
    return (
        f"- site: {size / 1e6:.2f} MB, written in {paged:.1f} s;\n"
        f"- in headless Chromium: {browse(root / 'site')};\n"
    )


def line(name: str, t: dict) -> str:
    return (
        f"- {name}: load {t['load_cpu']:.1f} s CPU ({t['load_wall']:.1f} s wall), find and "
        f"confirm steps {t['steps_cpu']:.1f} s CPU ({t['steps_wall']:.1f} s wall); together "
        f"{t['load_cpu'] + t['steps_cpu']:.1f} s CPU; peak RSS {t['peak_mb']:.0f} MB "
        f"({t['rss_loaded_mb']:.0f} MB once loaded)\n"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10_000)
    parser.add_argument("--cells", type=int, default=300)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--before", type=Path, help="a checkout of the code before a change")
    parser.add_argument("--history", type=Path, help="a history an earlier run built (kept)")
    parser.add_argument("--in-memory", action="store_true", help="rows in memory, steps only")
    parser.add_argument("--no-site", action="store_true", help="load and steps only, no site")
    parser.add_argument("--measure", nargs=2, help=argparse.SUPPRESS)
    parser.add_argument("--out", type=Path)
    a = parser.parse_args()
    if a.measure:
        measure(a.measure[0], a.runs, a.cells, a.jobs, Path(a.measure[1]))
        return
    root = Path(tempfile.mkdtemp(prefix="bench-history-"))
    try:
        built = 0.0
        history = a.history or root / "history"
        if a.in_memory:
            source = "memory"
        else:
            source = str(history.resolve())
            if a.history is None:
                start = time.perf_counter()
                build(history, a.runs, a.cells)
                built = time.perf_counter() - start
        here = Path(__file__).resolve().parents[1]
        after = timed(here, source, a, root / "after.pkl")
        text = f"# A history of {a.runs} runs x {a.cells} cells\n\n"
        text += (
            f"{after['series']} series, {after['proposed']} steps proposed, "
            f"{after['confirmed']} confirmed (pooled steps at {', '.join(after['pooled_at'])}); "
            f"--jobs {a.jobs}{'; rows made in memory: no load timed' if a.in_memory else ''}.\n\n"
        )
        if a.before:
            before = timed(a.before.resolve(), source, a, root / "before.pkl")
            text += line("before (--before)", before)
        text += line("this checkout", after)
        if a.before:
            ratio = {
                k: before[k] / max(after[k], 1e-9) for k in ("load_cpu", "steps_cpu", "peak_mb")
            }
            load = "" if a.in_memory else f"load {ratio['load_cpu']:.2f}x, "
            text += (
                f"- before / after: {load}steps {ratio['steps_cpu']:.2f}x "
                f"CPU, peak RSS {ratio['peak_mb']:.2f}x; results "
                f"{same(root / 'before.pkl', root / 'after.pkl')}\n"
            )
        if not (a.in_memory or a.no_site):
            text += site(root, history)
        if built:
            text += f"- building the history (not timed against anything): {built:.0f} s.\n"
        text += f"\n{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at the end.\n"
        print(text)
        if a.out:
            a.out.write_text(text)
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
