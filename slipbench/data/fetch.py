"""Fetching a published dataset by its card: download every file with pooch into slipbench's
cache, each checked against the card's SHA-256, then convert them with the card's importer and
record source and citation in the dataset's metadata.

Resumable means: pooch downloads each file to a temporary name in the cache and moves it into
place only once its SHA-256 matches, so the cache holds only whole, verified files; a rerun
after an interrupted download (Ctrl-C, a lost connection) downloads only the files missing
there, and a second fetch downloads nothing.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from pathlib import Path

from slipbench.data.card import Card, CardFile, sha256_of, with_slash
from slipbench.data.defaults import cache_dir
from slipbench.data.schema import CITATION_KEY, SOURCE_KEY
from slipbench.errors import DataError, EnvironmentFault, environment_fault

#: parallel downloads: a card lists hundreds of small files
WORKERS = 8
#: more tries per file after a dropped connection, 1 s apart
RETRIES = 1
TIMEOUT_S = 30
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
) -> Path:
    """Download (or find in the cache) the card's files from ``url`` (default: the card's
    ``base_url``), then import them into the new dataset folder ``out``.

    Raises
    ------
    DataError : ``out`` exists and is not empty; a file's SHA-256 differs from the card's (the
        message names the file and both hashes); the importer refuses the files.
    EnvironmentFault : no connection, an HTTP error (the URL named), an unwritable cache.

    Nothing is written to ``out`` unless every file is verified and the import succeeds.
    """
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise DataError(f"{out}: already exists and is not empty; choose a new folder")
    base = with_slash(url or card.base_url)
    folder = card_cache(card)
    say = echo or (lambda _: None)
    cached = sum((folder / f.path).is_file() for f in card.files)
    rest = (
        f"downloading the rest from {base}" if cached < len(card.files) else "nothing to download"
    )
    say(
        f"{card.name}: {len(card.files)} files, {card.size / 1e6:.1f} MB; {cached} already in "
        f"{folder}, {rest}"
    )
    download(card, base, folder)
    say(f"{card.name}: every file matches its SHA-256; converting with {_importer_name(card)}")
    description = {
        SOURCE_KEY: json.dumps(
            {
                "card": card.name,
                "title": card.title,
                "homepage": card.homepage,
                "downloaded_from": base,
                "license": card.license,
                "files": len(card.files),
                "bytes": card.size,
            },
            sort_keys=True,
        ),
        CITATION_KEY: card.citation,
    }
    with _staged(card, folder) as src:
        _convert(card, src, out, description)
    return out


def download(card: Card, base: str, folder: Path) -> None:
    """Every file of the card into ``folder``, verified; files already there with the right
    hash are kept. Stops at the first failure (the others' downloads finish or are skipped)."""
    import pooch
    import requests

    recorder = _Recorder()
    store = pooch.create(
        path=folder, base_url=base, registry={f.path: f"sha256:{f.sha256}" for f in card.files}
    )
    stop = threading.Event()
    # pooch makes a file's folder when it finds it missing: two threads finding it missing at
    # once race (FileExistsError), so every folder is made before any download starts
    for f in card.files:
        (folder / f.path).parent.mkdir(parents=True, exist_ok=True)

    def one(f: CardFile) -> BaseException | None:
        for attempt in range(1 + RETRIES):
            if stop.is_set():
                return None
            try:
                store.fetch(f.path, downloader=recorder)
                return None
            except (requests.ConnectionError, requests.Timeout) as exc:
                if attempt == RETRIES:
                    stop.set()
                    return exc
                time.sleep(1)  # a dropped connection; a wrong hash or a 404 is not retried
            except BaseException as exc:  # reported in file order below, the first one raised
                stop.set()
                return exc
        return None

    with _quiet_pooch():
        with ThreadPoolExecutor(WORKERS) as pool:
            try:
                errors = list(pool.map(one, card.files))
            except BaseException:  # Ctrl-C: queued files are skipped, not waited for
                stop.set()
                raise
    for f, exc in zip(card.files, errors):
        if exc is not None:
            raise _explain(exc, card, f, store.get_url(f.path), folder, recorder) from None


class _Recorder:
    """pooch's own downloader for the URL, plus the SHA-256 of what arrived: a mismatch message
    gives both hashes (pooch deletes the temporary file before it raises)."""

    def __init__(self) -> None:
        self.got: dict[str, str] = {}

    def __call__(self, url, output_file, pooch, check_only=False):
        from pooch.downloaders import choose_downloader

        downloader = choose_downloader(url)
        if hasattr(downloader, "kwargs"):  # HTTP and DOI; FTP has its own timeout
            downloader.kwargs.setdefault("timeout", TIMEOUT_S)
        result = downloader(url, output_file, pooch, check_only=check_only)
        if not check_only:
            self.got[url] = sha256_of(output_file)
        return result


def _explain(
    exc: BaseException, card: Card, f: CardFile, url: str, folder: Path, recorder: _Recorder
) -> BaseException:
    """The slipbench error a download failure stands for; anything unforeseen passes as it is."""
    import requests

    resume = f"files verified so far stay in {folder}, and a rerun downloads only the missing ones"
    if isinstance(exc, ValueError) and url in recorder.got:
        return DataError(
            f"{f.path}: downloaded from {url}, its SHA-256 is {recorder.got[url]}, but the card "
            f"({card.where}) says {f.sha256}: the file was changed at the source or damaged on "
            f"the way; it was not kept, and nothing was written"
        )
    if isinstance(exc, requests.HTTPError) and exc.response is not None:
        r = exc.response
        return EnvironmentFault(
            url,
            f"the server answered {r.status_code} {r.reason}",
            "download",
            f"check the URL (--url replaces the card's {card.base_url}); {resume}",
        )
    if isinstance(exc, requests.RequestException):
        return EnvironmentFault(
            url,
            f"no connection ({type(exc).__name__})",
            "download",
            f"check the network, or pass --url with a mirror of {card.base_url}; {resume}",
        )
    if isinstance(exc, OSError):
        try:
            fault = environment_fault(exc, folder)
        except OSError:
            return exc
        return EnvironmentFault(fault.path, fault.cause, fault.action, CACHE_HINT)
    return exc


@contextmanager
def _quiet_pooch() -> Iterator[None]:
    """pooch logs a line per file (hundreds); slipbench says what happens in its own lines."""
    import pooch

    logger = pooch.get_logger()
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(level)


@contextmanager
def _staged(card: Card, folder: Path) -> Iterator[Path]:
    """A folder holding exactly the card's files (links into the cache, copies where links
    fail), so that nothing else in the cache reaches the importer."""
    tmp = Path(tempfile.mkdtemp(prefix=f".{card.name}.staged-", dir=folder.parent))
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


def _importer_name(card: Card) -> str:
    return f"importer {card.importer}" if card.importer else f"the mapping in {card.where}"


def _convert(card: Card, src: Path, out: Path, description: dict[bytes, str]) -> None:
    from slipbench.data.importers import IMPORTERS, import_csv

    if card.importer:
        IMPORTERS[card.importer](src, out, description=description)
    else:
        assert card.mapping is not None  # load_card requires one of the two
        import_csv(src, out, card.mapping, base=src, description=description)
