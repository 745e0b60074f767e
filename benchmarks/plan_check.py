"""The plan's estimate of the paper's reproduction at scale 0.1 (`reports/reproduce.sh`: every
detector, every protocol, both splits, `--jobs 2`) against what that run measured, as
`reports/README.md` commits it ("What the reproduction cost": models and wall minutes per split
and detector). The estimate comes from the rows of a pilot (PILOT: any results folder of the
same detectors and parameters, at any scale), and plans no cell of its own.

    python benchmarks/plan_check.py PILOT

Per split and detector: models planned and counted, estimated and measured wall minutes (the
estimate: the detector's models scheduled longest first on 2 workers, as the script ran each
detector by itself); then the totals over the detectors both hold.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path
from tempfile import TemporaryDirectory

from slipbench.app.benchspec import load_benchmark, with_overrides
from slipbench.app.planning import planning
from slipbench.engine.estimate import makespan

ROOT = Path(__file__).resolve().parents[1]
FILE = """
[dataset]
scale = 0.1
[run]
jobs = 2
[detectors.features]
[detectors.holweg]
[detectors.bandpass]
[detectors.wavelet-svm]
[detectors.minirocket]
[detectors.lstm]
max_epochs = 100
[protocols.window-size]
[protocols.sampling-rate]
decimation = "both"
[protocols.material-holdout]
[protocols.speed-holdout]
[protocols.cross-instance]
[protocols.streaming]
"""
ROW = re.compile(r"^\| (grouped|paper) \| ([\w-]+) \| (\d+) \| ([\d.]+) \| ([\d.]+) \| (\d+) \|$")


def committed() -> dict[tuple[str, str], tuple[int, float]]:
    """(split, detector) -> (models, wall minutes) of the committed reproduction."""
    text = (ROOT / "reports" / "README.md").read_text()
    return {
        (m[1], m[2]): (int(m[3]), float(m[4]))
        for line in text.splitlines()
        if (m := ROW.match(line))
    }


def estimated(pilot: Path) -> dict[tuple[str, str], tuple[int, float | None]]:
    """(split, detector) -> (models, estimated wall minutes on 2 workers; None: unmeasured)."""
    out: dict[tuple[str, str], tuple[int, float | None]] = {}
    with TemporaryDirectory() as tmp:
        path = Path(tmp) / "reproduction.toml"
        path.write_text(FILE)
        for split in ("grouped", "paper"):
            bench = with_overrides(load_benchmark(path), split=split)
            p = planning(bench, [pilot], lambda line: print(line, file=sys.stderr))
            for name, cost in p.costs.items():
                # a detector whose streaming cells the pilot never ran is left out
                wall = makespan(cost.model_s, 2) / 60 if cost.model_s and not cost.unknown else None
                out[split, name] = (cost.models, wall)
    return out


def main(pilot: Path) -> None:
    measured, planned = committed(), estimated(pilot)
    print(
        "| Split | Detector | Models planned | Models run | Wall estimated (min) | Wall measured (min) |"
    )
    print("|:--|:--|--:|--:|--:|--:|")
    both = [k for k in measured if k in planned and planned[k][1] is not None]
    for key in sorted(set(measured) | set(planned)):
        models, wall = planned.get(key, (None, None))
        run_models, run_wall = measured.get(key, (None, None))
        shown = "-" if wall is None else f"{wall:.1f}"
        print(
            f"| {key[0]} | {key[1]} | {models or '-'} | {run_models or '-'} | {shown} | {run_wall or '-'} |"
        )
    est = sum(planned[k][1] or 0.0 for k in both)
    run = sum(measured[k][1] for k in both)
    names = sorted({k[1] for k in both})
    print(
        f"\nOver {', '.join(names)} (both splits): estimated {est:.1f} min, measured {run:.1f} "
        f"min, {100 * (est - run) / run:+.0f} %."
    )


if __name__ == "__main__":
    main(Path(sys.argv[1]))
