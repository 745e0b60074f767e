"""`dataset fetch` when the server or the process misbehaves (issue 33): a server that trickles
bytes or falls silent meets a per-file deadline and is named as stalled; no temporary file stays
in the cache after a stall, a wrong hash, an HTTP error or Ctrl-C; what a killed fetch left (its
temporary files, the folder staged for the importer) is removed by the next fetch; a cached file
that fails its hash is named and downloaded again. A local http.server in a thread stands in
for the publisher, with tiny deadlines."""

from __future__ import annotations

import _thread
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from publisher import serve

from slipbench.data import download
from slipbench.data.card import files_block, load_card
from slipbench.data.fetch import card_cache, fetch
from slipbench.data.read import read_dataset
from slipbench.errors import DataError, EnvironmentFault


def _publish(root: Path, n: int = 3) -> Path:
    """A lab's published folder: ``n`` CSV files of 40 rows (two channels)."""
    published = root / "published"
    for k in range(n):
        (published / "foam").mkdir(parents=True, exist_ok=True)
        rows = "\n".join(f"{i},{(i * 7 + k) % 11},{(i * 3) % 5}" for i in range(40))
        (published / "foam" / f"trial_{k}.csv").write_text(f"t,g1,g2\n{rows}\n")
    return published


def _card(root: Path, published: Path, extra: str = "") -> Path:
    card = root / "lab.toml"
    card.write_text(
        'name = "lab-x"\ntitle = "Lab X"\ncitation = "Lab X, 2026"\nlicense = "CC-BY-4.0"\n'
        'homepage = "https://example.org/x"\nbase_url = "https://example.org/x/"\n'
        + files_block(published, ["*/*.csv"])
        + '[mapping]\nfiles = "*/*.csv"\n[mapping.recording]\n'
        + 'sensor_type = "Gauge"\nsensor_instance = "index"\nscenario = "slip"\n'
        + '[mapping.channels]\nnames = ["g1", "g2"]\n[mapping.rate]\nhz = 50.0\n'
        + extra
    )
    return card


def leftovers(cache: Path) -> list[Path]:
    """What a fetch may not leave: temporary files, staged folders."""
    return sorted(p for p in cache.rglob(".*") if p.name.endswith(".tmp") or ".staged-" in p.name)


@pytest.fixture
def lab(tmp_path, monkeypatch):
    """(card, published folder, cache folder); deadlines of a fraction of a second."""
    monkeypatch.setenv("SLIPBENCH_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(download, "WAIT_S", 0.4)
    published = _publish(tmp_path)
    return load_card(_card(tmp_path, published)), published, tmp_path / "cache"


@pytest.mark.parametrize("how", ["trickle", "silent"])
def test_a_stalled_server_meets_the_deadline_and_is_named(lab, tmp_path, how):
    card, published, cache = lab
    with serve(published, {"foam/trial_1.csv": how}) as (host, _):
        url = f"{host}/"
        start = time.monotonic()
        with pytest.raises(EnvironmentFault) as err:
            fetch(card, tmp_path / "out", url, min_rate=1e9)
        took = time.monotonic() - start
    message, size = str(err.value), (published / "foam" / "trial_1.csv").stat().st_size
    assert message.startswith(f"cannot download {url}foam/trial_1.csv: the server stalled: ")
    if how == "trickle":  # a byte every beat: no read ever times out, the deadline does
        assert re.search(rf": \d+ of {size} bytes in 0\.\d s;", message), message
    else:
        assert f"no byte for 0.4 s after 4 of {size} bytes" in message
    assert "no connection" not in message and "lower --min-rate" in message
    assert took < 3 and not leftovers(cache) and not (tmp_path / "out").exists()
    assert not (card_cache(card) / "foam" / "trial_1.csv").exists()


@pytest.mark.parametrize("how", ["missing", "wrong hash"])
def test_no_temporary_file_stays_after_an_http_error_or_a_wrong_hash(lab, tmp_path, how):
    card, published, cache = lab
    if how == "wrong hash":
        (published / "foam" / "trial_2.csv").write_text("t,g1,g2\n" + "1,2,3\n" * 40)
    with serve(published, {"foam/trial_2.csv": how} if how == "missing" else {}) as (url, _):
        with pytest.raises((EnvironmentFault, DataError)) as err:
            fetch(card, tmp_path / "out", url)
    assert ("404" if how == "missing" else "its SHA-256 is") in str(err.value)
    assert not leftovers(cache) and not (tmp_path / "out").exists()
    assert not (card_cache(card) / "foam" / "trial_2.csv").exists()


def test_ctrl_c_stops_the_downloads_and_leaves_no_temporary_file(lab, tmp_path, cli, monkeypatch):
    card, published, cache = lab
    monkeypatch.setattr(download, "WAIT_S", 10.0)  # only Ctrl-C ends these downloads
    slow = {f"foam/trial_{k}.csv": "trickle" for k in range(3)}
    with serve(published, slow) as (url, requested):
        timer = threading.Timer(0.3, _thread.interrupt_main)  # as Ctrl-C would
        timer.start()
        start = time.monotonic()
        code, _, err = cli(
            ["dataset", "fetch", card.where, "--url", url, "--out", str(tmp_path / "out")]
        )
        timer.cancel()
        took = time.monotonic() - start
    assert code == 130 and "interrupted" in err, err
    assert len(requested) == 3 and took < 3
    assert not leftovers(cache) and not (tmp_path / "out").exists()


def test_a_damaged_cached_file_is_named_and_downloaded_again(lab, tmp_path):
    card, published, cache = lab
    with serve(published) as (url, requested):
        fetch(card, tmp_path / "first", url)
        damaged = card_cache(card) / "foam" / "trial_0.csv"
        damaged.write_text("t,g1,g2\n1,2,3\n")
        said: list[str] = []
        fetch(card, tmp_path / "second", url, said.append)
    assert said[0].endswith(
        f"2 verified in {card_cache(card)}; downloading 1 from {url}/: 1 in the cache failing "
        "their SHA-256 (foam/trial_0.csv), replaced"
    ), said
    assert requested.count("/foam/trial_0.csv") == 2 and len(requested) == 4
    assert (
        read_dataset(tmp_path / "second").fingerprint
        == read_dataset(tmp_path / "first").fingerprint
    )
    said.clear()
    with serve(published) as (url, requested):
        fetch(card, tmp_path / "third", url, said.append)
    assert said[0].endswith(f"all 3 verified in {card_cache(card)}: nothing to download")
    assert requested == []


def test_leftovers_of_a_killed_fetch_are_removed_by_the_next(lab, tmp_path):
    card, published, cache = lab
    folder = card_cache(card)
    (folder / "foam").mkdir(parents=True)
    stale = folder / "foam" / ".trial_1.csv.0123456789ab.tmp"
    stale.write_bytes(b"t,g1")
    staged = folder.parent / ".lab-x.staged-0123456789ab"
    (staged / "foam").mkdir(parents=True)
    (staged / "foam" / "trial_0.csv").write_text("half")
    with serve(published) as (url, _):
        fetch(card, tmp_path / "out", url)
    assert not leftovers(cache)
    assert sorted(read_dataset(tmp_path / "out").recordings["recording_id"]) == [
        f"foam/trial_{k}" for k in range(3)
    ]


KILLED = """
import sys, time
from slipbench.data import fetch
from slipbench.data.card import load_card
if sys.argv[3] == "convert":  # the conversion hangs: the kill comes while it runs
    fetch._convert = lambda *args: (print("converting", flush=True), time.sleep(60))
else:
    print("downloading", flush=True)
fetch.fetch(load_card(sys.argv[1]), sys.argv[4], sys.argv[2])
"""


@pytest.mark.slow
@pytest.mark.parametrize("phase", ["download", "convert"])
def test_a_fetch_killed_by_sigkill_is_cleaned_up_by_the_next(tmp_path, phase, monkeypatch):
    """A real SIGKILL, mid-download (a trickling server) or mid-conversion: the killed process
    leaves temporary files or a staged folder; the next fetch removes them and succeeds."""
    published = _publish(tmp_path)
    card = _card(tmp_path, published)
    env = {**os.environ, "SLIPBENCH_CACHE": str(tmp_path / "cache")}
    slow = {f"foam/trial_{k}.csv": "trickle" for k in range(3)} if phase == "download" else {}
    with serve(published, slow) as (url, _):
        proc = subprocess.Popen(
            [sys.executable, "-c", KILLED, str(card), url, phase, str(tmp_path / "killed")],
            stdout=subprocess.PIPE,
            text=True,
            env=env,
        )
        assert proc.stdout.readline().strip() in ("converting", "downloading")
        time.sleep(0.5)
        proc.send_signal(signal.SIGKILL)
        proc.communicate()
    left = leftovers(tmp_path / "cache")
    if phase == "convert":
        assert any(".staged-" in p.name for p in left), left
    else:
        assert any(p.name.endswith(".tmp") for p in left), left
    monkeypatch.setenv("SLIPBENCH_CACHE", env["SLIPBENCH_CACHE"])
    with serve(published) as (url, _):
        fetch(load_card(card), tmp_path / "out", url)
    assert not leftovers(tmp_path / "cache")
    assert len(read_dataset(tmp_path / "out").recordings) == 3
