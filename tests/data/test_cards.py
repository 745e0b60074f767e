"""Dataset cards and `dataset fetch`: published files served over a loopback HTTP server (no
network in CI), checked against the card's SHA-256, cached, converted with the card's importer."""

from __future__ import annotations

import shutil
import socket
from pathlib import Path

import pytest
from publisher import serve

from slipbench.data.card import builtin_cards, files_block, load_card, sha256_of
from slipbench.data.read import read_dataset, read_description

SOURCE = Path(__file__).resolve().parents[3] / "shared" / "datasets" / "biotacsp-dos" / "csvs"
needs_dos = pytest.mark.skipif(not SOURCE.is_dir(), reason=f"BioTacSP-DoS not found at {SOURCE}")
DOS_FINGERPRINT = "aac611fa5f8ae950"  # `dataset import biotacsp-dos` of the published csvs


@pytest.fixture
def cache(tmp_path, monkeypatch):
    folder = tmp_path / "cache"
    monkeypatch.setenv("SLIPBENCH_CACHE", str(folder))
    return folder / "datasets"


def test_the_builtin_card_lists_every_published_file():
    card = builtin_cards()["biotacsp-dos"]
    assert len(card.files) == 306 and card.importer == "biotacsp-dos"
    assert card.base_url.startswith("https://") and card.base_url.endswith("/csvs/")
    assert "Sensors 19(3):523" in card.citation and card.license
    if SOURCE.is_dir():  # the card's hashes are those of the published files
        for f in card.files[::50]:
            assert sha256_of(SOURCE / f.path) == f.sha256
            assert (SOURCE / f.path).stat().st_size == f.size


def test_cards_lists_name_title_size_license(cli):
    code, out, err = cli(["dataset", "cards"])
    assert code == 0, err
    assert "biotacsp-dos" in out and "BioTacSP-DoS" in out and "10.2 MB" in out
    assert "none stated upstream" in out


def test_an_unknown_card_lists_the_known_ones(cli, tmp_path):
    code, out, err = cli(["dataset", "fetch", "biotac", "--out", str(tmp_path / "x")])
    assert code == 2 and "no dataset card 'biotac'" in err and "known: biotacsp-dos" in err
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize(
    "change, message",
    [
        ('sha256 = "abc"', "sha256 must be 64 lower-case hex digits"),
        ('importer = "nope"', "importer 'nope' is not built in"),
        ('licence = "MIT"', "unknown key(s) licence"),
        ('path = "../x.csv"', "must be relative"),
        ('name = ".."', "name '..' must start with a lower-case letter or a digit"),
        ('name = "Lab"', "name 'Lab' must start with a lower-case letter or a digit"),
        ("description = " + "[" * 3000 + "]" * 3000, "nested too deeply to read"),
    ],
)
def test_a_bad_card_is_refused_naming_the_key(tmp_path, change, message):
    text = _card_text().splitlines()
    key = change.split(" =")[0]
    if key in ("sha256", "path"):
        i = next(i for i, line in enumerate(text) if line.startswith("  { path"))
        old = text[i].split(f"{key} = ")[1].split(",")[0]
        text[i] = text[i].replace(f"{key} = {old}", change)
    elif key in ("importer", "name", "description"):
        text = [change if line.startswith(f"{key} =") else line for line in text]
    else:
        text.insert(3, change)
    from slipbench.errors import UsageError

    with pytest.raises(UsageError, match=message.replace("(", r"\(").replace(")", r"\)")):
        load_card(tmp_path / "bad.toml", "\n".join(text))


def _card_text() -> str:
    return Path(builtin_cards()["biotacsp-dos"].where).read_text()


def test_the_documented_card_is_a_valid_card(tmp_path):
    import re

    docs = (Path(__file__).resolve().parents[2] / "docs" / "reference" / "datasets.md").read_text()
    (block,) = [b for b in re.findall(r"```toml\n(.*?)```", docs, flags=re.S) if "lab-x-slips" in b]
    card = load_card("datasets.md", block)
    assert card.name == "lab-x-slips" and card.mapping and card.importer is None
    assert card.files[0].path == "foam/trial_0.csv"


def test_no_network_names_the_url(cli, cache, tmp_path):
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    url = f"http://127.0.0.1:{port}/csvs"
    code, out, err = cli(
        ["dataset", "fetch", "biotacsp-dos", "--url", url, "--out", str(tmp_path / "x")]
    )
    assert code == 5, err
    assert f"cannot download {url}/" in err and "no connection" in err and "--url" in err
    assert "Traceback" not in err and not (tmp_path / "x").exists()


@needs_dos
def test_a_corrupted_download_is_refused(cli, cache, tmp_path):
    mirror = tmp_path / "mirror"
    shutil.copytree(SOURCE, mirror / "csvs")
    bad = mirror / "csvs" / "aw" / "bottle0.csv"
    data = bytearray(bad.read_bytes())
    i = data.index(b"\n") + 1  # one digit of the first sample flipped, as a bad copy would
    data[i] = ord("8") if data[i] == ord("9") else ord("9")
    bad.write_bytes(bytes(data))
    card = builtin_cards()["biotacsp-dos"]
    expected = next(f.sha256 for f in card.files if f.path == "aw/bottle0.csv")
    with serve(mirror) as (url, requested):
        code, out, err = cli(
            [
                "dataset",
                "fetch",
                "biotacsp-dos",
                "--url",
                f"{url}/csvs",
                "--out",
                str(tmp_path / "x"),
            ]
        )
    assert code == 2, err
    assert f"aw/bottle0.csv: downloaded from {url}/csvs/aw/bottle0.csv" in err
    assert sha256_of(bad) in err and expected in err and "nothing was written" in err
    assert not (tmp_path / "x").exists()
    assert not (cache / "biotacsp-dos" / "aw" / "bottle0.csv").exists()  # only verified files
    assert len(requested) < 306  # it stopped at the first failure


@pytest.fixture(scope="module")
def fetched(tmp_path_factory):
    """`dataset fetch` over loopback after an interrupted download: the cache already holds
    every file but the touch class, then a second fetch into another folder."""
    from slipbench.app.cli import main

    if not SOURCE.is_dir():
        pytest.skip(f"BioTacSP-DoS not found at {SOURCE}")
    root = tmp_path_factory.mktemp("fetch")
    mp = pytest.MonkeyPatch()
    mp.setenv("SLIPBENCH_CACHE", str(root / "cache"))
    partial = root / "cache" / "datasets" / "biotacsp-dos"
    shutil.copytree(SOURCE, partial, ignore=lambda d, names: ["t"] if Path(d) == SOURCE else [])
    runs = []
    with serve(SOURCE.parent) as (url, requested):
        for out in ("first", "second"):
            argv = ["dataset", "fetch", "biotacsp-dos", "--url", f"{url}/csvs"]
            try:
                main([*argv, "--out", str(root / out)])
                code = 0
            except SystemExit as exit_:
                code = exit_.code or 0
            runs.append((code, sorted(requested)))
    mp.undo()
    return root, runs


@pytest.mark.slow
def test_fetch_gives_the_imported_fingerprint_and_resumes(fetched):
    root, runs = fetched
    (code, requested), (code2, requested2) = runs
    assert code == 0
    touch = sorted(f"/csvs/t/{p.name}" for p in (SOURCE / "t").glob("*.csv"))
    assert requested == touch  # only the files the interrupted download had not kept
    ds = read_dataset(root / "first")
    assert ds.fingerprint == DOS_FINGERPRINT and len(ds.recordings) == 306
    description = read_description(root / "first")
    assert '"card": "biotacsp-dos"' in description["slipbench.source"]
    assert "/csvs/" in description["slipbench.source"]
    assert "Sensors 19(3):523" in description["slipbench.citation"]


@pytest.mark.slow
def test_a_second_fetch_uses_the_cache(fetched):
    root, runs = fetched
    (_, requested), (code2, requested2) = runs
    assert code2 == 0 and requested2 == requested  # the server saw no new request
    assert read_dataset(root / "second").fingerprint == DOS_FINGERPRINT


def test_a_lab_card_with_its_own_mapping(cli, cache, tmp_path):
    """A lab's card: CSVs on a server, the mapping inline, the card given as a file."""
    published = tmp_path / "published"
    for material, k in (("foam", 0), ("wood", 1), ("foam", 2)):
        (published / material).mkdir(parents=True, exist_ok=True)
        rows = "\n".join(f"{i},{(i * 7 + k) % 11},{(i * 3) % 5}" for i in range(40))
        (published / material / f"trial_{k}.csv").write_text(f"t,g1,g2\n{rows}\n")
    card = tmp_path / "lab.toml"
    card.write_text(
        'name = "lab-x"\ntitle = "Lab X slips"\ncitation = "Lab X, 2026"\nlicense = "CC-BY-4.0"\n'
        'homepage = "https://example.org/lab-x"\nbase_url = "https://example.org/lab-x/data/"\n'
        + files_block(published, ["*/*.csv"])
        + '[mapping]\nfiles = "*/*.csv"\n[mapping.recording]\n'
        + "regex = '(?P<material>[a-z]+)/trial_\\d+\\.csv'\n"
        + 'sensor_type = "Gauge"\nsensor_instance = "index"\nscenario = "slip"\n'
        + '[mapping.channels]\nnames = ["g1", "g2"]\nunits = "N"\n[mapping.rate]\nhz = 50.0\n'
    )
    with serve(published) as (url, requested):
        code, out, err = cli(
            ["dataset", "fetch", str(card), "--url", url, "--out", str(tmp_path / "x")]
        )
    assert code == 0, err
    assert len(requested) == 3 and "license: CC-BY-4.0" in out
    ds = read_dataset(tmp_path / "x")
    assert sorted(ds.recordings["material"]) == ["foam", "foam", "wood"]
    assert ds.samples["wood/trial_1"].shape == (40, 2)
    code, out, err = cli(["dataset", "info", str(tmp_path / "x")])
    assert "source: Lab X slips (https://example.org/lab-x), card lab-x" in out
    assert "cite: Lab X, 2026" in out
    from slipbench.data.schema import FINGERPRINT_KEY
    from slipbench.data.write import write_dataset
    from slipbench.errors import DataError

    with pytest.raises(DataError, match="writes slipbench.fingerprint itself"):
        write_dataset(tmp_path / "y", ds.recordings, ds.samples, None, {FINGERPRINT_KEY: "0"})
