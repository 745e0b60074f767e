"""How far a true calibration's seed variance lies from what three seeds of a base show: the
null spread behind ``slipbench.gate.calibration_check.SEED_FACTOR``.

Runs the shipped bench (``bench.toml``) at disjoint triples of seeds (0-2, 3-5, ...), each as
a base of the workflow runs it (``slipbench run bench.toml --seed S --out WORK/sS``; a folder
that holds results is read as it is), and prints, per detector, the ratio the check reads (the base's
pooled seed variance over the committed calibration's, per figure, and their geometric mean)
and whether it refuses it; then the same for the calibration scaled by 25 and by 0.

    nice python benchmarks/calibration_check_null.py --work DIR [--triples 6]
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _scaled(cal, k: float):
    """``cal`` with every seed variance (cells and means) times ``k``."""

    def noise(n):
        return replace(n, seed_var=k * n.seed_var, paired_var=k * n.paired_var)

    return replace(
        cal,
        detectors={
            name: replace(
                det,
                protocols={
                    p: replace(
                        part,
                        figures={f: noise(n) for f, n in part.figures.items()},
                        cells={
                            c: {f: noise(n) for f, n in fs.items()} for c, fs in part.cells.items()
                        },
                    )
                    for p, part in det.protocols.items()
                },
            )
            for name, det in cal.detectors.items()
        },
    )


def _ratios(det, name: str, rows, figures) -> list[float]:
    ok = rows[(rows["detector"] == name) & (rows["status"] == "ok")]
    out = []
    for protocol, part in det.protocols.items():
        mine = ok[ok["protocol"] == protocol]
        for f in figures:
            num = den = 0.0
            for cell, g in mine.groupby("cell"):
                x = g[f].astype(float).to_numpy()
                if len(x) < 2 or not np.isfinite(x).all() or str(cell) not in part.cells:
                    continue
                num += (len(x) - 1) * x.var(ddof=1)
                den += (len(x) - 1) * part.cells[str(cell)][f].seed_var
            out.append(num / den if den else math.inf)
    return out


def main() -> None:
    from slipbench.app.benchfile import load_benchmark
    from slipbench.gate.calibration import calibration_path, read_calibration
    from slipbench.gate.calibration_check import SEED_FACTOR, refused
    from slipbench.stats.factors import latest_runs
    from slipbench.store.results import read_results

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", type=Path, required=True)
    ap.add_argument("--triples", type=int, default=6)
    ap.add_argument("--bench", type=Path, default=ROOT / "bench.toml")
    args = ap.parse_args()
    bench = load_benchmark(args.bench)
    figures = list(bench.gate)
    cal = read_calibration(calibration_path(args.bench))
    print(
        f"bench {args.bench.name}, calibration seeds {cal.seeds[0]}-{cal.seeds[-1]}; factor {SEED_FACTOR:g}"
    )
    print(
        "seeds   detector  ratio per figure (" + ", ".join(figures) + ")  geometric mean  refused"
    )
    means: list[float] = []
    rows_of = {}
    for t in range(args.triples):
        seed = bench.seed + t * bench.repeats
        out = args.work / f"s{seed}"
        if not (out / "results.parquet").is_file():  # a finished folder is read as it is
            subprocess.run(
                [sys.executable, "-m", "slipbench", "run", str(args.bench), "--seed", str(seed),
                 "--out", str(out), "--quiet"],
                check=True, capture_output=True,
            )  # fmt: skip
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rows = rows_of[seed] = latest_runs(read_results(out))[0]
        bad = refused(cal, rows, figures)
        for name, det in cal.detectors.items():
            r = _ratios(det, name, rows, figures)
            g = float(np.exp(np.mean(np.log(r))))
            means.append(g)
            print(
                f"{f'{seed}-{seed + bench.repeats - 1}':<7} {name:<9} "
                + ", ".join(f"{x:.2f}" for x in r)
                + f"  {g:.2f}  {'yes' if name in bad else 'no'}"
            )
    print(f"null: geometric means {min(means):.2f} to {max(means):.2f} over {len(means)}")
    for k in (25.0, 0.0):
        scaled = _scaled(cal, k)
        hits = sum(len(refused(scaled, rows, figures)) for rows in rows_of.values())
        print(f"calibration x{k:g}: refused for {hits} of {len(means)} detector-triples")


if __name__ == "__main__":
    main()
