"""Detector costs: train µs per sample, inference µs per window, peak memory for every detector,
and the LSTM's speed targets as ratios against a stock ``torch.nn.LSTM`` timed in the same run
(timings on a shared machine drift; ratios taken minutes apart do not).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import pandas as pd

from .registry import detectors
from .runner import PeakMemory
from .testing import toy_windows


def _rate(call: Callable[[], object], units: float, seconds: float) -> float:
    """Units per second of ``call``, repeated for at least ``seconds`` after one warm-up call."""
    call()
    n, start = 0, time.perf_counter()
    while True:
        call()
        n += 1
        elapsed = time.perf_counter() - start
        if elapsed >= seconds:
            return n * units / elapsed


def detector_costs(names: list[str], n_windows: int, length: int, seed: int = 0) -> pd.DataFrame:
    """Fit each detector once with its defaults on ``n_windows`` toy windows of ``length``
    samples (3840 x 50 is a default-dataset cell at window 50) and predict as many."""
    x, y = toy_windows(n_windows, length, seed)
    rows = []
    for name in names:
        detector = detectors.get(name)()
        with PeakMemory() as mem:
            t0 = time.perf_counter()
            detector.fit(x, y, sampling_rate=1000.0, seed=seed)
            t1 = time.perf_counter()
            detector.predict_proba(x)
            t2 = time.perf_counter()
        rows.append({"detector": name, "train_us_per_sample": (t1 - t0) / x.size * 1e6,
                     "infer_us_per_window": (t2 - t1) / n_windows * 1e6, "peak_mem_mb": mem.mb, "train_s": t1 - t0})
    return pd.DataFrame(rows)


def lstm_targets(length: int = 50, seconds: float = 2.0, seed: int = 0) -> pd.DataFrame:
    """The issue's three LSTM targets, ours against stock torch.nn.LSTM (same size, same data).

    Training is an epoch of SGD with momentum at the detector's default batch size (ours
    serial) and, for reference, at batch 128 (ours parallel over chunks, torch at its best)."""
    import torch

    from . import fastlstm
    from .detectors.lstm import LSTM, _init

    rng = np.random.default_rng(seed)
    hidden, batch = 20, LSTM().batch_size
    n_train, n_infer = 2000, 20_000
    x = rng.normal(size=(n_infer, length)).astype(np.float32)
    y = (np.arange(n_infer) % 2).astype(np.int8)
    params = _init(hidden, rng)
    velocity = [np.zeros_like(p) for p in params]

    torch.manual_seed(seed)
    lstm, head = torch.nn.LSTM(1, hidden, batch_first=True), torch.nn.Linear(hidden, 2)
    opt = torch.optim.SGD([*lstm.parameters(), *head.parameters()], lr=0.01, momentum=0.125)
    xt, yt = torch.tensor(x)[:, :, None], torch.tensor(y).long()

    def ours_epoch(bs: int) -> Callable[[], object]:
        return lambda: fastlstm.train_epoch(x[:n_train], y, np.arange(n_train), bs, 1e-4, 0.125, *params, *velocity)

    def torch_epoch(bs: int, n: int) -> Callable[[], object]:
        def run():
            for s in range(0, n, bs):
                out, _ = lstm(xt[s : s + bs])
                loss = torch.nn.functional.cross_entropy(head(out[:, -1]), yt[s : s + bs])
                opt.zero_grad()
                loss.backward()
                opt.step()
        return run

    def torch_infer(xs):
        with torch.inference_mode():
            return head(lstm(xs)[0][:, -1])

    # stock torch at batch 1 is slow: time it on fewer windows
    n_torch1 = 200 if batch == 1 else n_train
    single = x[0].copy()
    single_t = xt[:1]
    detector = LSTM()
    detector.w_, detector.rt_, detector.b_, detector.wy_, detector.by_ = params
    detector.lo_, detector.scale_, detector.window_length_ = -1.0, 1.0, length
    figures = [
        ("train samples/s, batch %d (default)" % batch, _rate(ours_epoch(batch), n_train * length, seconds),
         _rate(torch_epoch(batch, n_torch1), n_torch1 * length, seconds), 2e6),
        ("train samples/s, batch 128", _rate(ours_epoch(128), n_train * length, seconds),
         _rate(torch_epoch(128, n_train), n_train * length, seconds), 2e6),
        ("batched inference samples/s", _rate(lambda: fastlstm.predict_proba(x, -1.0, 1.0, *params), x.size, seconds),
         _rate(lambda: torch_infer(xt), x.size, seconds), 20e6),
        ("one window, µs (predict_window)", 1e6 / _rate(lambda: detector.predict_window(single), 1, seconds),
         1e6 / _rate(lambda: torch_infer(single_t), 1, seconds), 20.0),
        ("one window, µs (predict_proba, checked)", 1e6 / _rate(lambda: detector.predict_proba(single[None]), 1, seconds),
         1e6 / _rate(lambda: torch_infer(single_t), 1, seconds), 20.0),
    ]
    table = pd.DataFrame(figures, columns=["figure", "slipbench", "stock torch", "target"])
    lower_is_better = table["figure"].str.contains("µs")
    table["speed-up vs torch"] = np.where(lower_is_better, table["stock torch"] / table["slipbench"],
                                          table["slipbench"] / table["stock torch"])
    table["meets target"] = np.where(lower_is_better, table["slipbench"] <= table["target"], table["slipbench"] >= table["target"])
    return table
