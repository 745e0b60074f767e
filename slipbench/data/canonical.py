"""The canonical form of a dataset, and the checks that bring a recordings table, samples and
labels to it: recordings validated and sorted by ``recording_id`` (each unit's rates pooled at
their median), integer samples as float64, labels as int8. Reading a file and building a
:class:`~slipbench.data.format.Dataset` in memory both end here, so both give the same form."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from slipbench.data.messages import data_error, plain_number, some_names
from slipbench.data.schema import (
    DERIVED_COLUMNS,
    FORMAT_COLUMNS,
    MAX_MAGNITUDE,
    NULLABLE,
    OPTIONAL,
    RATE_TOLERANCE,
    RECORDINGS_FILE,
    SCENARIOS,
    STRING_COLUMNS,
    UNIVARIATE_CHANNELS,
)
from slipbench.vocabulary import SENSOR_TYPE, SLIPS


def canonical_recordings(frame: pd.DataFrame, where: str | Path) -> pd.DataFrame:
    """Validate a recordings table and bring it to the canonical form (see :class:`~slipbench.data.format.Dataset`)."""
    cols = _present_columns(frame, where)
    ids = cols["recording_id"]
    _check_strings(cols, where)
    _check_ids_and_scenarios(cols, where)
    rate, speed = _rate_and_speed(cols, where)
    n_ch = _channel_lists(cols, where)
    cols["trial"] = [rid if t is None else t for rid, t in zip(ids, cols["trial"])]
    univariate = UNIVARIATE_CHANNELS.name
    cols[univariate] = _univariate_channels(
        list(frame[univariate]) if univariate in frame.columns else [None] * len(ids),
        ids,
        cols["channels"],
        where,
    )
    out = pd.DataFrame({**cols, "speed_mm_s": speed, "sampling_rate_hz": rate})
    out["n_channels"] = n_ch
    for name in frame.columns:  # a caller's own columns ride along (the format ignores them)
        if name not in out.columns and name not in DERIVED_COLUMNS:
            out[name] = frame[name].to_numpy()
    out = out.iloc[np.argsort(np.array(ids, dtype=object), kind="stable")].reset_index(drop=True)
    out["unit_rate_hz"] = _unit_rates(out, where)
    return out


def _present_columns(frame: pd.DataFrame, where: str | Path) -> dict[str, list]:
    """The format's columns as lists, None where a value is missing; refuses a missing required
    column, an empty table and a null where the format allows none."""
    missing = [c for c in FORMAT_COLUMNS if c not in frame.columns and c not in OPTIONAL]
    if missing:
        raise data_error(
            where,
            f"required column missing (columns present: {', '.join(map(str, frame.columns))})",
            column=missing[0],
        )
    n = len(frame)
    if n == 0:
        raise data_error(where, "no recordings")
    cols: dict[str, list] = {}
    for name in FORMAT_COLUMNS:
        values = list(frame[name]) if name in frame.columns else [None] * n
        # a NaN rate is a bad number, not a missing one; elsewhere NaN is how pandas says null
        absent = (lambda v: v is None or v is pd.NA) if name == "sampling_rate_hz" else is_null
        cols[name] = [None if absent(v) else v for v in values]
    ids = cols["recording_id"]
    for name in FORMAT_COLUMNS:
        for i, v in enumerate(cols[name]):
            if v is None and name not in NULLABLE:
                raise data_error(
                    where, "null value", None if name == "recording_id" else ids[i], name
                )
    return cols


def _check_strings(cols: dict[str, list], where: str | Path) -> None:
    ids = cols["recording_id"]
    for name in STRING_COLUMNS:
        for i, v in enumerate(cols[name]):
            if v is not None and not isinstance(v, str):
                raise data_error(
                    where, f"must be a string, found {type(v).__name__} {v!r}", ids[i], name
                )
            if v == "" and name in ("recording_id", SENSOR_TYPE, "sensor_instance"):
                raise data_error(
                    where, "empty string", None if name == "recording_id" else ids[i], name
                )


def _check_ids_and_scenarios(cols: dict[str, list], where: str | Path) -> None:
    ids = cols["recording_id"]
    seen: set[str] = set()
    for rid in ids:
        if rid in seen:
            raise data_error(where, "recording_id is not unique", rid, "recording_id")
        seen.add(rid)
    for rid, scenario in zip(ids, cols["scenario"]):
        if scenario not in SCENARIOS:
            raise data_error(
                where,
                f"scenario {scenario!r} is not one of {', '.join(SCENARIOS)}",
                rid,
                "scenario",
            )


def _rate_and_speed(cols: dict[str, list], where: str | Path) -> tuple[np.ndarray, np.ndarray]:
    ids = cols["recording_id"]
    rate = _floats(cols["sampling_rate_hz"], ids, where, "sampling_rate_hz")
    bad = ~(np.isfinite(rate) & (rate > 0))
    if bad.any():
        i = int(np.argmax(bad))
        raise data_error(
            where,
            f"sampling rate must be a finite positive number, got {plain_number(rate[i])}",
            ids[i],
            "sampling_rate_hz",
        )
    speed = _floats(cols["speed_mm_s"], ids, where, "speed_mm_s")
    bad = ~np.isnan(speed) & ~(np.isfinite(speed) & (speed >= 0))
    if bad.any():
        i = int(np.argmax(bad))
        raise data_error(
            where,
            f"speed must be finite and >= 0, got {plain_number(speed[i])}",
            ids[i],
            "speed_mm_s",
        )
    return rate, speed


def _channel_lists(cols: dict[str, list], where: str | Path) -> np.ndarray:
    """Channels and units as lists of strings, one unit per channel; the channel counts."""
    ids = cols["recording_id"]
    for name in ("channels", "units"):
        cols[name] = [_strings(v, rid, where, name) for rid, v in zip(ids, cols[name])]
    n_ch = np.array([len(c) for c in cols["channels"]], dtype=np.int64)
    for rid, channels, units in zip(ids, cols["channels"], cols["units"]):
        if not channels:
            raise data_error(where, "no channels", rid, "channels")
        if len(units) != len(channels):
            raise data_error(
                where,
                f"units must list one unit per channel ({len(channels)} channels, {len(units)} units)",
                rid,
                "units",
            )
    return n_ch


def is_null(v: Any) -> bool:
    """Whether a cell is missing, however pandas or Arrow spelled it (None, NaN, NA, NaT)."""
    return v is None or (isinstance(v, float) and np.isnan(v)) or v is pd.NA or v is pd.NaT


def _floats(values: list, ids: list, where, name: str) -> np.ndarray:
    out = np.full(len(values), np.nan)
    for i, v in enumerate(values):
        if v is None:
            continue
        if isinstance(v, (bool, np.bool_)) or not isinstance(
            v, (int, float, np.integer, np.floating)
        ):
            raise data_error(
                where, f"must be a number, found {type(v).__name__} {v!r}", ids[i], name
            )
        out[i] = float(v)
    return out


def _strings(value: Any, rid: str, where, name: str) -> tuple[str, ...]:
    if isinstance(value, str) or not hasattr(value, "__iter__"):
        raise data_error(
            where, f"must be a list of strings, found {type(value).__name__}", rid, name
        )
    items = tuple(value)
    for item in items:
        if not isinstance(item, str):
            raise data_error(
                where,
                f"must be a list of strings, found {'null' if is_null(item) else repr(item)} in it",
                rid,
                name,
            )
    return items


def _univariate_channels(
    values: list, ids: list, channels: list[tuple[str, ...]], where
) -> list[tuple[str, ...]]:
    """Each recording's ``univariate_channels`` in canonical form: the channels it names, in the
    order of ``channels``; () where it names none (null or empty) or every channel, which both
    mean all of them, so that the same signal s gives the same fingerprint."""
    name = UNIVARIATE_CHANNELS.name
    out = []
    for rid, value, chans in zip(ids, values, channels):
        named = () if is_null(value) else _strings(value, rid, where, name)
        unknown = [c for c in named if c not in chans]
        if unknown:
            raise data_error(
                where,
                f"names {some_names(unknown)}, not among the recording's channels ({some_names(chans, 6)})",
                rid,
                name,
            )
        twice = sorted({c for c in named if named.count(c) > 1})
        if twice:
            raise data_error(where, f"names {some_names(twice)} more than once", rid, name)
        kept = tuple(c for c in chans if c in named)
        out.append(() if len(kept) == len(chans) else kept)
    return out


def _unit_rates(rec: pd.DataFrame, where) -> np.ndarray:
    """The median rate of each recording's unit; a unit whose rates spread beyond
    :data:`RATE_TOLERANCE` of its lowest is refused, naming the recordings at both ends."""
    out = np.empty(len(rec))
    rates = rec["sampling_rate_hz"].to_numpy(dtype=float)
    ids = rec["recording_id"].to_numpy(dtype=object)
    for (sensor, unit), rows in rec.groupby(
        [SENSOR_TYPE, "sensor_instance"], sort=True
    ).indices.items():
        r = rates[rows]
        lo, hi = r.min(), r.max()
        if hi > lo * (1 + RATE_TOLERANCE):
            raise data_error(
                where,
                f"sensor {sensor!r} unit {unit!r}: sampling rates differ by {100 * (hi / lo - 1):.3g} %, more than "
                f"RATE_TOLERANCE ({100 * RATE_TOLERANCE:g} %): lowest {plain_number(lo)} Hz in recording(s) {some_names(ids[rows][r == lo])}, "
                f"highest {plain_number(hi)} Hz in recording(s) {some_names(ids[rows][r == hi])}; a unit recorded at two settings "
                "is two units (give each its own sensor_instance); a logger whose rate wanders is "
                "one: import it with [rate] resample_hz = a nominal rate and its time_column "
                "(drop_repeats = true first where a slower sensor's rows repeat)",
                column="sampling_rate_hz",
            )
        out[rows] = np.median(r)
    return out


def canonical_dataset(
    recordings: pd.DataFrame,
    samples: Mapping[str, np.ndarray],
    slip_labels: Mapping[str, np.ndarray] | None,
    rec_where: str | Path,
    samples_where: str | Path,
) -> tuple[pd.DataFrame, dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Validated canonical recordings, samples and labels; cheap when they already are (no copies)."""
    rec = canonical_recordings(recordings, rec_where)
    ids = rec["recording_id"].tolist()
    out_samples: dict[str, np.ndarray] = {}
    for rid, channels, names in zip(ids, rec["n_channels"].to_numpy(), rec["channels"]):
        if rid not in samples:
            raise data_error(samples_where, "recording has no samples", rid, "recording_id")
        a = np.asarray(samples[rid])
        if a.dtype.kind in "iu":
            a = a.astype(np.float64)
        elif a.dtype == np.float16:
            a = a.astype(np.float32)
        elif a.dtype not in (np.float32, np.float64):
            raise data_error(
                samples_where, f"samples must be numbers, found dtype {a.dtype}", rid, "values"
            )
        if a.ndim != 2 or a.shape[1] != channels or len(a) < 2:
            raise data_error(
                samples_where,
                f"samples must have shape (n >= 2, {int(channels)} channels), found {a.shape}",
                rid,
                "values",
            )
        _check_magnitude(a, rid, tuple(names), samples_where)
        out_samples[rid] = a
    labels: dict[str, np.ndarray] = {}
    if slip_labels:
        unknown = set(slip_labels) - set(ids)
        if unknown:
            raise data_error(
                samples_where,
                f"labels of a recording not listed in {RECORDINGS_FILE}",
                sorted(unknown)[0],
                "slip",
            )
        for rid in ids:
            labels[rid] = _canonical_labels(
                slip_labels.get(rid), len(out_samples[rid]), rid, samples_where
            )
    for rid, scenario in zip(ids, rec["scenario"]):
        if scenario == "hold-slip":
            _check_onset(labels.get(rid), rid, samples_where)
    rec["n_samples"] = np.array([len(out_samples[rid]) for rid in ids], np.int64)
    rec[SLIPS] = [
        scenario == "slip" or (rid in labels and bool((labels[rid] == 1).any()))
        for rid, scenario in zip(ids, rec["scenario"])
    ]
    return rec, out_samples, labels


def _check_magnitude(a: np.ndarray, rid: str, channels: tuple[str, ...], where) -> None:
    """Refuse a non-finite sample, or one beyond MAX_MAGNITUDE, naming where it is and its
    value: two reductions without a copy, the search only where one fails."""
    if -MAX_MAGNITUDE <= a.min() and a.max() <= MAX_MAGNITUDE:  # NaN fails both
        return
    bad = ~(np.abs(a) <= MAX_MAGNITUDE)
    sample, channel = np.unravel_index(int(np.argmax(bad)), a.shape)
    value = float(a[sample, channel])
    where_ = f"sample {sample}, channel {channels[channel]!r}"
    raise data_error(
        where,
        f"non-finite value {value} (NaN or infinity) at {where_}"
        if not np.isfinite(value)
        else f"value {value:.6g} at {where_} is beyond {MAX_MAGNITUDE:.2g} in magnitude, where a "
        "detector's arithmetic overflows; rescale the recording (e.g. to other units)",
        rid,
        "values",
    )


def _canonical_labels(labels, n: int, rid: str, where) -> np.ndarray:
    if labels is None:
        return np.full(n, -1, np.int8)
    a = np.asarray(labels)
    if a.dtype == bool:
        a = a.astype(np.int8)
    elif a.dtype.kind not in "iu" or a.ndim != 1 or (len(a) and (a.min() < -1 or a.max() > 1)):
        raise data_error(
            where,
            f"labels must be bool, or int with -1 unlabelled, 0 no slip, 1 slip; found dtype {a.dtype}",
            rid,
            "slip",
        )
    if a.shape != (n,):
        raise data_error(
            where, f"{a.shape[0] if a.ndim else 0} labels for {n} samples", rid, "slip"
        )
    return a.astype(np.int8, copy=False)


def _check_onset(labels: np.ndarray | None, rid: str, where) -> None:
    """A hold-slip recording holds (labelled 0) and then may slip (labelled 1) from a known
    sample; a trial that held throughout (no onset) is kept: it is non-slip time."""
    if labels is None:
        raise data_error(
            where,
            "a hold-slip recording needs per-sample labels (a slip column) to give its onset",
            rid,
            "slip",
        )
    slipping = np.flatnonzero(labels == 1)
    before = labels[: slipping[0]] if len(slipping) else labels
    if not (before == 0).any():
        raise data_error(
            where,
            "a hold-slip recording has no sample labelled no-slip before its onset: no hold "
            "(one that starts in slip: cut or unlabel (-1) its samples before its hold, as the "
            "CSV importer's [labels] leading_slip does)",
            rid,
            "slip",
        )


def names_univariate_channels(recordings: pd.DataFrame) -> bool:
    """Whether a canonical recordings table names univariate channels for any recording: only
    then is the column hashed and written, so that a dataset without it keeps its fingerprint."""
    name = UNIVARIATE_CHANNELS.name
    return name in recordings.columns and any(len(v) for v in recordings[name])


def plain_value(v: Any) -> Any:
    """A canonical metadata value as plain JSON (and Arrow): str, float, None, list of str."""
    if isinstance(v, tuple):
        return list(v)
    if isinstance(v, (float, np.floating)):
        return None if np.isnan(v) else float(v)
    return None if is_null(v) else v
