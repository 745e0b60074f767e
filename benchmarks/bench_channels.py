"""What reading the raw channels costs: training time and batched scoring of the detectors that
take both inputs, on windows of C channels against the same number of univariate windows,
measured in the same run.

    python benchmarks/bench_channels.py [--windows 2000] [--window 200] [--channels 25]
                                        [--epochs 5] [--threads 1]

tcn trains a fixed number of epochs (``--epochs``, early stopping off), so both inputs do the
same work per epoch; its figure per epoch is the one that matters (early stopping decides how
many a cell runs). Each fit runs once after a short warm-up fit (torch's first calls set up) (a training run is long enough that set-up is noise, and
a shared machine's other work slows whichever runs at that moment: read a ratio near 1 as
equal). torch and BLAS run on ``--threads`` threads.
"""

from __future__ import annotations

import argparse
import time

import pandas as pd
from threadpoolctl import threadpool_limits

from slipbench.engine.registry import detectors
from slipbench.testing import toy_channel_windows, toy_windows


def measure(name: str, n: int, window: int, channels: int, epochs: int) -> dict[str, object]:
    """One fit and one batched scoring of ``name`` on univariate windows and on windows of
    ``channels`` channels: seconds, and the channels / univariate ratio."""
    cls = detectors.get(name)
    params = (
        {"max_epochs": epochs, "patience": epochs + 1, "device": "cpu"} if name == "tcn" else {}
    )
    kinds = {
        "univariate": toy_windows(n, window),
        f"{channels} channels": toy_channel_windows(n, window, channels),
    }
    seconds: dict[str, float] = {}
    for label, (x, y) in kinds.items():
        cls(**{**params, "max_epochs": 1} if params else {}).fit(x[:200], y[:200])  # warm-up
        detector = cls(**params)
        t0 = time.perf_counter()
        detector.fit(x, y, seed=0)
        seconds[f"fit s, {label}"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        detector.predict_proba(x)
        seconds[f"score s, {label}"] = time.perf_counter() - t0
    uni, multi = kinds
    ratios = {
        f"{w} ratio": seconds[f"{w} s, {multi}"] / seconds[f"{w} s, {uni}"]
        for w in ("fit", "score")
    }
    return {"detector": name, "windows": n, "window": window, **seconds, **ratios}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--detector", action="append", help="default: tcn and wavelet-svm")
    parser.add_argument("--windows", type=int, default=2000)
    parser.add_argument("--window", type=int, default=200)
    parser.add_argument("--channels", type=int, default=25)
    parser.add_argument("--epochs", type=int, default=5, help="tcn's epochs per fit")
    parser.add_argument("--threads", type=int, default=1, help="threads of torch and BLAS")
    args = parser.parse_args()
    names = args.detector or ["tcn", "wavelet-svm"]
    names = [n for n in names if detectors.status(n).state == "ok"]
    threadpool_limits(args.threads)
    if "tcn" in names:
        import torch

        torch.set_num_threads(args.threads)
    table = pd.DataFrame(
        [measure(n, args.windows, args.window, args.channels, args.epochs) for n in names]
    )
    print(f"{args.threads} thread(s); tcn: {args.epochs} epochs per fit")
    print(table.T.to_string(header=False, float_format=lambda v: f"{v:.3g}"))


if __name__ == "__main__":
    main()
