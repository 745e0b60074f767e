"""A dataset's health as a lab engineer reads it before trusting windows cut from it: rows a
slow sensor's logger repeated (s_t = 0 on them), and, where the import had a time column, time
gaps and a wandering rate. Said as ``warning:`` lines with figures by ``dataset validate``,
``dataset info`` and ``dataset check``; the CSV importer's ``[rate]`` options ``drop_repeats``
and ``resample_hz`` are the routes."""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

import numpy as np

from slipbench.data.format import Dataset
from slipbench.data.schema import RATE_TOLERANCE
from slipbench.vocabulary import SENSOR_TYPE

REPEATS_WARN = 0.1  # a unit with at least this share of samples equal to the one before is said
GAP_STEPS = 1.5  # a time step this many times the file's median step is a gap
JITTER_WARN = 0.05  # files whose rates spread more than this (of the median rate) are said
STEPS_WARN = 0.25  # a file whose steps spread (5-95 %) more than this of its median is said
TIMING_KEY = "slipbench.timing"  # recordings.parquet's metadata: what an import's times showed
LEADING_KEY = "slipbench.leading_slip"  # and what [labels] leading_slip took from which files
DROPPED_KEY = "slipbench.dropped_repeats"  # and the rows [rate] drop_repeats dropped
ROUTES = (
    "import with [rate] drop_repeats = true (and hz = the sensor's own rate), or resample_hz = "
    "a nominal rate with a time_column"
)


def repeats(samples: np.ndarray) -> tuple[int, int]:
    """Of one recording's samples (n_samples, n_channels): how many equal the one before in
    every channel, and the longest run of equal samples (1 where none repeats)."""
    if len(samples) < 2:
        return 0, len(samples)
    same = np.all(samples[1:] == samples[:-1], axis=1)
    if not same.any():
        return 0, 1
    # run lengths of True in ``same``: a run of k repeats is k + 1 equal samples
    edges = np.flatnonzero(np.diff(np.r_[0, same.astype(np.int8), 0]))
    return int(same.sum()), int((edges[1::2] - edges[::2]).max()) + 1


def repeat_lines(dataset: Dataset) -> list[str]:
    """One line per unit whose samples repeat the one before at least :data:`REPEATS_WARN` of
    the time: the share, the longest run and the rate its sensor seems to update at."""
    rec = dataset.recordings
    lines = []
    for (sensor, unit), part in rec.groupby([SENSOR_TYPE, "sensor_instance"], sort=True):
        counted = [repeats(dataset.samples[r]) for r in part["recording_id"]]
        steps = sum(max(len(dataset.samples[r]) - 1, 0) for r in part["recording_id"])
        repeated = sum(c[0] for c in counted)
        if not steps or repeated / steps < REPEATS_WARN:
            continue
        share = repeated / steps
        rate = float(np.median(part["sampling_rate_hz"]))
        lines.append(
            f"sensor {sensor} unit {unit}: {100 * share:.1f} % of its samples repeat the one "
            f"before in every channel ({repeated} of {steps}; longest run "
            f"{max(c[1] for c in counted)} samples), so s_t is 0 there: it updates at about "
            f"{rate * (1 - share):.3g} Hz, logged at {rate:g} Hz; {ROUTES}"
        )
    return lines


def timing(times: np.ndarray, stated_hz: float | None = None) -> dict[str, Any]:
    """One file's time column (s from its first row): its rate (from the median step), its
    gaps (steps over :data:`GAP_STEPS` times the median: count, largest in s), how even its
    steps are (5th and 95th percentiles), its rows over its span and the rate a mapping or the
    lab stated for it (``stated_hz``; None where the times gave it)."""
    step = np.diff(times)
    median = float(np.median(step)) if len(step) else 0.0
    gaps = step[step > GAP_STEPS * median] if median > 0 else step[:0]
    p5, p95 = np.percentile(step, [5, 95]) if len(step) else (0.0, 0.0)
    return {
        "rate_hz": 1.0 / median if median > 0 else 0.0,
        "gaps": int(len(gaps)),
        "largest_gap_s": float(gaps.max()) if len(gaps) else 0.0,
        "median_step_s": median,
        "step_p5_s": float(p5),
        "step_p95_s": float(p95),
        "span_hz": len(step) / float(times[-1]) if len(step) and times[-1] > 0 else 0.0,
        "stated_hz": None if stated_hz is None else float(stated_hz),
    }


def timing_summary(per_file: Mapping[str, dict[str, Any]]) -> dict[str, Any]:
    """What the files' times showed, together (stored under :data:`TIMING_KEY`)."""
    rates = np.array([t["rate_hz"] for t in per_file.values()], float)
    gapped = {f: t for f, t in per_file.items() if t["gaps"]}
    worst = max(gapped, key=lambda f: gapped[f]["largest_gap_s"]) if gapped else ""
    out = {
        "files": len(per_file),
        "rate_hz": [float(rates.min()), float(np.median(rates)), float(rates.max())],
        "gaps": int(sum(t["gaps"] for t in per_file.values())),
        "files_with_gaps": len(gapped),
        "largest_gap_s": gapped[worst]["largest_gap_s"] if worst else 0.0,
        "largest_gap_file": worst,
        "median_step_s": gapped[worst]["median_step_s"] if worst else 0.0,
    }
    uneven = [
        t
        for t in per_file.values()
        if t["step_p95_s"] - t["step_p5_s"] > STEPS_WARN * t["median_step_s"]
    ]
    if uneven:  # 5-95 % of steps, over the files whose steps spread
        out["uneven"] = len(uneven)
        out["step_s"] = [
            min(t["step_p5_s"] for t in uneven),
            float(np.median([t["median_step_s"] for t in uneven])),
            max(t["step_p95_s"] for t in uneven),
        ]
    off = {
        f: t
        for f, t in per_file.items()
        if t["stated_hz"]
        and t["span_hz"]
        and abs(t["span_hz"] / t["stated_hz"] - 1) > RATE_TOLERANCE
    }
    if off:  # the rate stated, against the rows over each file's times
        out["stated_off"] = len(off)
        out["stated_hz"] = [
            min(t["stated_hz"] for t in off.values()),
            max(t["stated_hz"] for t in off.values()),
        ]
        out["span_hz"] = [
            min(t["span_hz"] for t in off.values()),
            max(t["span_hz"] for t in off.values()),
        ]
    return out


def _hz(lo: float, hi: float) -> str:
    return f"{lo:.4g} Hz" if f"{lo:.4g}" == f"{hi:.4g}" else f"{lo:.4g}-{hi:.4g} Hz"


def _step_lines(t: Mapping[str, Any]) -> list[str]:
    """Lines on uneven steps and a stated rate the times do not bear out."""
    lines = []
    if t.get("uneven"):
        lo, mid, hi = (1e3 * x for x in t["step_s"])
        lines.append(
            f"uneven steps: in {t['uneven']} of {t['files']} files 5-95 % of the rows are "
            f"{lo:.3g}-{hi:.3g} ms apart (median {mid:.3g} ms), so a window of n rows spans a "
            "varying time; resample_hz on a CSV import puts them on one grid"
        )
    if t.get("stated_off"):
        lines.append(
            f"stated rate: {t['stated_off']} of {t['files']} files state "
            f"{_hz(*t['stated_hz'])}, but their rows over their time columns come to "
            f"{_hz(*t['span_hz'])}; the stated rate is used (resample_hz on a CSV import uses "
            "the times)"
        )
    return lines


def timing_lines(description: Mapping[str, str]) -> list[str]:
    """The lines about an import's time column (gaps, a wandering rate, uneven steps, a stated
    rate the times do not bear out) that its dataset's description stored; none where it had no
    time column or nothing to say."""
    text = description.get(TIMING_KEY)
    if not text:
        return []
    try:
        t = json.loads(text)
        if t.get("resampled_hz"):  # the import put every file on one rate: nothing left to say
            return []
        lo, mid, hi = t["rate_hz"]
        lines = []
        if t["gaps"]:
            lines.append(
                f"time gaps: {t['gaps']} steps over {GAP_STEPS:g} x the median step in "
                f"{t['files_with_gaps']} of {t['files']} files (largest {t['largest_gap_s']:.3g} s "
                f"among {t['median_step_s']:.3g} s steps, in {t['largest_gap_file']}): windows "
                "span the missing rows; resample_hz on import fills them by interpolation"
            )
        if mid > 0 and hi - lo > JITTER_WARN * mid:
            lines.append(
                f"rate jitter: the files' rates (from their time columns) run {lo:.3g}-{hi:.3g} Hz "
                f"(median {mid:.3g} Hz); resample_hz on import puts them on one rate"
            )
        return lines + _step_lines(t)
    except (ValueError, TypeError, KeyError):  # written by other means: shown as it is
        return [f"timing: {text}"]


def leading_summary(cut: Mapping[str, tuple[str, int, float]], held: int) -> dict[str, Any]:
    """What ``[labels] leading_slip`` took (stored under :data:`LEADING_KEY`): ``cut`` maps
    each file that started in slip to (route, rows, seconds); ``held``: the hold-slip files."""
    most = max(cut, key=lambda f: cut[f][1])
    return {
        "routes": sorted({v[0] for v in cut.values()}),
        "files": len(cut),
        "hold_slip_files": held,
        "rows": int(sum(v[1] for v in cut.values())),
        "seconds": float(sum(v[2] for v in cut.values())),
        "most_file": most,
        "most_rows": int(cut[most][1]),
    }


def leading_lines(description: Mapping[str, str]) -> list[str]:
    """The line saying what an import's ``leading_slip`` took; none where it took nothing."""
    text = description.get(LEADING_KEY)
    if not text:
        return []
    try:
        t = json.loads(text)
        did = {"trim": "dropped", "unlabelled": "kept unlabelled"}
        return [
            f"leading slip: {t['files']} of {t['hold_slip_files']} hold-slip files started in "
            f"slip; [labels] leading_slip = {' / '.join(repr(r) for r in t['routes'])} "
            f"{' or '.join(did.get(r, r) for r in t['routes'])} their rows before the first "
            f"no-slip sample: {t['rows']} rows ({t['seconds']:.3g} s) in all, most "
            f"{t['most_rows']} in {t['most_file']}"
        ]
    except (ValueError, TypeError, KeyError):  # written by other means: shown as it is
        return [f"leading slip: {text}"]


def dropped_summary(per_file: Mapping[str, tuple[int, int]]) -> dict[str, Any]:
    """The rows ``[rate] drop_repeats`` dropped (stored under :data:`DROPPED_KEY`): ``per_file``
    maps each file to (its rows, those dropped)."""
    most = max(per_file, key=lambda f: per_file[f][1] / max(per_file[f][0], 1))
    return {
        "files": len(per_file),
        "rows": int(sum(v[0] for v in per_file.values())),
        "dropped": int(sum(v[1] for v in per_file.values())),
        "most_file": most,
        "most_share": per_file[most][1] / max(per_file[most][0], 1),
    }


def dropped_lines(description: Mapping[str, str]) -> list[str]:
    """The line counting the rows an import's ``drop_repeats`` dropped; none where it dropped
    none or was not asked."""
    text = description.get(DROPPED_KEY)
    if not text:
        return []
    try:
        t = json.loads(text)
        if not t["dropped"]:
            return []
        return [
            f"repeated rows dropped: [rate] drop_repeats = true dropped {t['dropped']} of "
            f"{t['rows']} rows ({100 * t['dropped'] / t['rows']:.1f} %) in {t['files']} files "
            f"(most {100 * t['most_share']:.1f} % of {t['most_file']}); their labels with them"
        ]
    except (ValueError, TypeError, KeyError, ZeroDivisionError):  # written by other means
        return [f"repeated rows dropped: {text}"]


def health_lines(dataset: Dataset, description: Mapping[str, str]) -> list[str]:
    """Every health line of a dataset, each to be printed after ``warning: ``."""
    return (
        repeat_lines(dataset)
        + timing_lines(description)
        + dropped_lines(description)
        + leading_lines(description)
    )
