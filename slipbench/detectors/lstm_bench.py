"""The LSTM's speed targets against a stock ``torch.nn.LSTM`` of the same size, timed in the same
run (``slipbench bench`` calls it through ``LSTM.benchmark``)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pandas as pd

from slipbench.base import DEFAULT_HOP, Streamer, push_costs, rate
from slipbench.detectors import lstm_kernels as kernels


def lstm_targets(
    detector_class: type, length: int = 50, seconds: float = 2.0, seed: int = 0
) -> pd.DataFrame:
    """The issue's LSTM targets, ours against stock torch.nn.LSTM (same size, same data).

    Training is an epoch of SGD with momentum at the detector's default batch size (ours
    serial) and, for reference, at batch 128 (ours parallel over chunks, torch at its best).
    Streaming (window ``length``, hop DEFAULT_HOP) is the cost per incoming sample of
    ``detector.streamer(hop).push`` fed a hop, or a sample, at a time (the median push, see
    ``slipbench.base.push_costs``: robust to other processes); the references score
    each window anew every hop: stock torch (one thread), and the base class's stream, which
    calls ``predict_proba`` on each window as it completes."""
    import torch

    rng = np.random.default_rng(seed)
    hidden, batch = 20, detector_class().batch_size
    n_train, n_infer = 2000, 20_000
    x = rng.normal(size=(n_infer, length)).astype(np.float32)
    y = (np.arange(n_infer) % 2).astype(np.int8)
    params = kernels.init_params(hidden, rng)
    velocity = [np.zeros_like(p) for p in params]

    torch.manual_seed(seed)
    lstm, head = torch.nn.LSTM(1, hidden, batch_first=True), torch.nn.Linear(hidden, 2)
    opt = torch.optim.SGD([*lstm.parameters(), *head.parameters()], lr=0.01, momentum=0.125)
    xt, yt = torch.tensor(x)[:, :, None], torch.tensor(y).long()

    def ours_epoch(bs: int) -> Callable[[], object]:
        return lambda: kernels.train_epoch(
            (x[:n_train], y), np.arange(n_train), (bs, 1e-4, 0.125), params, velocity
        )

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
    detector = detector_class()
    detector.w_, detector.rt_, detector.b_, detector.wy_, detector.by_ = params
    detector.lo_, detector.scale_, detector.window_length_ = -1.0, 1.0, length
    hop = min(DEFAULT_HOP, length)
    signal = x[:400].ravel()  # 20,000 samples at window 50
    stream = detector.streamer(hop)
    pieces = {n: [signal[i : i + n] for i in range(0, len(signal), n)] for n in (hop, 1)}
    # one window is too small for torch's thread pool to help; on a shared machine its threads
    # wait for one another whenever another process holds a core (here: 0.2 s for a window)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    torch_window_us = 1e6 / rate(lambda: torch_infer(single_t), 1, seconds)
    torch.set_num_threads(threads)
    torch_per_sample = torch_window_us / hop

    anew = Streamer(
        detector, hop
    )  # the base class's stream: predict_proba on each window as it completes
    figures = [
        (
            f"train samples/s, batch {batch} (default)",
            rate(ours_epoch(batch), n_train * length, seconds),
            rate(torch_epoch(batch, n_torch1), n_torch1 * length, seconds),
            2e6,
        ),
        (
            "train samples/s, batch 128",
            rate(ours_epoch(128), n_train * length, seconds),
            rate(torch_epoch(128, n_train), n_train * length, seconds),
            2e6,
        ),
        (
            "batched inference samples/s",
            rate(
                lambda: kernels.predict_proba(x, kernels.network(-1.0, 1.0, params)),
                x.size,
                seconds,
            ),
            rate(lambda: torch_infer(xt), x.size, seconds),
            20e6,
        ),
        (
            "one window, µs (predict_window)",
            1e6 / rate(lambda: detector.predict_window(single), 1, seconds),
            torch_window_us,
            20.0,
        ),
        (
            "one window, µs (predict_proba, checked)",
            1e6 / rate(lambda: detector.predict_proba(single[None]), 1, seconds),
            torch_window_us,
            20.0,
        ),
        (
            f"stream, a hop per push, µs/sample (hop {hop})",
            min(push_costs(stream, pieces[hop])[0] for _ in range(3)),
            torch_per_sample,
            2.0,
        ),
        (
            f"stream, a sample per push, µs/sample (hop {hop})",
            min(push_costs(stream, pieces[1])[0] for _ in range(3)),
            torch_per_sample,
            np.nan,
        ),
        (
            f"each window anew, a hop per push, µs/sample (hop {hop})",
            min(push_costs(anew, pieces[hop])[0] for _ in range(3)),
            torch_per_sample,
            np.nan,
        ),
    ]
    table = pd.DataFrame(figures, columns=["figure", "slipbench", "reference", "target"])
    table.insert(3, "reference is", "stock torch.nn.LSTM")
    table = pd.concat([table, lockstep_figures(x, y, batch, seconds)], ignore_index=True)
    lower_is_better = table["figure"].str.contains("µs")
    table["speed-up"] = np.where(
        lower_is_better,
        table["reference"] / table["slipbench"],
        table["slipbench"] / table["reference"],
    )
    meets = np.where(
        lower_is_better,
        table["slipbench"] <= table["target"],
        table["slipbench"] >= table["target"],
    )
    table["meets target"] = np.where(table["target"].isna(), "", np.where(meets, "yes", "no"))
    return table


def lockstep_figures(
    x: np.ndarray, y: np.ndarray, batch: int, seconds: float, n_models: int = 32
) -> pd.DataFrame:
    """Training samples/s of ``n_models`` LSTM models in lockstep (an epoch of each on its own
    order of 250 windows of x, in the SIMD lanes, blocks of lanes on numba's threads), against
    the same epochs one model after another (the single-model kernel), timed in the same run.
    The issue's target: 4x the per-model throughput of one at a time."""
    from slipbench.detectors import lstm_lockstep

    n, length, hidden = 250, x.shape[1], 20
    rng = np.random.default_rng(0)
    models = [kernels.init_params(hidden, rng) for _ in range(n_models)]
    orders = [rng.permutation(n) for _ in range(n_models)]
    lanes = -(-n_models // lstm_lockstep.MODELS) * lstm_lockstep.MODELS
    plan_orders = np.zeros((lanes, n), np.int64)
    plan_orders[:n_models] = orders
    counts = np.where(np.arange(lanes) < n_models, n, 0)
    plan = (plan_orders, counts, np.full(lanes, 1e-4, np.float32), batch, 0.125)
    params = lstm_lockstep.pack(models)
    velocity = np.zeros_like(params)
    data = (x[:n], y[:n])

    def one_after_another():
        for model, order in zip(models, orders):
            v = [np.zeros_like(p) for p in model]
            kernels.train_epoch(data, order, (batch, 1e-4, 0.125), model, v)

    def lockstep():
        lstm_lockstep.lockstep_epoch(data, plan, params, velocity)

    # alternated, the best of 5 rounds each: other processes' load falls on both alike
    samples, rounds, pair = n_models * n * length, 5, (lockstep, one_after_another)
    best = np.max([[rate(f, samples, seconds / rounds) for f in pair] for _ in range(rounds)], 0)
    return pd.DataFrame(
        [
            (
                f"train samples/s, {n_models} models in lockstep",
                *best,
                f"the same {n_models} models one after another",
                np.nan,
            )
        ],
        columns=["figure", "slipbench", "reference", "reference is", "target"],
    )
