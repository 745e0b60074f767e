"""The mapping of a lab's CSV files (TOML, documented with a full example in ``datasets.md``):
parsed and checked (:func:`load_mapping`), then applied to one file's path to give its
metadata (:func:`file_fields`): ``[recording]``, then each ``[[rules]]`` that selects the file,
templates filled from path parts and named regex groups, values mapped, numbers parsed."""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import tomllib

from slipbench.data.importers.metadata import MetadataReader, MetadataTable, parse_metadata
from slipbench.data.importers.paths import check_relative, escapes
from slipbench.errors import TOO_DEEP, DataError, UsageError
from slipbench.vocabulary import SENSOR_TYPE

FIELDS = (
    "recording_id",
    SENSOR_TYPE,
    "sensor_instance",
    "scenario",
    "material",
    "speed_mm_s",
    "source",
    "trial",
    "sampling_rate_hz",
    "slip_onset",
    "slip_offset",
    "after_offset",  # per file, overriding [labels]
    "unlisted",
    "leading_slip",
)
NUMERIC_FIELDS = ("speed_mm_s", "sampling_rate_hz", "slip_onset", "slip_offset")
TOP_KEYS = {
    "files",
    "delimiter",
    "comment",
    "skip_rows",
    "recording",
    "rules",
    "map",
    "channels",
    "rate",
    "labels",
    "metadata",
}
CHANNEL_KEYS = {"names", "pattern", "count", "units", "sensor_instance", SENSOR_TYPE}
RATE_KEYS = {"hz", "time_column", "time_unit", "drop_repeats", "resample_hz"}
LABEL_KEYS = {
    "column",
    "slip",
    "no_slip",
    "unlabelled",
    "segments",
    "unit",
    "after_offset",
    "unlisted",
    "leading_slip",
}
# What [labels] after_offset, unlisted and leading_slip (or a file's own fields of those names)
# may say; the first is the default
LABEL_CHOICES = {
    "after_offset": ("no-slip", "unlabelled"),
    "unlisted": ("unlabelled", "no-slip"),
    # a hold-slip trial whose labels start in slip: refused, its leading rows dropped, or kept
    # unlabelled (-1)
    "leading_slip": ("refuse", "trim", "unlabelled"),
}
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
GLOBS_STAY = "a glob selects files under SRC: no '..', no absolute path"


@dataclass(frozen=True)
class Rule:
    """Fields for the files a glob and/or a regex (on the path relative to SRC) select."""

    name: str
    glob: str | None
    regex: re.Pattern | None
    fields: dict[str, Any]


@dataclass(frozen=True)
class CsvFile:
    """One CSV file being imported: its path (and the path relative to the mapping's root),
    the fields its metadata and rules give it, its table, its sampling rate and, with a time
    column, the time of each row (s)."""

    path: Path
    rel: str
    fields: dict
    frame: Any  # a pandas DataFrame (pandas stays out of the mapping's imports)
    rate: float
    times: Any = None  # np.ndarray | None
    variables: dict[str, str] = field(default_factory=dict)  # what its templates may name


@dataclass(frozen=True)
class CsvMapping:
    """A parsed, checked mapping file."""

    where: str
    files: tuple[str, ...]
    csv: dict[str, Any]
    recording: Rule
    rules: tuple[Rule, ...]
    maps: dict[str, dict[str, Any]]
    channels: tuple[dict[str, Any], ...]
    rate: dict[str, Any]
    labels: dict[str, Any]
    base: Path
    metadata: tuple[MetadataTable, ...] = ()
    #: folders beyond SRC and ``base`` its paths may lead into; None: a card's, never
    outside: tuple[Path, ...] | None = ()


def _bad(where: str, what: str) -> UsageError:
    return UsageError(f"{where}: {what}")


def _keys(table: Any, known: set[str], where: str, section: str) -> dict:
    if not isinstance(table, dict):
        raise _bad(where, f"{section} must be a table")
    unknown = sorted(set(table) - known)
    if unknown:
        raise _bad(
            where, f"unknown key {unknown[0]!r} in {section} (known: {', '.join(sorted(known))})"
        )
    return table


def _regex(text: Any, where: str, section: str) -> re.Pattern | None:
    if text is None:
        return None
    if not isinstance(text, str):
        raise _bad(where, f"{section}.regex must be a string")
    try:
        return re.compile(text)
    except re.error as exc:
        raise _bad(where, f"{section}.regex {text!r} is not a regular expression ({exc})") from None


def _rule(table: Any, where: str, section: str, selector: bool) -> Rule:
    table = _keys(
        table, set(FIELDS) | {"regex"} | ({"glob"} if selector else set()), where, section
    )
    glob = table.get("glob")
    if glob is not None and not isinstance(glob, str):
        raise _bad(where, f"{section}.glob must be a string")
    if glob is not None and escapes(glob):
        raise _bad(where, f"{section}.glob = {glob!r}: {GLOBS_STAY}")
    if selector and glob is None and "regex" not in table:
        raise _bad(where, f"{section} needs a glob or a regex saying which files it applies to")
    fields = {k: v for k, v in table.items() if k in FIELDS}
    for key, value in fields.items():
        if not isinstance(value, (str, int, float)) or isinstance(value, bool):
            raise _bad(where, f"{section}.{key} must be a string or a number, got {value!r}")
    return Rule(section, glob, _regex(table.get("regex"), where, section), fields)


def load_mapping(
    config: str | Path | Mapping,
    base: Path | None = None,
    outside: Sequence[Path] | None = (),
    where: str | None = None,
) -> CsvMapping:
    """Parse and check a mapping: a TOML file, or the same structure as a dict.

    ``base`` is the folder relative paths in the mapping (a segments table) start from: the
    mapping file's folder, or the working folder for a dict. ``outside``: folders beyond SRC
    and ``base`` its paths may lead into (``dataset import csv --read-outside``); None for a
    card's mapping, which never may (see :mod:`~slipbench.data.importers.paths`). ``where``
    names the mapping in messages [default: its file, or "mapping"].
    """
    if isinstance(config, Mapping):
        raw, base = dict(config), Path(base or ".")
        where = where or "mapping"
    else:
        path = Path(config)
        where = where or str(path)
        try:
            raw = tomllib.loads(path.read_text(encoding="utf-8"))
        except OSError as exc:
            raise UsageError(f"{path}: cannot read the mapping ({exc.strerror or exc})") from None
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise UsageError(f"{path}: not valid TOML ({exc})") from None
        except RecursionError:
            raise UsageError(f"{path}: {TOO_DEEP}") from None
        base = Path(base) if base else path.parent
    outside = None if outside is None else tuple(Path(f) for f in outside)
    _keys(raw, TOP_KEYS, where, "the mapping")
    files, csv = _files(raw, where), _csv(raw, where)
    recording = _rule(raw.get("recording", {}), where, "[recording]", selector=False)
    rules = raw.get("rules", [])
    if not isinstance(rules, list):
        raise _bad(where, "rules must be an array of tables: [[rules]]")
    rules = tuple(
        _rule(r, where, f"[[rules]] #{i + 1}", selector=True) for i, r in enumerate(rules)
    )
    maps, channels, rate = _maps(raw, where), _channels(raw, where), _rate(raw, where)
    labels = _labels(raw, where, outside)
    metadata = parse_metadata(raw.get("metadata", []), where, FIELDS)
    for entry in metadata:
        check_relative(entry.table, f"{where}: {entry.name}.table = {entry.table!r}", outside)
    return CsvMapping(
        where, files, csv, recording, rules, maps, channels, rate, labels, base, metadata, outside
    )


def _files(raw: dict, where: str) -> tuple[str, ...]:
    files = raw.get("files", "**/*.csv")
    files = (files,) if isinstance(files, str) else files
    if (
        not isinstance(files, (list, tuple))
        or not files
        or not all(isinstance(f, str) for f in files)
    ):
        raise _bad(
            where, 'files must be a glob or a list of globs relative to SRC, e.g. "**/*.csv"'
        )
    for glob in files:
        if escapes(glob):
            raise _bad(where, f"files = {glob!r}: {GLOBS_STAY}")
    return tuple(files)


def _csv(raw: dict, where: str) -> dict[str, Any]:
    csv = {
        "delimiter": raw.get("delimiter", ","),
        "comment": raw.get("comment"),
        "skip_rows": raw.get("skip_rows", 0),
    }
    if not isinstance(csv["delimiter"], str) or len(csv["delimiter"]) != 1:
        raise _bad(where, f"delimiter must be one character, got {csv['delimiter']!r}")
    if csv["comment"] is not None and (
        not isinstance(csv["comment"], str) or len(csv["comment"]) != 1
    ):
        raise _bad(where, f"comment must be one character, got {csv['comment']!r}")
    if (
        not isinstance(csv["skip_rows"], int)
        or isinstance(csv["skip_rows"], bool)
        or csv["skip_rows"] < 0
    ):
        raise _bad(where, f"skip_rows must be an int >= 0, got {csv['skip_rows']!r}")
    return csv


def _maps(raw: dict, where: str) -> dict[str, dict[str, Any]]:
    maps = _keys(raw.get("map", {}), set(FIELDS), where, "[map]")
    for key, table in maps.items():
        if not isinstance(table, dict):
            raise _bad(where, f"[map.{key}] must be a table of old = new values")
    return maps


def _channels(raw: dict, where: str) -> tuple[dict[str, Any], ...]:
    channels = raw.get("channels")
    if channels is None:
        raise _bad(where, '[channels] is missing: give names = [...] or pattern = "..."')
    groups = tuple(channels) if isinstance(channels, list) else (channels,)
    return tuple(_channel_group(g, where, i, len(groups)) for i, g in enumerate(groups))


def _channel_group(group: Any, where: str, i: int, n: int) -> dict[str, Any]:
    section = "[channels]" if n == 1 else f"[[channels]] #{i + 1}"
    _keys(group, CHANNEL_KEYS, where, section)
    if ("names" in group) == ("pattern" in group):
        raise _bad(where, f'{section} needs exactly one of names = [...] or pattern = "..."')
    if "names" in group and (
        not isinstance(group["names"], list)
        or not group["names"]
        or not all(isinstance(n, str) for n in group["names"])
    ):
        raise _bad(where, f"{section}.names must be a non-empty list of column names")
    if n > 1 and "sensor_instance" not in group:
        raise _bad(
            where, f"{section} needs sensor_instance: several channel groups are several units"
        )
    if "pattern" in group:
        return {**group, "pattern": _regex(group["pattern"], where, section)}
    return group


def _rate(raw: dict, where: str) -> dict[str, Any]:
    rate = _keys(raw.get("rate", {}), RATE_KEYS, where, "[rate]")
    for key in ("hz", "resample_hz"):
        if key in rate and (
            isinstance(rate[key], bool)
            or not isinstance(rate[key], (int, float))
            or not rate[key] > 0
        ):
            raise _bad(where, f"[rate].{key} must be a number > 0, got {rate[key]!r}")
    if not isinstance(rate.get("drop_repeats", False), bool):
        raise _bad(
            where, f"[rate].drop_repeats must be true or false, got {rate['drop_repeats']!r}"
        )
    if "resample_hz" in rate and "time_column" not in rate:
        raise _bad(
            where,
            "[rate].resample_hz needs a time_column: each file's rows are interpolated at their times",
        )
    if rate.get("time_unit", "s") not in TIME_UNITS:
        raise _bad(
            where,
            f"[rate].time_unit must be one of {', '.join(TIME_UNITS)}, got {rate['time_unit']!r}",
        )
    return rate


def _labels(raw: dict, where: str, outside: tuple[Path, ...] | None) -> dict[str, Any]:
    labels = _keys(raw.get("labels", {}), LABEL_KEYS, where, "[labels]")
    if "column" in labels and "segments" in labels:
        raise _bad(where, "[labels] takes a column or segments, not both")
    if "column" in labels and not labels.get("slip"):
        raise _bad(where, "[labels].column needs slip = [...]: the values that mean slip")
    for key in ("slip", "no_slip", "unlabelled"):
        value = labels.get(key, [])
        if not isinstance(value, list) or not all(
            isinstance(v, (str, int)) and not isinstance(v, bool) for v in value
        ):
            raise _bad(
                where,
                f"[labels].{key} must be a list of values as written in the files (strings or integers)",
            )
    for key, allowed in (("unit", ("sample", "s")), *LABEL_CHOICES.items()):
        if key in labels and labels[key] not in allowed:
            raise _bad(
                where, f"[labels].{key} must be one of {', '.join(allowed)}, got {labels[key]!r}"
            )
    if isinstance(labels.get("segments"), str):
        segments = labels["segments"]
        check_relative(segments, f"{where}: [labels].segments = {segments!r}", outside)
    return labels


def file_fields(
    m: CsvMapping, rel: str, selected: list[set[str]], metadata: MetadataReader | None = None
) -> dict[str, Any]:
    """The resolved metadata of one file: [recording], then each rule that selects it, in order;
    templates filled from path parts and named regex groups; then the fields its
    [[metadata]] tables give (as written there, not templates); values mapped; numbers parsed."""
    fields, variables = _resolved(m, rel, selected)

    def fill(value: str, key: str) -> str:
        return fill_template(m, rel, variables, value, key)

    fields = {k: fill(v, k) if isinstance(v, str) else v for k, v in fields.items()}
    if metadata is not None:
        for entry in m.metadata:
            fields.update(metadata.fields(entry, rel, fill))
    out: dict[str, Any] = {}
    for key, value in fields.items():
        value = m.maps.get(key, {}).get(value, value)
        if key in NUMERIC_FIELDS:
            value = _number(value, rel, key)
        out[key] = value
    return out


def file_variables(m: CsvMapping, rel: str, selected: list[set[str]]) -> dict[str, str]:
    """What a template may name for one file: its path parts and the named groups of the
    regexes of [recording] and the rules that select it."""
    return _resolved(m, rel, selected)[1]


def fill_template(m: CsvMapping, rel: str, variables: dict[str, str], value: str, key: str) -> str:
    """``value`` with its templates filled from ``variables``; UsageError naming the key and
    the names it may use where it names another."""
    try:
        return value.format_map(variables)
    except (KeyError, IndexError, ValueError) as exc:
        raise UsageError(
            f"{m.where}: {key} = {value!r}: no value for {exc} in {rel} (known: {', '.join(sorted(variables))})"
        ) from None


def _resolved(
    m: CsvMapping, rel: str, selected: list[set[str]]
) -> tuple[dict[str, Any], dict[str, str]]:
    """A file's fields as [recording] and its rules give them (templates unfilled), and the
    variables its templates may name."""
    parts = rel.rsplit("/", 1)
    variables = {
        "path": default_id(rel),
        "name": parts[-1],
        "stem": Path(parts[-1]).stem,
        "parent": parts[0] if len(parts) == 2 else "",
        "file": rel,
    }
    fields: dict[str, Any] = {}
    for rule, chosen in [(m.recording, None)] + list(zip(m.rules, selected)):
        if chosen is not None and rel not in chosen:
            continue
        if rule.regex is not None:
            match = rule.regex.fullmatch(rel)
            if match is None:
                if chosen is None:
                    raise DataError(
                        f"{rel}: the path does not match {rule.name}.regex {rule.regex.pattern!r} (paths are relative to SRC, with /)"
                    )
                continue
            groups = {k: v for k, v in match.groupdict().items() if v is not None}
            variables.update(groups)
            fields.update({k: v for k, v in groups.items() if k in FIELDS})
        fields.update(rule.fields)
    return fields, variables


def _number(value: Any, rel: str, key: str) -> float | None:
    if isinstance(value, str):
        if value.strip().lower() in ("", "none", "null", "nan"):
            return None
        try:
            return float(value)
        except ValueError:
            raise DataError(f"{rel}: {key} = {value!r} is not a number") from None
    return float(value)


def default_id(rel: str) -> str:
    """The default recording id of a file: its path relative to SRC without the extension."""
    head, _, name = rel.rpartition("/")
    stem = name.rsplit(".", 1)[0] if "." in name else name
    return f"{head}/{stem}" if head else stem
