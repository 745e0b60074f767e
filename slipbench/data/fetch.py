"""Fetching a published dataset by its card: download every file into slipbench's cache, each
checked against the card's SHA-256 (:mod:`slipbench.data.download`), then convert them with the
card's importer and record source and citation in the dataset's metadata.

Resumable means: each file is written to a hidden temporary name and takes its own name only
once its SHA-256 matches, so the cache holds only whole, verified files; a rerun after an
interrupted download (Ctrl-C, a lost connection, a stalled server) downloads only the files
missing there or failing their hash, and a second fetch downloads nothing.

Nothing is left behind: a failure (a stall, a wrong hash, an HTTP error, Ctrl-C) removes the
temporary files, and the folder the importer reads is removed when it ends. A process killed
by SIGKILL cannot clean up: the next fetch of the card removes what it left, under the card's
lock (held for the whole fetch, so what it finds there belongs to no live fetch).
"""

from __future__ import annotations

import json
import os
import shutil
import threading
import time
import urllib.error
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

from slipbench.atomic import check_writable, folder_lock, make_folder, unique_folder
from slipbench.data import download
from slipbench.data.card import Card, CardFile, sha256_of, with_slash
from slipbench.data.defaults import cache_dir
from slipbench.data.download import MIN_RATE, Cancelled, Mismatch, Stalled, deadline
from slipbench.data.schema import CITATION_KEY, SOURCE_KEY
from slipbench.errors import DataError, EnvironmentFault

#: parallel downloads: a card lists hundreds of small files
WORKERS = 8
#: more tries per file after a dropped connection, 1 s apart
RETRIES = 1
#: seconds a download stopped by Ctrl-C may take to remove its temporary file itself
GRACE_S = 1.0
CACHE_HINT = "set SLIPBENCH_CACHE (or, on Linux, XDG_CACHE_HOME) to a writable folder"


def card_cache(card: Card) -> Path:
    """Where the card's files are kept once verified: one folder per card; any URL (a mirror)
    fills the same folder, since the hashes say the files are the same."""
    return cache_dir() / "datasets" / card.name


def fetch(
    card: Card,
    out: str | Path,
    url: str | None = None,
    echo: Callable[[str], None] | None = None,
    min_rate: float = MIN_RATE,
) -> Path:
    """Download (or find in the cache) the card's files from ``url`` (default: the card's
    ``base_url``), then import them into the new dataset folder ``out``.

    Each file must arrive within ``deadline(size, min_rate)`` seconds: WAIT_S (30 s) plus its
    size at ``min_rate`` bytes per second; lower ``min_rate`` on a slow link.

    Raises
    ------
    DataError : ``out`` exists and is not empty; a file's SHA-256 differs from the card's (the
        message names the file and both hashes); the importer refuses the files.
    EnvironmentFault : ``out`` or the cache cannot be written (found before any download); no
        connection, an HTTP error or a stalled server (the URL named).

    Nothing is written to ``out`` unless every file is verified and the import succeeds.
    """
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise DataError(f"{out}: already exists and is not empty; choose a new folder")
    check_writable(out)
    folder = card_cache(card)
    base = with_slash(url or card.base_url)
    say = echo or (lambda _: None)
    with _cache_faults():
        check_writable(folder)
        make_folder(folder)
    with folder_lock(folder):
        _remove_leftovers(card, folder)
        missing, damaged = _not_verified(card, folder)
        say(_plan(card, folder, base, missing, damaged))
        _download(card, base, folder, missing + damaged, min_rate)
        say(f"{card.name}: every file matches its SHA-256; converting with {_importer_name(card)}")
        with _staged(card, folder) as src:
            _convert(card, src, out, _description(card, base))
    return out


@contextmanager
def _cache_faults() -> Iterator[None]:
    """An unwritable cache says how to choose another."""
    try:
        yield
    except EnvironmentFault as fault:
        raise EnvironmentFault(fault.path, fault.cause, fault.action, CACHE_HINT) from None


def _not_verified(card: Card, folder: Path) -> tuple[list[CardFile], list[CardFile]]:
    """The card's files missing from the cache, and those there whose SHA-256 differs (a
    damaged cache, or a file the card has since changed)."""
    missing = [f for f in card.files if not (folder / f.path).is_file()]
    damaged = [
        f
        for f in card.files
        if (folder / f.path).is_file() and sha256_of(folder / f.path) != f.sha256
    ]
    return missing, damaged


def _plan(
    card: Card, folder: Path, base: str, missing: list[CardFile], damaged: list[CardFile]
) -> str:
    """What the fetch finds in the cache and what it downloads, and why."""
    head = f"{card.name}: {len(card.files)} files, {card.size / 1e6:.1f} MB"
    verified = len(card.files) - len(missing) - len(damaged)
    if not missing and not damaged:
        return f"{head}; all {verified} verified in {folder}: nothing to download"
    why = [f"{len(missing)} missing"] if missing else []
    if damaged:
        shown = ", ".join(f.path for f in damaged[:3]) + (" ..." if len(damaged) > 3 else "")
        why.append(f"{len(damaged)} in the cache failing their SHA-256 ({shown}), replaced")
    return (
        f"{head}; {verified} verified in {folder}; downloading {len(missing) + len(damaged)} "
        f"from {base}: {', '.join(why)}"
    )


def _download(card: Card, base: str, folder: Path, files: list[CardFile], min_rate: float) -> None:
    """``files`` into ``folder``, verified, WORKERS at a time; stops at the first failure and
    raises it (in the card's order). On Ctrl-C, the downloads stop and their temporary files
    are removed before KeyboardInterrupt goes on."""
    pending, errors = list(reversed(files)), {}
    take, stop = threading.Lock(), threading.Event()

    def work() -> None:
        while not stop.is_set():
            with take:
                if not pending:
                    return
                f = pending.pop()
            try:
                _one(base + f.path, f, folder, deadline(f.size, min_rate), stop)
            except Cancelled:
                return
            except BaseException as exc:  # reported in the card's order, below
                errors[f.path] = exc
                stop.set()

    # daemon threads: Ctrl-C must not wait for a stalled server's socket to time out
    threads = [threading.Thread(target=work, daemon=True) for _ in range(WORKERS)]
    for t in threads:
        t.start()
    try:
        for t in threads:
            while t.is_alive():
                t.join(0.1)  # a short wait: Ctrl-C reaches this thread between waits
    except BaseException:
        stop.set()
        until = time.monotonic() + GRACE_S
        for t in threads:
            t.join(max(0.0, until - time.monotonic()))
        _remove_leftovers(card, folder)
        raise
    for f in card.files:
        if f.path in errors:
            raise _explain(errors[f.path], card, f, base, min_rate)


def _one(url: str, f: CardFile, folder: Path, seconds: float, stop: threading.Event) -> None:
    for attempt in range(1 + RETRIES):
        try:
            return download.download_file(url, f, folder, seconds, stop)
        except urllib.error.HTTPError:
            raise
        except (urllib.error.URLError, ConnectionError):  # a dropped connection: once more
            if attempt == RETRIES or stop.is_set():
                raise
            time.sleep(1)


def _explain(
    exc: BaseException, card: Card, f: CardFile, base: str, min_rate: float
) -> BaseException:
    """The slipbench error a download failure stands for; anything unforeseen passes as it is."""
    url = base + f.path
    resume = (
        f"files verified so far stay in {card_cache(card)}, and a rerun downloads only the "
        "missing ones"
    )
    if isinstance(exc, Mismatch):
        got = (
            f"its SHA-256 is {exc.sha256}, but the card ({card.where}) says {f.sha256}"
            if exc.sha256
            else f"more than the {f.size} bytes the card ({card.where}) gives"
        )
        return DataError(
            f"{f.path}: downloaded from {url}, {got}: the file was changed at the source or "
            "damaged on the way; it was not kept, and nothing was written"
        )
    if isinstance(exc, Stalled):
        said = (
            f"no byte for {download.WAIT_S:g} s after {exc.received} of {f.size} bytes"
            if exc.idle
            else f"{exc.received} of {f.size} bytes in {exc.seconds:.1f} s"
        )
        return EnvironmentFault(
            url,
            f"the server stalled: {said}",
            "download",
            f"a file may take {download.WAIT_S:g} s plus its size at --min-rate "
            f"({min_rate / 1e3:g} kB/s), here {deadline(f.size, min_rate):.3g} s: on a slow "
            f"link lower --min-rate, or pass --url with a mirror of {card.base_url}; {resume}",
        )
    if isinstance(exc, urllib.error.HTTPError):
        return EnvironmentFault(
            url,
            f"the server answered {exc.code} {exc.reason}",
            "download",
            f"check the URL (--url replaces the card's {card.base_url}); {resume}",
        )
    if isinstance(exc, (urllib.error.URLError, ConnectionError)):
        why = exc.reason if isinstance(exc, urllib.error.URLError) else exc
        return EnvironmentFault(
            url,
            f"no connection ({why})",
            "download",
            f"check the network, or pass --url with a mirror of {card.base_url}; {resume}",
        )
    if isinstance(exc, EnvironmentFault):  # the cache: full, read-only
        return EnvironmentFault(exc.path, exc.cause, exc.action, CACHE_HINT)
    return exc


def _remove_leftovers(card: Card, folder: Path) -> None:
    """What an interrupted or killed fetch of this card left: temporary files of downloads,
    and folders staged for the importer. Called under the card's lock (or by the fetch that
    made them), so none belongs to a live fetch."""
    listed = {f.path for f in card.files}
    for path in folder.rglob(".*.tmp"):
        if (
            download.PARTIAL.fullmatch(path.name)
            and path.relative_to(folder).as_posix() not in listed
        ):
            with suppress(FileNotFoundError):
                path.unlink()
    for staged in folder.parent.glob(f".{card.name}.staged-*"):
        shutil.rmtree(staged, ignore_errors=True)


@contextmanager
def _staged(card: Card, folder: Path) -> Iterator[Path]:
    """A folder holding exactly the card's files (links into the cache, copies where links
    fail), so that nothing else in the cache reaches the importer."""
    with _cache_faults():
        tmp = unique_folder(folder.parent, f".{card.name}.staged-")
    try:
        for f in card.files:
            target = tmp / f.path
            target.parent.mkdir(parents=True, exist_ok=True)
            try:
                os.link(folder / f.path, target)
            except OSError:
                shutil.copyfile(folder / f.path, target)
        yield tmp
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _description(card: Card, base: str) -> dict[bytes, str]:
    """Source and citation for the dataset's metadata."""
    source = {
        "card": card.name,
        "title": card.title,
        "homepage": card.homepage,
        "downloaded_from": base,
        "license": card.license,
        "files": len(card.files),
        "bytes": card.size,
    }
    return {SOURCE_KEY: json.dumps(source, sort_keys=True), CITATION_KEY: card.citation}


def _importer_name(card: Card) -> str:
    return f"importer {card.importer}" if card.importer else f"the mapping in {card.where}"


def _convert(card: Card, src: Path, out: Path, description: dict[bytes, str]) -> None:
    from slipbench.data.importers import IMPORTERS, import_csv, load_mapping

    if card.importer:
        IMPORTERS[card.importer](src, out, description=description)
    else:
        assert card.mapping is not None  # load_card requires one of the two
        mapping = load_mapping(card.mapping, src, None, f"{card.where}: [mapping]")
        import_csv(src, out, mapping, description=description)
