"""Null and power study of the gate (issue 35): whole-protocol comparisons, each side retrained
under its own seeds, damage done in a wrapper plugin's ``predict``.

Detectors (plugins of benchmarks/compare_study.py, window-size protocol, grouped split,
simulated data at ``--scale``): ``HalfEnergy`` (BASE, and the null CANDIDATE under other seeds);
``HalfEnergyDrop`` (a random ``DROP`` share of its windows' scores inverted: a uniform accuracy
drop of about 2 points); ``HalfEnergyShift`` (its logit raised by ``SHIFT``: more false alarms at
about equal accuracy). Each detector runs once over a pool of seeds (BASE 0.., CANDIDATE 1000..:
drawn apart); comparison k takes seeds k*R .. k*R + R - 1 of each pool. Designs: one seed per side
and ``--repeats`` seeds per side. Printed: the share of exit codes 0, 1 and 6 per design, and the
mean pooled changes of accuracy and TN rate (what the damage did).

    nice python benchmarks/bench_compare_gate.py [--comparisons 3] [--repeats 3] [--work DIR] > docs/gate-study.txt
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import textwrap
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import compare_study as cs  # noqa: E402

DROP = 0.07  # windows inverted: accuracy a -> a - DROP (2a - 1), about 2 points at a = 0.65
SHIFT = 1.5  # logit units added to every score
WRAPPERS = {
    "half_energy_drop.py": f'''
        import numpy as np
        from half_energy import HalfEnergy


        class HalfEnergyDrop(HalfEnergy):
            """HalfEnergy with a random {DROP:g} of its windows' scores inverted."""

            def _predict_proba(self, x):
                p = super()._predict_proba(x)
                rng = np.random.default_rng([len(x), int(abs(self.cut_) * 1e9) % 2**32])
                return np.where(rng.random(len(x)) < {DROP}, 1 - p, p)
        ''',
    "half_energy_shift.py": f'''
        import numpy as np
        from half_energy import HalfEnergy


        class HalfEnergyShift(HalfEnergy):
            """HalfEnergy with its logit raised by {SHIFT:g}: more windows called slip."""

            def _predict_proba(self, x):
                p = np.clip(super()._predict_proba(x), 1e-9, 1 - 1e-9)
                return 1 / (1 + np.exp(-(np.log(p / (1 - p)) + {SHIFT})))
        ''',
}


def pools(root: Path, scale: float, seeds: int) -> dict[str, Path]:
    data, plugins = cs.setup(root, scale)
    for name, text in WRAPPERS.items():
        (plugins / "detectors" / name).write_text(textwrap.dedent(text))
    out = {}
    for label, detector, first in (
        ("base", "half-energy", 0),
        ("null", "half-energy", 1000),
        ("drop", "half-energy-drop", 1000),
        ("shift", "half-energy-shift", 1000),
    ):
        out[label] = root / f"pool-{label}-{seeds}"
        if not (out[label] / "results.parquet").exists():
            cs.evaluate(data, plugins, out[label], first, seeds, detector=detector)
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--comparisons", type=int, default=3)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--scale", type=float, default=0.02)
    ap.add_argument("--work", type=Path, default=None, help="keep the pools here (reused)")
    args = ap.parse_args()
    from slipbench.stats.compare import compare

    root = args.work or Path(tempfile.mkdtemp(prefix="compare-gate-"))
    root.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    pool = pools(root, args.scale, args.comparisons * args.repeats)
    print(
        f"HalfEnergy on window-size (grouped split, scale {args.scale:g}); "
        f"{args.comparisons} comparisons per design, seeds drawn apart; pools "
        f"{time.perf_counter() - t0:.0f} s"
    )
    for cand in ("null", "drop", "shift"):
        for r in (1, args.repeats):
            codes: Counter[int] = Counter()
            acc, tn = [], []
            for k in range(args.comparisons):
                seeds = list(range(k * args.repeats, k * args.repeats + r))
                work = root / f"{cand}-{r}-{k}"
                if not work.exists():
                    cs.side(pool["base"], work / "base", seeds)
                    cs.side(pool[cand], work / "cand", [1000 + s for s in seeds])
                cmp = compare(work / "base", work / "cand", seed=k)
                codes[cmp.exit_code] += 1
                by = cmp.pooled.set_index("figure")["change"] if len(cmp.pooled) else {}
                acc.append(by.get("accuracy", np.nan))
                tn.append(by.get("tn_rate", np.nan))
            n = args.comparisons
            print(
                f"{cand:>5}, {r} seed(s) per side: exit 0 in {codes[0]}/{n}, exit 1 in {codes[1]}/{n}, "
                f"exit 6 in {codes[6]}/{n}; pooled change accuracy {np.nanmean(acc):+.1f}, "
                f"TN rate {np.nanmean(tn):+.1f} points",
                flush=True,
            )


if __name__ == "__main__":
    main()
