"""Synthetic result rows for every built-in protocol, deterministic, for layout tests."""

from __future__ import annotations

import json
import zlib

import pandas as pd

SENSORS = {
    "Nano17": ("index", "middle", "little"),
    "OptoForce20": ("index", "middle", "little"),
    "BioTacSP": ("index", "middle"),
}
RATES = {"Nano17": 1000.0, "OptoForce20": 1000.0, "BioTacSP": 850.0}


def _cells(protocol: str):
    for sensor, fingers in SENSORS.items():
        if protocol == "cross-instance":
            for train in (*fingers, "combined"):
                for test in (*fingers, "combined"):
                    yield {"sensor_type": sensor, "train_instance": train, "test_instance": test}
            continue
        for finger in fingers:
            base = {"sensor_type": sensor, "sensor_instance": finger}
            if protocol == "window-size":
                for w in (5, 10, 25, 50, 100, 200):
                    yield {**base, "window": w}
            elif protocol == "sampling-rate":
                for d in (32, 16, 8, 4, 2, 1):
                    yield {
                        **base,
                        "window": 200,
                        "downsample": d,
                        "rate_hz": RATES[sensor] / d,
                        "decimation": "plain",
                    }
            elif protocol == "material-holdout":
                for m in ("aluminum", "PVC", "neoprene", "cardboard", "plywood"):
                    for t in ("with", "without"):
                        yield {**base, "material": m, "training": t}
            elif protocol == "speed-holdout":
                for s in (5.0, 25.0, 50.0, 75.0):
                    for t in ("with", "without"):
                        yield {**base, "speed_mm_s": s, "training": t}


def recorded(protocol: str, detector: str) -> dict:
    """What ``evaluate`` records in each row of the plugins: the protocol's layout and
    presentation at its default options, and whether the detector is the reference."""
    from slipbench.engine.registry import detectors, protocols
    from slipbench.protocol import described

    known = detector in detectors.names()  # a test's own name (hostile, made up) is no reference
    return {
        **described(protocols.get(protocol)()),
        "detector_reference": known and bool(detectors.get(detector).reference),
    }


def fake_rows(
    protocol: str, detector: str = "lstm", seeds=(0,), shift: float = 0.0
) -> pd.DataFrame:
    """Rows as ``evaluate`` writes them, accuracies drawn from a hash of the cell (so stable)."""
    plugins = recorded(protocol, detector)
    rows = []
    for cell in _cells(protocol):
        text = json.dumps(cell, sort_keys=True)
        for seed in seeds:
            u = zlib.crc32(f"{text}|{detector}|{seed}".encode()) / 2**32
            acc = 0.6 + 0.35 * u + shift
            row = {
                "key": f"{zlib.crc32((text + detector + str(seed)).encode()):08x}",
                "protocol": protocol,
                "detector": detector,
                "split": "paper",
                "seed": seed,
                **cell,
                "cell": text,
                "status": "ok",
                "reason": "",
                "accuracy": acc,
                "accuracy_lo": acc - 0.021,
                "accuracy_hi": acc + 0.019,
                "tp_rate": acc + 0.02,
                "tp_rate_lo": acc,
                "tp_rate_hi": acc + 0.04,
                "tn_rate": acc - 0.02,
                "tn_rate_lo": acc - 0.04,
                "tn_rate_hi": acc,
                "dataset_fingerprint": "f00d",
                **plugins,
            }
            rows.append(row)
    frame = pd.DataFrame(rows)
    if protocol == "cross-instance":  # a cell the dataset cannot fill, as the runner reports it
        first = frame.index[0]
        frame.loc[first, ["status", "reason"]] = ["skipped", "no slip windows to test on"]
    return frame


def all_rows() -> pd.DataFrame:
    """Every protocol with lstm; window-size with holweg too, and lstm's sampling rate with 3 seeds."""
    parts = [
        fake_rows(p) for p in ("window-size", "material-holdout", "speed-holdout", "cross-instance")
    ]
    parts += [fake_rows("sampling-rate", seeds=(0, 1, 2)), fake_rows("window-size", "holweg")]
    return pd.concat(parts, ignore_index=True)


DETECTORS = ("lstm", "holweg", "bandpass", "wavelet-svm", "minirocket")
PROTOCOLS = ("window-size", "sampling-rate", "material-holdout", "speed-holdout", "cross-instance")


def whole_paper_pair(root) -> tuple:
    """BASE and CANDIDATE results files of a whole-paper run (every built-in detector and
    paper protocol, 1,395 cells): the candidate differs per cell by a deterministic amount
    within +-3 points, and loses 15 points on the LSTM's BioTac SP sampling-rate cells."""
    base = pd.concat([fake_rows(p, d) for d in DETECTORS for p in PROTOCOLS], ignore_index=True)
    cand = base.copy()
    u = base["cell"].map(lambda c: zlib.crc32(c.encode()) / 2**32) - 0.5
    worse = (
        (base["detector"] == "lstm")
        & (base["protocol"] == "sampling-rate")
        & (base["sensor_type"] == "BioTacSP")
    )
    change = 0.06 * u - 0.15 * worse
    for name in ("accuracy", "tp_rate", "tn_rate"):
        for col in (name, f"{name}_lo", f"{name}_hi"):
            cand[col] = (base[col] + change).clip(0, 1)  # a rate stays a rate
    paths = (root / "base.parquet", root / "candidate.parquet")
    base.to_parquet(paths[0])
    cand.to_parquet(paths[1])
    return paths


def predictions_pair(
    root,
    n_cells: int = 12,
    trials: int = 24,
    windows: int = 8,
    base_seeds=(0,),
    cand_seeds=(0,),
    flip: float = 0.0,
    unchanged_cells: int = 0,
    low_n_cells: int = 0,
) -> tuple:
    """BASE and CANDIDATE result folders of ``n_cells`` window-size cells with predictions, all
    testing the same ``trials`` trials (half slip, half non-slip; the ``low_n_cells`` last cells
    only 4 of each class). A seed's predictions depend on the cell, the trial and the seed only,
    so the two sides agree where their seeds do; the candidate then predicts every window of
    a share ``flip`` of the trials (drawn per cell) wrongly (a spread-out drop), except in the first
    ``unchanged_cells`` cells, which stay identical."""
    import numpy as np

    from slipbench.stats.metrics import classification_figures

    trial_ids = np.array([f"t{i:03d}" for i in range(trials)])
    slip = np.arange(trials) % 2 == 0
    hard = np.random.default_rng(99).normal(0, 1, trials)  # shared trial difficulty
    folders = []
    for side, seeds in (("base", base_seeds), ("cand", cand_seeds)):
        folder = root / side
        (folder / "predictions").mkdir(parents=True)
        rows = []
        for c in range(n_cells):
            keep = np.ones(trials, bool)
            if c >= n_cells - low_n_cells:
                keep = np.isin(np.arange(trials), np.arange(8))
            cell = {"sensor_type": "Nano17", "sensor_instance": "index", "window": 5 * (c + 1)}
            text = json.dumps(cell, sort_keys=True)
            # the trials the candidate fails in this cell: drawn per cell
            order = np.argsort(np.random.default_rng(1000 + c).random(trials))
            flipped = np.isin(np.arange(trials), order[: round(flip * trials)])
            for s in seeds:
                rng = np.random.default_rng(zlib.crc32(f"{c}|{s}".encode()))
                t = np.repeat(np.flatnonzero(keep), windows)
                p = 1 / (1 + np.exp(-(1.2 + hard[t] + rng.normal(0, 0.3))))
                correct = rng.random(len(t)) < p
                if side == "cand" and c >= unchanged_cells:
                    correct = np.where(flipped[t], False, correct)
                y = slip[t]
                pred = np.where(correct, y, ~y)
                score = np.where(pred, 0.8, 0.2)
                key = f"{side}-{c:03d}-{s}"
                pd.DataFrame(
                    {
                        "recording_id": trial_ids[t],
                        "window_index": np.tile(np.arange(windows), keep.sum()),
                        "y_true": y.astype(np.int8),
                        "score": score,
                        "trial": trial_ids[t],
                    }
                ).to_parquet(folder / "predictions" / f"{key}.parquet")
                rows.append(
                    {
                        "key": key,
                        "protocol": "window-size",
                        "detector": "holweg",
                        "split": "grouped",
                        "seed": s,
                        **cell,
                        "cell": text,
                        "status": "ok",
                        "reason": "",
                        "dataset_fingerprint": "f00d",
                        **classification_figures(y, pred, trial_ids[t], seed=c, scores=score),
                    }
                )
        pd.DataFrame(rows).to_parquet(folder / "results.parquet")
        folders.append(folder)
    return tuple(folders)


def inputs_folder(
    root,
    boost: dict[str, float] | None = None,
    seeds=(0,),
    trials: int = 24,
    windows: int = 6,
    legacy: bool = True,
    predictions: bool = True,
    model_noise: float = 0.3,
    replicate: int = 0,
    split_noise: float = 0.0,
) -> tuple:
    """A results folder of one detector ("tcn") run with ``--input both`` on window-size cells
    of the sensors of ``boost`` (two at least), with predictions unless not ``predictions``;
    returns (folder, rows).

    Both inputs test the same windows of the same ``trials`` trials per sensor (half slip), and a
    trial's difficulty is shared by every cell and input. A window is classified correctly with
    probability sigmoid(0.8 + difficulty + a draw of N(0, ``model_noise``) per trained model (its
    retraining noise) + ``boost[sensor]`` and a draw of N(0, ``split_noise``) per seed and sensor
    for channels): with the default boost the channels are truly better on Nano17 (+1.5 on the
    logit) and truly equal on the BioTac SP. The split's draw is the luck a seed's split gives one
    input over the other in every cell of a sensor at once (the committed reproduction shows it:
    benchmarks/bench_seed_by_cell.py). ``replicate``
    draws the trials and predictions anew. ``legacy``: the univariate rows lack the ``input``
    column, as rows of earlier versions do. Beside the paired cells: a channels cell of the first
    sensor (index, window 200) without a univariate twin, and the same cell of the second sensor
    with its channels run skipped."""
    import numpy as np

    from slipbench.stats.metrics import classification_figures

    boost = {"Nano17": 1.5, "BioTacSP": 0.0} if boost is None else boost
    first, second = list(boost)[:2]
    lone = (first, "index", 200)  # a channels cell without its univariate twin
    skipped = (second, "index", 200)  # a cell whose channels run was skipped
    folder = root / "results"
    (folder / "predictions").mkdir(parents=True)
    rows = []
    slip = np.arange(trials) % 2 == 0
    for si, sensor in enumerate(boost):
        trial_ids = np.array([f"{sensor}-t{i:03d}" for i in range(trials)])
        hard = np.random.default_rng((7 + si, replicate)).normal(0, 1, trials)
        for finger in ("index", "middle"):
            for window in (25, 50, 100, 200):
                cell = {"sensor_type": sensor, "sensor_instance": finger, "window": window}
                for kind in ("univariate", "channels"):
                    if kind == "univariate" and (sensor, finger, window) == lone:
                        continue
                    key_cell = {**cell, **({"input": "channels"} if kind == "channels" else {})}
                    for s in seeds:
                        key = f"{kind}-{sensor}-{finger}-{window}-{s}"
                        row = {
                            "key": key,
                            "protocol": "window-size",
                            "detector": "tcn",
                            "detector_params": "{}",
                            "split": "grouped",
                            "seed": s,
                            **cell,
                            "cell": json.dumps(key_cell, sort_keys=True),
                            "status": "ok",
                            "reason": "",
                            "dataset_fingerprint": "f00d",
                            **({"input": kind} if kind == "channels" or not legacy else {}),
                        }
                        if kind == "channels" and (sensor, finger, window) == skipped:
                            row |= {"status": "skipped", "reason": "units differ in channels"}
                            rows.append(row)
                            continue
                        rng = np.random.default_rng(zlib.crc32(f"{key}|{replicate}".encode()))
                        t = np.repeat(np.arange(trials), windows)
                        logit = 0.8 + hard[t] + rng.normal(0, model_noise)
                        split = np.random.default_rng((11 + si, s, replicate)).normal(0, 1)
                        logit += boost[sensor] + split_noise * split if kind == "channels" else 0.0
                        correct = rng.random(len(t)) < 1 / (1 + np.exp(-logit))
                        y = slip[t]
                        pred = np.where(correct, y, ~y)
                        score = np.where(pred, 0.8, 0.2)
                        if predictions:
                            pd.DataFrame(
                                {
                                    "recording_id": trial_ids[t],
                                    "window_index": np.tile(np.arange(windows), trials),
                                    "y_true": y.astype(np.int8),
                                    "score": score,
                                    "trial": trial_ids[t],
                                }
                            ).to_parquet(folder / "predictions" / f"{key}.parquet")
                        row |= classification_figures(y, pred, trial_ids[t], seed=s, scores=score)
                        rows.append(row)
    frame = pd.DataFrame(rows)
    frame.to_parquet(folder / "results.parquet")
    return folder, frame
