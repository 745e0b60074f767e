"""Paths from a dataset card or a mapping stay inside their root (issue 33): a `files` glob, a
rule's glob, a `[[metadata]] table` or a `[labels] segments` table with `..`, an absolute path,
or a symbolic link leading out is refused with exit 2, naming the card or mapping file, the key
and the value; a card's is refused before anything is downloaded. A user's own mapping reads an
outside folder only where `dataset import csv --read-outside` names it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from slipbench.data.card import load_card
from slipbench.data.importers import import_csv, load_mapping
from slipbench.data.read import read_dataset
from slipbench.errors import UsageError

CARD = """\
name = "lab-x"
title = "Lab X"
citation = "Lab X, 2026"
license = "CC-BY-4.0"
homepage = "https://example.org/x"
base_url = "https://example.org/x/"
files = [{{ path = "foam/trial_0.csv", sha256 = "{sha}", size = 10 }}]
[mapping]
files = "{files}"
[mapping.recording]
sensor_type = "Gauge"
sensor_instance = "index"
scenario = "slip"
[mapping.channels]
names = ["g1"]
[mapping.rate]
hz = 50.0
{extra}"""


def _card_text(files: str = "*/*.csv", extra: str = "") -> str:
    return CARD.format(sha="0" * 64, files=files, extra=extra)


@pytest.mark.parametrize(
    "files, extra, entry",
    [
        ("../../../outside/lab/*", "", "files = '../../../outside/lab/*'"),
        ("/home/*/*.csv", "", "files = '/home/*/*.csv'"),
        ("*/*.csv", '[[mapping.rules]]\nglob = "../*.csv"\n', "[[rules]] #1.glob = '../*.csv'"),
        (
            "*/*.csv",
            '[[mapping.metadata]]\ntable = "../outside.json"\nfields = { source = "s" }\n',
            "[[metadata]] #1.table = '../outside.json'",
        ),
        (
            "*/*.csv",
            '[[mapping.metadata]]\ntable = "/etc/lab.json"\nfields = { source = "s" }\n',
            "[[metadata]] #1.table = '/etc/lab.json'",
        ),
        (
            "*/*.csv",
            '[mapping.labels]\nsegments = "../../segments.csv"\n',
            "[labels].segments = '../../segments.csv'",
        ),
    ],
)
def test_a_card_path_leading_out_is_refused_before_any_download(tmp_path, cli, files, extra, entry):
    card = tmp_path / "lab.toml"
    card.write_text(_card_text(files, extra))
    with pytest.raises(UsageError) as err:
        load_card(card)
    assert str(err.value).startswith(f"{card}: [mapping]: {entry}: "), err.value
    code, _, stderr = cli(  # the URL is never asked: nothing listens there
        [
            "dataset",
            "fetch",
            str(card),
            "--url",
            "http://127.0.0.1:9/",
            "--out",
            str(tmp_path / "o"),
        ]
    )
    assert code == 2 and f"{card}: [mapping]: {entry}" in stderr and "Traceback" not in stderr
    assert "--read-outside" not in stderr  # a card may never read outside its files
    assert not (tmp_path / "o").exists()


def _lab(root: Path) -> tuple[Path, Path, Path]:
    """SRC with one recording, an outside folder holding another recording and a metadata
    file, and a mapping file beside SRC."""
    src, outside = root / "src", root / "outside"
    for folder, name in ((src / "foam", "trial_0.csv"), (outside / "lab", "stolen.csv")):
        folder.mkdir(parents=True)
        (folder / name).write_text("g1\n" + "\n".join(str(i % 7) for i in range(30)) + "\n")
    (outside / "lab" / "meta.json").write_text(json.dumps({"s": "from outside"}))
    mapping = root / "mapping.toml"
    return src, outside, mapping


MAPPING = """\
files = "**/*.csv"
[recording]
sensor_type = "Gauge"
sensor_instance = "index"
scenario = "slip"
[channels]
names = ["g1"]
[rate]
hz = 50.0
"""


@pytest.mark.parametrize("link", ["a folder", "a file"])
def test_a_link_out_of_src_is_refused_unless_its_folder_is_named(tmp_path, cli, link):
    src, outside, mapping = _lab(tmp_path)
    mapping.write_text(MAPPING.replace('"**/*.csv"', '"*/*.csv"'))
    if link == "a folder":
        (src / "linked").symlink_to(outside / "lab", target_is_directory=True)
    else:
        (src / "linked").mkdir()
        (src / "linked" / "stolen.csv").symlink_to(outside / "lab" / "stolen.csv")
    argv = ["dataset", "import", "csv", str(src), str(tmp_path / "out"), "--config", str(mapping)]
    code, _, err = cli(argv)
    assert code == 2, err
    assert err.startswith(
        f"error: {mapping}: files = '*/*.csv': {src}/linked/stolen.csv leads to "
        f"{(outside / 'lab' / 'stolen.csv').resolve()}, outside {src}; "
    ), err
    assert "--read-outside" in err and not (tmp_path / "out").exists()
    code, _, err = cli([*argv, "--read-outside", str(outside)])
    assert code == 0, err
    ids = sorted(read_dataset(tmp_path / "out").recordings["recording_id"])
    assert ids == ["foam/trial_0", "linked/stolen"]


@pytest.mark.parametrize("table", ["../outside/lab/meta.json", "{outside}/lab/meta.json", "link"])
def test_a_metadata_table_outside_src_needs_read_outside(tmp_path, table):
    src, outside, mapping = _lab(tmp_path)
    if table == "link":  # inside SRC as written, outside once the link is followed
        (src / "meta.json").symlink_to(outside / "lab" / "meta.json")
        table = "meta.json"
    table = table.format(outside=outside)
    mapping.write_text(
        MAPPING.replace('"**/*.csv"', '"foam/*.csv"')
        + f'[[metadata]]\ntable = "{table}"\nfields = {{ source = "s" }}\n'
    )
    with pytest.raises(UsageError, match=r"\[\[metadata\]\] #1\.table = ") as err:
        import_csv(src, tmp_path / "out", mapping)
    assert str(err.value).startswith(f"{mapping}: [[metadata]] #1.table = {table!r}")
    assert "--read-outside" in str(err.value) and not (tmp_path / "out").exists()
    allowed = load_mapping(mapping, None, [outside])
    ds = read_dataset(import_csv(src, tmp_path / "out", allowed))
    assert ds.recordings["source"].tolist() == ["from outside"]


def test_a_segments_table_stays_in_the_mappings_folder(tmp_path):
    src, outside, mapping = _lab(tmp_path)
    (outside / "segments.csv").write_text("file,onset,offset\nfoam/trial_0.csv,10,20\n")
    mapping.write_text(MAPPING + '[labels]\nsegments = "outside/segments.csv"\n')
    labels = read_dataset(import_csv(src, tmp_path / "in", mapping)).slip_labels
    assert labels["foam/trial_0"].sum() == 10  # beside the mapping: inside its root
    (tmp_path / "elsewhere").mkdir()
    moved = tmp_path / "elsewhere" / "mapping.toml"
    moved.write_text(MAPPING + '[labels]\nsegments = "../outside/segments.csv"\n')
    with pytest.raises(UsageError, match=r"\[labels\]\.segments = '\.\./outside/segments\.csv'"):
        import_csv(src, tmp_path / "out", moved)
    labels = read_dataset(
        import_csv(src, tmp_path / "out", load_mapping(moved, None, [outside]))
    ).slip_labels
    assert labels["foam/trial_0"].sum() == 10
