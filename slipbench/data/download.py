"""One published file over HTTP into the cache: a deadline for the whole file, its SHA-256 taken
as it arrives, and a hidden temporary file that takes the file's name only once the hash matches.

Written on the standard library's ``urllib`` rather than pooch, which slipbench used before:
pooch's downloader gives each read a timeout but the file none (a server that sends a byte every
5 s never times out), and names its temporary files ``tmpXXXXXXXX``, which a killed process
leaves in the cache where nothing can tell them from data. Here the temporary files are
:func:`slipbench.atomic.atomic_file`'s ``.NAME.<hex>.tmp`` (:data:`PARTIAL`), so a later fetch
finds and removes what a killed one left.
"""

from __future__ import annotations

import hashlib
import http.client
import re
import threading
import time
import urllib.request
from pathlib import Path

from slipbench.atomic import atomic_file
from slipbench.data.card import CardFile

#: bytes per second: the slowest transfer accepted by default (a very slow link, or one shared
#: by the parallel downloads); ``dataset fetch --min-rate`` lowers it
MIN_RATE = 10_000.0
#: seconds: the deadline's floor, and the longest wait for any one byte
WAIT_S = 30.0
CHUNK = 1 << 16
#: the name atomic_file gives a file being written (``.NAME.<12 hex>.tmp``)
PARTIAL = re.compile(r"\..+\.[0-9a-f]{12}\.tmp")


def deadline(size: int, min_rate: float = MIN_RATE) -> float:
    """Seconds a file of ``size`` bytes may take: WAIT_S, plus its size at ``min_rate``."""
    return WAIT_S + size / min_rate


class Stalled(Exception):
    """The server sent too slowly: no byte for WAIT_S (``idle``), or the file missed its
    deadline."""

    def __init__(self, received: int, seconds: float, idle: bool) -> None:
        super().__init__(f"{received} bytes in {seconds:.1f} s")
        self.received, self.seconds, self.idle = received, seconds, idle


class Mismatch(Exception):
    """What arrived is not the file the card lists: another SHA-256, or more bytes."""

    def __init__(self, sha256: str | None, received: int) -> None:
        super().__init__(f"{received} bytes, SHA-256 {sha256}")
        self.sha256, self.received = sha256, received


class Cancelled(Exception):
    """The download was stopped from outside (another file failed, or Ctrl-C)."""


def download_file(
    url: str, file: CardFile, folder: Path, seconds: float, stop: threading.Event
) -> None:
    """Download ``url`` to ``folder / file.path`` if what arrives has the file's SHA-256, within
    ``seconds``; otherwise raise (Stalled, Mismatch, Cancelled; urllib's errors; ConnectionError
    for a connection lost on the way) and leave no file behind: the target is replaced only by
    a verified file."""
    start = time.monotonic()
    digest, received = hashlib.sha256(), 0
    with urllib.request.urlopen(url, timeout=min(WAIT_S, seconds)) as response:
        with atomic_file(folder / file.path) as fh:
            while True:
                if stop.is_set():
                    raise Cancelled
                try:
                    chunk = response.read1(CHUNK)  # what has arrived: a trickle is seen
                except TimeoutError:
                    raise Stalled(received, time.monotonic() - start, idle=True) from None
                except http.client.IncompleteRead:  # a chunked answer cut short
                    raise ConnectionError(f"connection lost after {received} bytes") from None
                if not chunk:
                    if response.length:  # fewer bytes than the server announced
                        raise ConnectionError(f"connection lost after {received} bytes")
                    break
                received += len(chunk)
                if received > file.size:  # an endless answer never fills the disk
                    raise Mismatch(None, received)
                digest.update(chunk)
                fh.write(chunk)
                if time.monotonic() - start > seconds:
                    raise Stalled(received, time.monotonic() - start, idle=False)
            if digest.hexdigest() != file.sha256:
                raise Mismatch(digest.hexdigest(), received)
