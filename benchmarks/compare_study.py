"""What the compare studies share: a reseedable detector plugin, and evaluate runs of it.

``HalfEnergy`` fits a mean-absolute-signal threshold on a random half of its training windows
(the half drawn from the fit's seed): two seeds give two detectors that are equally good in
expectation but differ cell by cell, as retrained models do. ``HalfEnergySalted`` draws its half
from another stream of the same seed: under the same seeds (so the same splits) it is an equally
good rewrite of ``HalfEnergy``, as a refactored detector compared with main is.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

PLUGIN = textwrap.dedent(
    '''
    import numpy as np

    from slipbench.base import BaseDetector


    class HalfEnergy(BaseDetector):
        """Energy threshold fitted on a random half of the training windows."""

        def _fit(self, x, y, seed):
            pick = np.random.default_rng(seed).random(len(x)) < 0.5
            e, yy = np.abs(x[pick]).mean(axis=1), y[pick].astype(bool)
            cuts = np.quantile(e, np.linspace(0.02, 0.98, 49))
            ba = [((e[yy] > c).mean() + (e[~yy] <= c).mean()) / 2 for c in cuts]
            self.cut_ = float(cuts[int(np.argmax(ba))])
            self.scale_ = float(e.std()) or 1.0

        def _predict_proba(self, x):
            return 1 / (1 + np.exp(-10 * (np.abs(x).mean(axis=1) - self.cut_) / self.scale_))
    '''
)
SALTED = textwrap.dedent(  # a plugin file of its own: one detector per file, named by it
    '''
    from half_energy import HalfEnergy


    class HalfEnergySalted(HalfEnergy):
        """HalfEnergy with its half drawn from another stream of the same seed."""

        def _fit(self, x, y, seed):
            return super()._fit(x, y, [seed, 1])
    '''
)


def setup(root: Path, scale: float = 0.02) -> tuple[Path, Path]:
    """The simulated dataset at ``scale`` and a plugin folder holding HalfEnergy and its salted
    twin."""
    from slipbench.data.synth import synthesize

    data = root / "data"
    if not data.exists():
        synthesize(data, scale=scale, seed=1)
    plugins = root / "plugins" / "detectors"
    plugins.mkdir(parents=True, exist_ok=True)
    (plugins / "half_energy.py").write_text(PLUGIN)
    (plugins / "half_energy_salted.py").write_text(SALTED)
    return data, root / "plugins"


def evaluate(
    data: Path,
    plugins: Path,
    out: Path,
    seed: int,
    repeats: int,
    *extra: str,
    detector: str = "half-energy",
) -> None:
    """``slipbench evaluate`` of ``detector`` (a plugin of this module) on window-size, grouped
    split."""
    subprocess.run(
        [
            sys.executable, "-m", "slipbench", "evaluate", "--detector", detector,
            "--protocol", "window-size", "--split", "grouped", "--dataset", str(data),
            "--plugins", str(plugins), "--seed", str(seed), "--repeats", str(repeats),
            "--out", str(out), "--quiet", *extra,
        ],
        check=True,
        stdout=subprocess.DEVNULL,
    )  # fmt: skip


def side(pool: Path, out: Path, seeds: list[int], rename: str = "") -> Path:
    """A results folder holding the pool's rows of ``seeds`` (its predictions linked, not
    copied); ``rename`` prefixes the keys (and links the predictions under the new names)."""
    import pandas as pd

    rows = pd.read_parquet(pool / "results.parquet")
    rows = rows[rows["seed"].isin(seeds)].copy()
    (out / "predictions").mkdir(parents=True)
    for key in rows["key"]:
        (out / "predictions" / f"{rename}{key}.parquet").symlink_to(
            (pool / "predictions" / f"{key}.parquet").resolve()
        )
    rows["key"] = rename + rows["key"]
    rows.to_parquet(out / "results.parquet")
    return out


def compare_exit(base: Path, cand: Path, seed: int = 0) -> tuple[int, str]:
    """compare's exit code and verdict line."""
    from slipbench.gate.compare import compare
    from slipbench.report.compare import _verdict_line

    cmp = compare(base, cand, seed=seed)
    return cmp.exit_code, _verdict_line(cmp).split("\n")[0]
