"""Cost of the spectral analysis for one sensor instance, against references run in the same
process: scipy's own vectorised ``ks_2samp(axis=...)`` on the same amplitudes (timed on a share
of the rounds and scaled up), and one FFT pass over the same number of sequences.

    python benchmarks/bench_spectral.py [--sensor Nano17] [--instance index] [--scale 0.05]

The target is under 30 s per instance on a 2-core machine.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.stats import ks_2samp

from slipbench.analysis.spectral import analyze_pools, ks_2samp_last_axis, pools
from slipbench.data.defaults import default_dataset
from slipbench.spectra import amplitude_spectrum


def timed(fn, *args, **kwargs) -> tuple[float, object]:
    start = time.perf_counter()
    value = fn(*args, **kwargs)
    return time.perf_counter() - start, value


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sensor", default="Nano17")
    parser.add_argument("--instance", default="index")
    parser.add_argument("--scale", type=float, default=0.05)
    parser.add_argument("--boot", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=200)
    args = parser.parse_args()

    ds = default_dataset(args.scale)
    t_pool, (nonslip, slip, rate) = timed(pools, ds, args.sensor, args.instance, None, 0)
    t_all, _ = timed(
        analyze_pools, nonslip, slip, rate, n_boot=args.boot, repeats=args.repeats, seed=0
    )

    # references on data of the analysis' shape: (rounds, bins, n_boot) amplitudes per class
    length = int(round(rate))
    rng = np.random.default_rng(0)
    seq = nonslip[rng.integers(len(nonslip), size=2 * args.repeats * args.boot)][:, :length]
    t_fft, (_, amp) = timed(amplitude_spectrum, seq, rate)
    amp = amp.reshape(2, args.repeats, args.boot, -1).swapaxes(-1, -2)
    share = max(1, args.repeats // 10)
    t_scipy, _ = timed(ks_2samp, amp[0, :share], amp[1, :share], axis=-1)
    t_ours, _ = timed(ks_2samp_last_axis, amp[0, :share], amp[1, :share])
    scale_up = args.repeats / share

    n_tests = args.repeats * amp.shape[-2]
    print(
        f"{args.sensor} {args.instance}: {len(nonslip)} non-slip and {len(slip)} slip windows of {length} samples; "
        f"{2 * args.repeats * args.boot} FFTs, {n_tests} KS tests"
    )
    print(f"pooling (univariate signal, windows, balance): {t_pool:6.2f} s")
    print(f"analysis (draws, FFTs, KS tests, percentiles):  {t_all:6.2f} s")
    print(
        f"total per instance:                            {t_pool + t_all:6.2f} s  (target < 30 s)"
    )
    print(
        f"reference, one FFT pass over all sequences:    {t_fft:6.2f} s  (analysis / FFT pass = {t_all / t_fft:.1f})"
    )
    print(
        f"KS tests, vectorised here:  {t_ours * scale_up:6.2f} s (timed on {share} of {args.repeats} rounds, scaled)"
    )
    print(
        f"KS tests, scipy axis=-1:    {t_scipy * scale_up:6.2f} s  (scipy / here = {t_scipy / t_ours:.1f})"
    )


if __name__ == "__main__":
    main()
