"""A bench's calibration: the seed noise of every figure the gate reads, measured once on many
seeds, so that a comparison of three seeds a side is not left to the two degrees of freedom its
own seeds carry.

Two runs of the bench's detectors make it, at seeds ``s_1 .. s_N``: the run itself, and its
**twin**, every model trained again from another draw of the detector's seed on the same split
(:meth:`slipbench.engine.plan.Run.retrained`). Per figure of every cell, and of every protocol's
mean over its cells (what the gate's pooled test reads), they give:

- ``seed_var``: the variance of one seed's figure across seeds (ddof 1, ``seeds - 1`` degrees of
  freedom): what two sides run under different seeds differ by (twice it, per seed);
- ``paired_var``: the variance of one seed's difference between the twin and the run, whose mean
  is zero by construction (``sum(d**2) / seeds``, ``seeds`` degrees of freedom): what two sides
  run under the same seeds differ by when nothing but training randomness separates them (a
  retrained rewrite); 0 for a detector that draws nothing in ``fit``, whose twin is the run;
- ``trial_var``: the mean over seeds of the figure's squared standard error over test trials
  (its row's bootstrap): the test-set share of that noise.

Variances are in the units the results store (rates as fractions). The file format, its key
and when it is stale: ``docs/explanation/gate.md`` (section "The calibration").
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from slipbench.errors import DataError
from slipbench.stats.noise import SeedNoise
from slipbench.store.columns import CELL_ROLE, ENTRANT, SEED, identity
from slipbench.store.keys import canonical

#: the source a calibration's noise names beside a verdict
CALIBRATION = "the bench's calibration"
FORMAT = "slipbench-calibration"
VERSION = 1
#: the calibration of ``bench.toml`` is ``bench.calibration.json``, beside it
SUFFIX = ".calibration.json"
#: the draw of the detector's seed stream the twin trains from
TWIN_DRAW = 1
#: where two cells of a twin and its run differ by less than this, in every figure, the
#: detector drew nothing in fit (floating-point noise of a BLAS aside)
SAME = 1e-12
#: what pairs a twin's row with its run's: the same entrant's cell and seed (a bench's
#: settings are one per bench)
TWINNED = list(identity(SEED, ENTRANT, CELL_ROLE, named=True))


def calibration_path(bench: Path) -> Path:
    """The calibration file of a bench file: ``<stem>.calibration.json`` beside it."""
    return bench.with_name(bench.stem + SUFFIX)


@dataclass(frozen=True)
class Noise:
    """The seed noise of one figure, of a cell or of a protocol's mean over ``cells`` cells."""

    seeds: int
    cells: int
    mean: float
    seed_var: float
    seed_df: float
    paired_var: float
    paired_df: float
    trial_var: float

    def per_seed(self, paired: bool, drop: float | None = None) -> float:
        """The variance of one seed's change between two sides, as a plan reads it: under
        different seeds twice one side's (its splits' test sets inside it); under the same
        seeds (``paired``) the twin's plus the test trials' share of a change of ``drop``
        (:meth:`test_noise`), so that a detector whose twin is its run (``paired_var`` 0)
        still carries the noise its test trials leave."""
        if not paired:
            return 2 * self.seed_var
        return self.paired_var + self.test_noise(drop)

    def test_noise(self, drop: float | None = None) -> float:
        """The test trials' variance of one seed's paired change of ``drop`` (a rate's change,
        stored units): a change of ``drop`` flips at least that share of the windows, whose
        variance over trials is ``drop / (p (1 - p))`` of the figure's own (``trial_var``, ``p``
        its mean), at most all of it; without ``drop`` (not a rate), all of it. 0 where the
        rows held no standard error. A comparison's interval holds this noise in its cluster
        bootstrap already: only a plan, made before any change is seen, adds it."""
        if not math.isfinite(self.trial_var):
            return 0.0
        p = self.mean
        if drop is None or not 0 < p < 1:
            return self.trial_var
        return self.trial_var * min(1.0, abs(drop) / (p * (1 - p)))

    def df(self, paired: bool) -> float:
        return self.paired_df if paired else self.seed_df

    def pool(self, paired: bool) -> SeedNoise:
        """The seed variance a contrast takes (:class:`slipbench.stats.noise.SeedNoise`): one
        seed's paired difference where ``paired``, one side's seed otherwise."""
        return SeedNoise(self.paired_var if paired else self.seed_var, self.df(paired), CALIBRATION)


@dataclass(frozen=True)
class ProtocolNoise:
    """One protocol of one detector: ``figures``, its mean over its cells; ``cells``, each
    cell's (keyed by the rows' ``cell``)."""

    figures: dict[str, Noise]
    cells: dict[str, dict[str, Noise]]


@dataclass(frozen=True)
class DetectorCalibration:
    """One detector: the parameters and own code (:func:`slipbench.store.keys.own_code_identity`)
    it was calibrated with, whether its twin equalled its run in every cell
    (``deterministic``), what one seed of it costs (``seconds_per_seed``: its cells' fit and
    test seconds, from the rows) and its noise per protocol."""

    params: dict[str, Any]
    code: str
    deterministic: bool
    seconds_per_seed: float
    protocols: dict[str, ProtocolNoise]


@dataclass(frozen=True)
class Calibration:
    """A bench's calibration (the file beside it).

    ``settings``: what the noise depends on besides the detectors (dataset, split, labels,
    input, protocols with their options and code, the stream scheme) and ``digest`` its
    SHA-256; ``seeds``: the seeds both runs ran; ``wall_seconds_per_seed``: the whole bench's
    wall time per seed and side on the machine that calibrated (``machine``: processors,
    workers, load); ``side``: the rest of a side's wall seconds, measured there (``start_s``:
    the process's start and planning its runs, ``read_s``: reading the dataset, ``reports_s``:
    writing the reports of ``report_seeds`` seeds' rows; ``simulate_s``, where the simulated
    dataset was not cached: simulating it); empty in a calibration written
    before they were measured, whose cost of a side counts its models only."""

    settings: dict[str, Any]
    digest: str
    seeds: tuple[int, ...]
    dataset_fingerprint: str
    created: str
    slipbench_version: str
    wall_seconds_per_seed: float
    machine: dict[str, Any]
    detectors: dict[str, DetectorCalibration] = field(default_factory=dict)
    side: dict[str, float] = field(default_factory=dict)

    def noise(
        self, detector: str, protocol: str, figure: str, cell: str | None = None
    ) -> Noise | None:
        """The noise of ``figure`` in a protocol's mean (or in ``cell``); None where it was
        not calibrated."""
        found = self.detectors.get(detector)
        part = found.protocols.get(protocol) if found else None
        if part is None:
            return None
        return (part.figures if cell is None else part.cells.get(cell, {})).get(figure)

    def seed_noise(
        self, detector: str, protocol: str, figure: str, cell: str | None, paired: bool
    ) -> SeedNoise | None:
        """What a comparison takes of it (:class:`slipbench.stats.noise.NoiseSource`): the
        :meth:`Noise.pool` of ``figure``, None where it was not calibrated."""
        found = self.noise(detector, protocol, figure, cell)
        return None if found is None else found.pool(paired)

    def holding(self, detectors: Iterable[str]) -> Calibration:
        """This calibration kept to ``detectors`` (those it holds for): the others' noise is
        not answered."""
        kept = set(detectors)
        return replace(self, detectors={k: v for k, v in self.detectors.items() if k in kept})

    def to_json(self) -> str:
        out = {"format": FORMAT, "version": VERSION} | asdict(self)
        out["seeds"] = list(self.seeds)
        return json.dumps(_finite(out), indent=1, sort_keys=False) + "\n"


# ----------------------------------------------------------------------------- measuring
def measure(
    runs: pd.DataFrame, twins: pd.DataFrame, figures: Sequence[str]
) -> dict[str, dict[str, ProtocolNoise]]:
    """Per detector and protocol, the noise of ``figures`` from the rows of the runs and of
    their twins (the same cells and seeds, another training draw).

    Cells count where every seed finished (``ok``) in both; a figure of a cell counts where it
    is finite in every one of them (a cell of one class has no TN rate). A protocol's mean is
    over the cells in which the figure counts, the same cells at every seed.
    """
    both = _ok(runs).merge(_ok(twins), on=TWINNED, suffixes=("", "_twin"), validate="one_to_one")
    seeds = sorted(set(_ok(runs)["seed"]))
    out: dict[str, dict[str, ProtocolNoise]] = {}
    for (detector, protocol), rows in both.groupby(["detector", "protocol"], sort=True):
        complete = rows.groupby("cell")["seed"].transform("nunique") == len(seeds)
        rows = rows[complete]
        if rows.empty:
            continue
        out.setdefault(str(detector), {})[str(protocol)] = _protocol(rows, figures)
    return out


def deterministic(runs: pd.DataFrame, twins: pd.DataFrame, figures: Sequence[str]) -> bool:
    """Every cell of the twin scored as its run in every figure: the detector drew nothing."""
    both = _ok(runs).merge(_ok(twins), on=TWINNED, suffixes=("", "_twin"))
    if both.empty:
        return False
    for f in figures:
        if f not in both:
            continue
        a, b = both[f].to_numpy(float), both[f"{f}_twin"].to_numpy(float)
        if not np.all((np.abs(a - b) <= SAME) | (np.isnan(a) & np.isnan(b))):
            return False
    return True


def _ok(rows: pd.DataFrame) -> pd.DataFrame:
    return rows[rows["status"] == "ok"] if "status" in rows else rows


def _protocol(rows: pd.DataFrame, figures: Sequence[str]) -> ProtocolNoise:
    cells: dict[str, dict[str, Noise]] = {}
    means: dict[str, Noise] = {}
    for f in figures:
        if f not in rows:
            continue
        table = rows.pivot(index="seed", columns="cell", values=f).astype(float)
        twin = rows.pivot(index="seed", columns="cell", values=f"{f}_twin").astype(float)
        se = (
            rows.pivot(index="seed", columns="cell", values=f"{f}_se").astype(float)
            if (f"{f}_se" in rows)
            else pd.DataFrame(np.nan, index=table.index, columns=table.columns)
        )
        kept = [c for c in table if table[c].notna().all() and twin[c].notna().all()]
        for c in kept:
            cells.setdefault(str(c), {})[f] = _noise(table[c], twin[c], se[c])
        if kept:
            means[f] = _noise(
                table[kept].mean(axis=1), twin[kept].mean(axis=1), se[kept].mean(axis=1), len(kept)
            )
    return ProtocolNoise(means, cells)


def _noise(run: pd.Series, twin: pd.Series, se: pd.Series, cells: int = 1) -> Noise:
    """One figure's noise from its values per seed in the run and the twin, and the run's
    standard errors over trials (a protocol's mean: the mean of its cells', as if they moved
    together, the widest case)."""
    x, d = run.to_numpy(float), twin.to_numpy(float) - run.to_numpy(float)
    n = len(x)
    return Noise(
        seeds=n,
        cells=cells,
        mean=float(x.mean()),
        seed_var=float(x.var(ddof=1)) if n > 1 else math.nan,
        seed_df=float(n - 1),
        paired_var=float(np.mean(d**2)),
        paired_df=float(n),
        trial_var=float(np.nanmean(se.to_numpy(float) ** 2)) if se.notna().any() else math.nan,
    )


# ----------------------------------------------------------------------------- the file
def read_calibration(path: Path) -> Calibration:
    """The calibration in ``path``; DataError (exit 2) naming the file and what is wrong."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise DataError(f"{path}: no such calibration file") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DataError(
            f"{path}: not a slipbench calibration (not JSON: {exc}); run `slipbench calibrate` "
            "on its bench file to write it again"
        ) from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise DataError(
            f'{path}: not a slipbench calibration (no "format": "{FORMAT}"); run '
            "`slipbench calibrate` on its bench file to write it again"
        )
    if data.get("version") != VERSION:
        raise DataError(
            f"{path}: calibration format version {data.get('version')!r}, this slipbench reads "
            f"version {VERSION}; run `slipbench calibrate` on its bench file to write it again"
        )
    try:
        return _calibration(data)
    except (KeyError, TypeError, ValueError) as exc:
        raise DataError(
            f"{path}: a calibration with a missing or malformed field ({type(exc).__name__}: "
            f"{exc}); run `slipbench calibrate` on its bench file to write it again"
        ) from None


def _calibration(data: dict) -> Calibration:
    detectors = {
        name: DetectorCalibration(
            params=dict(d["params"]),
            code=str(d["code"]),
            deterministic=bool(d["deterministic"]),
            seconds_per_seed=_number(d["seconds_per_seed"]),
            protocols={
                p: ProtocolNoise(
                    {f: _noise_of(v, f"{name}, {p}, {f}") for f, v in part["figures"].items()},
                    {
                        c: {f: _noise_of(v, f"{name}, {p}, cell {c}, {f}") for f, v in figs.items()}
                        for c, figs in part["cells"].items()
                    },
                )
                for p, part in d["protocols"].items()
            },
        )
        for name, d in data["detectors"].items()
    }
    return Calibration(
        settings=dict(data["settings"]),
        digest=str(data["digest"]),
        seeds=tuple(int(s) for s in data["seeds"]),
        dataset_fingerprint=str(data["dataset_fingerprint"]),
        created=str(data["created"]),
        slipbench_version=str(data["slipbench_version"]),
        wall_seconds_per_seed=_number(data["wall_seconds_per_seed"]),
        machine=dict(data["machine"]),
        detectors=detectors,
        # absent in a calibration written before a side's other costs were measured
        side={str(k): _number(v) for k, v in dict(data.get("side", {})).items()},
    )


def _noise_of(v: Mapping[str, Any], where: str) -> Noise:
    """One figure's noise; a variance or degrees of freedom that is negative or infinite
    (``null``, not measured, stands) is a ValueError naming ``where`` (a SeedNoise would
    refuse it later as an internal error)."""
    noise = Noise(
        seeds=int(v["seeds"]),
        cells=int(v["cells"]),
        **{k: _number(v[k]) for k in ("mean", "seed_var", "seed_df", "paired_var", "paired_df")},
        trial_var=_number(v["trial_var"]),
    )
    for k in ("seed_var", "seed_df", "paired_var", "paired_df", "trial_var"):
        x = getattr(noise, k)
        if not (math.isnan(x) or (x >= 0 and math.isfinite(x))):
            raise ValueError(f"{where}: {k} is {x!r}, not a finite number >= 0")
    return noise


def _number(v: Any) -> float:
    """A float from the file (``null`` stands for NaN, which JSON cannot hold)."""
    if v is None:
        return math.nan
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise TypeError(f"expected a number, got {v!r}")
    return float(v)


def _finite(value: Any) -> Any:
    """``value`` with NaN and infinities as ``null``: strict JSON."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value


def stale_reasons(
    cal: Calibration, digest: str, detectors: Mapping[str, tuple[dict, str]]
) -> dict[str, str]:
    """Per detector of ``detectors`` (name -> (parameters, own code identity) as they are
    now), why the calibration does not hold for it: the bench's settings changed (``digest``),
    it was never calibrated, or its parameters or code changed. Empty where it holds for all."""
    out = {}
    for name, (params, code) in detectors.items():
        found = cal.detectors.get(name)
        if cal.digest != digest:
            out[name] = "the bench's settings changed since it was calibrated"
        elif found is None:
            out[name] = "it was not calibrated"
        elif canonical(found.params) != canonical(params):
            out[name] = "its parameters changed since it was calibrated"
        elif found.code != code:
            out[name] = "its code changed since it was calibrated"
    return out
