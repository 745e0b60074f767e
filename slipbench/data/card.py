"""Dataset cards: a small TOML file that says where a published dataset lives (base URL, each
file with its SHA-256 and size), what it is (title, citation, license, homepage) and how it
becomes a slipbench dataset (a built-in importer, or a CSV mapping inline). The built-in cards
ship in ``slipbench/data/cards/``; ``datasets.md`` documents the format for labs.
"""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

import tomllib

from slipbench.errors import TOO_DEEP, UsageError

CARDS_DIR = Path(__file__).with_name("cards")
NAME = re.compile(r"[a-z0-9][a-z0-9._-]*")
SHA256 = re.compile(r"[0-9a-f]{64}")
REQUIRED = ("name", "title", "citation", "license", "homepage", "base_url", "files")
KEYS = frozenset(REQUIRED) | {"importer", "mapping", "description"}
FILE_KEYS = frozenset({"path", "sha256", "size"})


@dataclass(frozen=True)
class CardFile:
    """One published file: its path below the base URL, SHA-256 (hex) and size in bytes."""

    path: str
    sha256: str
    size: int


@dataclass(frozen=True)
class Card:
    """A parsed, checked card; ``where`` names its file in messages."""

    name: str
    title: str
    citation: str
    license: str
    homepage: str
    base_url: str
    files: tuple[CardFile, ...]
    importer: str | None = None
    mapping: Mapping[str, Any] | None = None
    description: str = ""
    where: str = field(default="card", compare=False)

    @property
    def size(self) -> int:
        """Bytes of all its files."""
        return sum(f.size for f in self.files)


def load_card(source: str | Path, text: str | None = None) -> Card:
    """Parse and check the card at ``source`` (or ``text``, with ``source`` naming it)."""
    where = str(source)
    try:
        raw = tomllib.loads(Path(source).read_text(encoding="utf-8") if text is None else text)
    except OSError as exc:
        raise UsageError(f"{where}: cannot read the card ({exc.strerror or exc})") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise UsageError(f"{where}: not valid TOML ({exc})") from None
    except RecursionError:
        raise UsageError(f"{where}: {TOO_DEEP}") from None
    unknown = sorted(set(raw) - KEYS)
    if unknown:
        raise UsageError(f"{where}: unknown key(s) {', '.join(unknown)}; a card has {sorted(KEYS)}")
    missing = [k for k in REQUIRED if k not in raw]
    if missing:
        raise UsageError(f"{where}: missing key(s) {', '.join(missing)}")
    for key in REQUIRED[:-1] + ("description", "importer"):
        if key in raw and not (isinstance(raw[key], str) and raw[key].strip()):
            raise UsageError(f"{where}: {key} must be a non-empty string")
    if not NAME.fullmatch(raw["name"]):
        raise UsageError(
            f"{where}: name {raw['name']!r} must start with a lower-case letter or a digit, "
            "then hold only those, '.', '-' and '_'"
        )
    if not re.match(r"[a-z][a-z0-9+.-]*://", raw["base_url"]):
        raise UsageError(f"{where}: base_url {raw['base_url']!r} is not a URL (https://...)")
    if ("importer" in raw) == ("mapping" in raw):
        raise UsageError(
            f"{where}: give exactly one of importer (a built-in importer's name) or [mapping]"
        )
    if "importer" in raw:
        from slipbench.data.importers import IMPORTERS

        if raw["importer"] not in IMPORTERS:
            raise UsageError(
                f"{where}: importer {raw['importer']!r} is not built in; known: {', '.join(IMPORTERS)} "
                "(or give a CSV mapping as [mapping])"
            )
    if "mapping" in raw and not isinstance(raw["mapping"], dict):
        raise UsageError(f"{where}: mapping must be a table ([mapping], as in datasets.md)")
    if "mapping" in raw:  # before any download: a path leading out of the files is refused now
        from slipbench.data.importers import load_mapping

        load_mapping(raw["mapping"], None, None, f"{where}: [mapping]")
    return Card(
        name=raw["name"],
        title=raw["title"].strip(),
        citation=raw["citation"].strip(),
        license=raw["license"].strip(),
        homepage=raw["homepage"].strip(),
        base_url=with_slash(raw["base_url"].strip()),
        files=_files(raw["files"], where),
        importer=raw.get("importer"),
        mapping=raw.get("mapping"),
        description=raw.get("description", "").strip(),
        where=where,
    )


def _files(raw: Any, where: str) -> tuple[CardFile, ...]:
    if not isinstance(raw, list) or not raw:
        raise UsageError(f"{where}: files must be a non-empty list of {{ path, sha256, size }}")
    files, seen = [], set()
    for i, entry in enumerate(raw):
        at = f"{where}: files[{i}]"
        if not isinstance(entry, dict) or set(entry) != FILE_KEYS:
            raise UsageError(f"{at}: must be {{ path = ..., sha256 = ..., size = ... }}")
        path, sha, size = entry["path"], entry["sha256"], entry["size"]
        parts = PurePosixPath(path).parts if isinstance(path, str) else ()
        if not parts or path.startswith("/") or ".." in parts or "\\" in path:
            raise UsageError(f"{at}: path {path!r} must be relative, with / and no '..'")
        if path in seen:
            raise UsageError(f"{at}: path {path!r} is listed twice")
        if not isinstance(sha, str) or not SHA256.fullmatch(sha):
            raise UsageError(f"{at} ({path}): sha256 must be 64 lower-case hex digits")
        if not isinstance(size, int) or isinstance(size, bool) or size < 0:
            raise UsageError(f"{at} ({path}): size must be a whole number of bytes")
        seen.add(path)
        files.append(CardFile(path, sha, size))
    return tuple(files)


def with_slash(url: str) -> str:
    """A base URL that file paths append to."""
    return url if url.endswith("/") else url + "/"


def builtin_cards() -> dict[str, Card]:
    """The cards shipped with slipbench, by name."""
    cards = [load_card(p) for p in sorted(CARDS_DIR.glob("*.toml"))]
    return {c.name: c for c in cards}


def find_card(name: str) -> Card:
    """The built-in card ``name``, or the card file at path ``name`` (a ``.toml`` file: a lab
    trying its card before contributing it)."""
    if name.endswith(".toml") and Path(name).is_file():
        return load_card(name)
    cards = builtin_cards()
    if name not in cards:
        raise UsageError(
            f"no dataset card {name!r}; known: {', '.join(cards) or 'none'} "
            "(`slipbench dataset cards` lists them; a path to a .toml card works too)"
        )
    return cards[name]


def sha256_of(path: str | Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def files_block(folder: str | Path, patterns: Iterable[str] = ("**/*",)) -> str:
    """The ``files = [...]`` entries of a card for the files under ``folder`` that the glob
    ``patterns`` select (paths relative to it), each with its SHA-256 and size."""
    folder = Path(folder)
    found = sorted({p for g in patterns for p in folder.glob(g) if p.is_file()})
    if not found:
        raise UsageError(f"{folder}: no file matches {list(patterns)}")
    lines = []
    for p in found:
        path = json.dumps(p.relative_to(folder).as_posix(), ensure_ascii=False)  # TOML-safe
        lines.append(
            f'  {{ path = {path}, sha256 = "{sha256_of(p)}", size = {p.stat().st_size} }},'
        )
    return "files = [\n" + "\n".join(lines) + "\n]\n"
