"""Results folders of a simulated history: window-size rows (resultgen's 48 cells), each run
with its own seed and code identity, its figures moved by a shift and a seeded noise."""

from __future__ import annotations

import zlib
from pathlib import Path

import numpy as np
import pandas as pd
from resultgen import fake_rows

from slipbench.seeding import rng_for
from slipbench.store.results import ResultsStore


def run_folder(
    folder: Path,
    seed: int,
    shift: float = 0.0,
    noise: float = 0.005,
    code: str = "code-0",
    detector: str = "holweg",
    cells: bool = False,
    **extra,
) -> Path:
    """One run's results folder: every figure of every cell ``shift`` (a fraction) away from
    resultgen's value of the cell (the same under every seed), plus seeded noise of standard deviation ``noise``, its standard error
    ``noise`` on 30 degrees of freedom; ``extra`` columns set on every row. With ``cells``, a
    results folder as ``evaluate`` writes it (each cell stored, then consolidated: its rows
    verified when read); else the folder's results.parquet alone, written directly (fast)."""
    # holweg's rows under the detector's name (a name no plugin holds: the site's hostile one)
    rows = fake_rows("window-size", "holweg").assign(seed=seed, detector=detector)
    rng = rng_for(seed, "historygen", code)
    kept = []
    for r in rows.to_dict("records"):
        salt = f"{r['key']}|{detector}|{code}|{extra}".encode()
        r["key"] = f"{zlib.crc32(salt):08x}{seed:04d}"
        for name in ("accuracy", "tp_rate", "tn_rate"):
            value = r[name] + shift + noise * rng.standard_normal()
            r |= {name: value, f"{name}_se": noise, f"{name}_lo": value - 2 * noise}
            r[f"{name}_hi"] = value + 2 * noise
        r |= {"df": 30.0, "code_identity": code, "detector_params": "{}", **extra}
        kept.append({k: v for k, v in r.items() if not (isinstance(v, float) and np.isnan(v))})
    if not cells:
        folder.mkdir(parents=True, exist_ok=True)
        pd.DataFrame(kept).to_parquet(folder / "results.parquet")
        return folder
    store = ResultsStore(folder)
    for r in kept:
        store.put(r)
    store.consolidate()
    return folder
