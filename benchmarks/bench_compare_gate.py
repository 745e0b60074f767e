"""Null and power study of the gate (issue 35) at the shipped CI bench's settings: bench.toml's
protocols (window-size at windows 50 and 100, cross-instance), scale, grouped split and
tolerances, with a reseedable plugin detector in place of its detectors, each side retrained.

Detectors (plugins of benchmarks/compare_study.py): ``HalfEnergy`` is the base. Candidates:
``HalfEnergySalted`` (the same detector drawing its training half from another stream of each
seed: an equal rewrite, retrained), ``HalfEnergy`` under seeds drawn apart (1000..), and damaged
rewrites, all salted: ``Drop`` (a random ``DROP`` share of windows' scores inverted: a uniform
accuracy drop of about 2 points), ``Shift`` (logit raised by ``SHIFT``: about 7 points more
false alarms), ``Sensor`` (``SENSOR_DROP`` of the windows inverted in cells trained on Nano17:
7 points on one sensor type). Each detector runs once over a pool of seeds; comparison k takes
seeds k*R .. k*R + R - 1. Designs: "same" seeds on both sides (as a branch against main in
CI) or drawn apart; R seeds per side. Printed per design: the share of exit codes 0 (no
regression), 1 (regressed) and 6 (undecided), which figures regressed, and the mean pooled
change of accuracy and TN rate (what the damage did).

    nice python benchmarks/bench_compare_gate.py [--nulls 20] [--nulls-3 20] [--powers 10] [--work DIR] > docs/studies/gate-study.txt
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import compare_study as cs  # noqa: E402

SCALE = 0.05  # bench.toml's [dataset]
PROTOCOLS = ("--protocol", "cross-instance", "--protocol-param", "windows=[50,100]")
DROP = 0.048  # windows inverted: accuracy a -> a - DROP (2a - 1), 2 points at a = 0.71
SENSOR_DROP = 0.167  # the same, 7 points, in cells trained on Nano17 only
SHIFT = 0.35  # logit units added to every score: about 7 points of TN rate
SALTED = "from half_energy_salted import HalfEnergySalted\n\n\n"
WRAPPERS = {
    "half_energy_drop.py": SALTED
    + f'''
class HalfEnergyDrop(HalfEnergySalted):
    """HalfEnergySalted with a random {DROP:g} of its windows' scores inverted."""

    def _predict_proba(self, x):
        p = super()._predict_proba(x)
        rng = np.random.default_rng([len(x), int(abs(self.cut_) * 1e9) % 2**32])
        return np.where(rng.random(len(x)) < {DROP}, 1 - p, p)
''',
    "half_energy_shift.py": SALTED
    + f'''
class HalfEnergyShift(HalfEnergySalted):
    """HalfEnergySalted with its logit raised by {SHIFT:g}: more windows called slip."""

    def _predict_proba(self, x):
        p = np.clip(super()._predict_proba(x), 1e-9, 1 - 1e-9)
        return 1 / (1 + np.exp(-(np.log(p / (1 - p)) + {SHIFT})))
''',
    "half_energy_sensor.py": SALTED
    + f'''
class HalfEnergySensor(HalfEnergySalted):
    """HalfEnergySalted with {SENSOR_DROP:g} of its windows inverted where it trained on Nano17."""

    def _fit(self, x, y, seed, groups=None):
        self.nano_ = groups is not None and str(groups[0]).startswith("Nano17")
        return super()._fit(x, y, seed)

    def _predict_proba(self, x):
        p = super()._predict_proba(x)
        if not self.nano_:
            return p
        rng = np.random.default_rng([len(x), int(abs(self.cut_) * 1e9) % 2**32])
        return np.where(rng.random(len(x)) < {SENSOR_DROP}, 1 - p, p)
''',
}
#: design: (candidate pool, seeds per side, null or power)
DESIGNS = {  # the shipped design (same seeds, 3 a side) first
    "null, same seeds, 3 a side": ("salted", 3, "null"),
    "2-point drop, same seeds, 3 a side": ("drop", 3, "power"),
    "7 points of false alarms, 3 a side": ("shift", 3, "power"),
    "7 points on Nano17 only, 3 a side": ("sensor", 3, "power"),
    "null, seeds apart, 3 a side": ("apart", 3, "null"),
    "null, same seeds, 1 a side": ("salted", 1, "null"),
    "null, seeds apart, 1 a side": ("apart", 1, "null"),
}
POOLS = {  # label: (detector, first seed)
    "base": ("half-energy", 0),
    "salted": ("half-energy-salted", 0),
    "apart": ("half-energy", 1000),
    "drop": ("half-energy-drop", 0),
    "shift": ("half-energy-shift", 0),
    "sensor": ("half-energy-sensor", 0),
}


def pools(root: Path, sizes: dict[str, int]) -> dict[str, Path]:
    data, plugins = cs.setup(root, SCALE)
    for name, text in WRAPPERS.items():
        (plugins / "detectors" / name).write_text("import numpy as np\n" + text)
    out = {}
    for label, n in sizes.items():
        detector, first = POOLS[label]
        out[label] = root / f"pool-{label}-{n}"
        if not (out[label] / "results.parquet").exists():
            _grow_from_smaller(root, label, n)
            t0 = time.perf_counter()
            cs.evaluate(
                data, plugins, out[label], first, n, *PROTOCOLS, "--jobs", "2", detector=detector
            )
            print(f"# pool {label}: {n} seeds in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    return out


def _grow_from_smaller(root: Path, label: str, n: int) -> None:
    """Start a pool of ``n`` seeds from the largest smaller pool of ``label`` in ``root``, its
    files hard-linked (comparisons link into the smaller one): evaluate finds its cells cached
    and runs only the seeds it lacks."""
    smaller = [
        (int(p.name.rsplit("-", 1)[1]), p)
        for p in root.glob(f"pool-{label}-*")
        if (p / "results.parquet").exists() and int(p.name.rsplit("-", 1)[1]) < n
    ]
    if smaller:
        shutil.copytree(max(smaller)[1], root / f"pool-{label}-{n}", copy_function=os.link)


def run_design(root: Path, pool: dict[str, Path], design: str, n: int) -> str:
    from slipbench.gate.compare import compare

    cand, r, _ = DESIGNS[design]
    codes: Counter[int] = Counter()
    flagged: Counter[str] = Counter()
    acc, tn, seconds = [], [], []
    for k in range(n):
        seeds = list(range(k * r, k * r + r))
        work = root / f"{cand}-{r}-{k}"
        if not work.exists():
            cs.side(pool["base"], work / "base", seeds)
            cs.side(pool[cand], work / "cand", [POOLS[cand][1] + s for s in seeds])
        t0 = time.perf_counter()
        cmp = compare(work / "base", work / "cand", seed=k)
        seconds.append(time.perf_counter() - t0)
        codes[cmp.exit_code] += 1
        pooled = cmp.pooled.set_index("figure") if len(cmp.pooled) else None
        if pooled is not None:
            acc.append(pooled["change"].get("accuracy", np.nan))
            tn.append(pooled["change"].get("tn_rate", np.nan))
            flagged.update(pooled.index[pooled["verdict"] == "regressed"])
    seen = ", ".join(f"{f} {c}" for f, c in sorted(flagged.items())) or "none"
    return (
        f"{design}: exit 0 in {codes[0]}/{n}, exit 1 in {codes[1]}/{n}, exit 6 in {codes[6]}/{n}; "
        f"pooled tests flagged: {seen}; mean pooled change accuracy {np.nanmean(acc):+.1f}, "
        f"TN rate {np.nanmean(tn):+.1f} points; compare {np.median(seconds):.0f} s (median)"
    )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--nulls", type=int, default=20, help="comparisons per null design")
    ap.add_argument("--nulls-3", type=int, default=20, help="the same, 3 seeds a side")
    ap.add_argument("--powers", type=int, default=10, help="comparisons per power design")
    ap.add_argument("--work", type=Path, default=None, help="keep the pools here (reused)")
    args = ap.parse_args()
    root = args.work or Path(tempfile.mkdtemp(prefix="compare-gate-"))
    root.mkdir(parents=True, exist_ok=True)
    count = {
        d: args.powers if kind == "power" else args.nulls if r == 1 else args.nulls_3
        for d, (_, r, kind) in DESIGNS.items()
    }
    sizes: dict[str, int] = {"base": 0}
    for design, (cand, r, _) in DESIGNS.items():
        sizes[cand] = max(sizes.get(cand, 0), r * count[design])
        sizes["base"] = max(sizes["base"], r * count[design])
    print(
        f"HalfEnergy at bench.toml's settings (window-size at 50 and 100, cross-instance; grouped "
        f"split; scale {SCALE:g}; tolerance 1 point), each side retrained",
        flush=True,
    )
    for design, (cand, _, _) in DESIGNS.items():  # each design's pools just before it runs
        pool = pools(root, {"base": sizes["base"], cand: sizes[cand]})
        print(run_design(root, pool, design, count[design]), flush=True)


if __name__ == "__main__":
    main()
