"""The generic CSV importer, on small synthetic files shaped like three labs' recordings:

(a) a 48-channel taxel array at about 60 Hz: integer counts, trials of 250-400 frames that hold
    and then slip for 20-100 frames, some ending in a drop; per-trial rates of 59.7-60.0 Hz read
    from a time column; a label column;
(b) one vibration channel at 2.2 kHz, every trial sliding, trials recorded in pieces;
(c) 100 Hz, two fingers in one file, slip and pressing, slip segments from a sidecar table.

And every kind of bad file and bad mapping, named by file, line and column (or mapping key)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from slipbench.data.importers import import_csv, load_mapping
from slipbench.data.read import read_dataset
from slipbench.errors import DataError, UsageError

DOCS = Path(__file__).resolve().parents[2] / "docs" / "reference" / "datasets.md"


def _write(path: Path, frame: pd.DataFrame, header: str = "") -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(header + frame.to_csv(index=False))
    return path


def _toml_block(marker: str) -> str:
    """The ```toml block of docs/reference/datasets.md that contains ``marker``: the documented examples are
    the ones tested."""
    blocks = re.findall(r"```toml\n(.*?)```", DOCS.read_text(), flags=re.S)
    found = [b for b in blocks if marker in b]
    assert len(found) == 1, (
        f"one toml block of docs/reference/datasets.md should contain {marker!r}"
    )
    return found[0]


# ----------------------------------------------------------------------------- (a) taxel array
def _taxel_trials(root: Path, n_trials: int = 6, seed: int = 0) -> dict[str, dict]:
    """Files taxels/<material>/trial_<n>.csv with columns t, taxel_0..taxel_47, state."""
    rng = np.random.default_rng(seed)
    truth = {}
    for k in range(n_trials):
        material = ("foam", "wood")[k % 2]
        n = int(rng.integers(250, 401))
        rate = float(rng.uniform(59.7, 60.0))
        onset = int(rng.integers(100, n - 120))
        slip = int(rng.integers(20, 101))
        drop = k % 3 == 0
        state = np.array(
            ["hold"] * onset
            + ["slip"] * slip
            + (["drop"] if drop else ["hold"]) * (n - onset - slip)
        )
        counts = rng.integers(200, 4000, size=(n, 48))
        frame = pd.DataFrame(counts, columns=[f"taxel_{i}" for i in range(48)])
        frame.insert(0, "t", 1000.0 + np.arange(n) / rate)  # a logger's clock: seconds
        frame["state"] = state
        rid = f"{material}/trial_{k}"
        _write(root / "taxels" / f"{rid}.csv", frame)
        labels = np.select([state == "slip", state == "hold"], [1, 0], -1).astype(np.int8)
        truth[rid] = dict(counts=counts, rate=rate, labels=labels, material=material)
    return truth


def test_taxel_array_from_the_documented_mapping(tmp_path):
    truth = _taxel_trials(tmp_path / "src")
    mapping = tmp_path / "mapping.toml"
    mapping.write_text(_toml_block("taxel_"))
    ds = read_dataset(import_csv(tmp_path / "src", tmp_path / "out", mapping))
    rec = ds.recordings.set_index("recording_id")
    assert sorted(rec.index) == sorted(f"taxels/{r}" for r in truth)
    rates = []
    for rid, t in truth.items():
        row = rec.loc[f"taxels/{rid}"]
        assert (row["sensor_type"], row["sensor_instance"], row["scenario"], row["material"]) == (
            "TaxelArray",
            "right-hand",
            "hold-slip",
            t["material"],
        )
        assert (
            row["channels"] == tuple(f"taxel_{i}" for i in range(48))
            and row["units"] == ("count",) * 48
        )
        assert row["sampling_rate_hz"] == pytest.approx(
            t["rate"], rel=1e-9
        )  # the median step of its time column
        rates.append(row["sampling_rate_hz"])
        np.testing.assert_array_equal(
            ds.samples[f"taxels/{rid}"], t["counts"]
        )  # integer counts, exact
        np.testing.assert_array_equal(ds.slip_labels[f"taxels/{rid}"], t["labels"])
        assert row["trial"] == f"taxels/{rid}"  # one file, one trial
    assert rec["unit_rate_hz"].to_numpy() == pytest.approx(
        [np.median(rates)] * len(rates), rel=1e-12
    )
    assert (rec["source"] == "Lab X, right hand, 2026").all()


# ----------------------------------------------------------------------------- (b) vibration
def test_vibration_channel_with_trials_in_pieces(tmp_path):
    rng = np.random.default_rng(1)
    src = tmp_path / "src"
    parts = {}
    for session in ("s1", "s2"):
        for piece in (1, 2):
            a = rng.normal(0, 0.02, size=(440, 1)).round(6)
            parts[f"{session}_part{piece}"] = a
            _write(
                src / f"{session}_part{piece}.csv",
                pd.DataFrame(a, columns=["accel_g"]),
                header="# accelerometer log\n",
            )
    mapping = {
        "files": "*.csv",
        "comment": "#",
        "recording": {
            "regex": r"(?P<session>s\d+)_part\d+\.csv",
            "sensor_type": "Vibro",
            "sensor_instance": "tip",
            "scenario": "slip",
            "material": "glass",
            "speed_mm_s": 20,
            "trial": "{session}",
        },
        "channels": {"names": ["accel_g"], "units": ["g"]},
        "rate": {"hz": 2200},
    }
    ds = read_dataset(import_csv(src, tmp_path / "out", mapping))
    rec = ds.recordings
    assert list(rec["recording_id"]) == sorted(parts)
    assert list(rec["trial"]) == ["s1", "s1", "s2", "s2"]
    assert (
        set(rec["scenario"]) == {"slip"}
        and set(rec["sampling_rate_hz"]) == {2200.0}
        and set(rec["speed_mm_s"]) == {20.0}
    )
    assert ds.slip_labels == {}  # labelled by scenario only
    for rid, a in parts.items():
        np.testing.assert_array_equal(ds.samples[rid], a)


# ----------------------------------------------------------------------------- (c) 100 Hz, two fingers, segments
def test_two_fingers_per_file_with_slip_segments(tmp_path):
    rng = np.random.default_rng(2)
    src = tmp_path / "src"
    segments = []
    files = {}
    for scenario in ("slip", "press"):
        for material in ("pvc", "cork"):
            for speed in (10, 40):
                name = f"{scenario}/{material}_{speed}mms.csv"
                n = 300
                frame = pd.DataFrame(
                    rng.normal(size=(n, 6)).round(4), columns=["ix", "iy", "iz", "mx", "my", "mz"]
                )
                _write(src / name, frame)
                files[name] = frame
                if scenario == "slip":
                    segments.append((name, 1.0, 2.5))  # seconds
    pd.DataFrame(segments, columns=["file", "onset", "offset"]).to_csv(
        tmp_path / "segments.csv", index=False
    )
    (tmp_path / "mapping.toml").write_text("""
files = "*/*.csv"
[recording]
regex = '(?P<scenario>[a-z]+)/(?P<material>[a-z]+)_(?P<speed_mm_s>\\d+)mms\\.csv'
sensor_type = "Force3D"
source = "lab Y"
[[rules]]
glob = "press/*.csv"
speed_mm_s = "none"
[map.material]
pvc = "PVC"
[[channels]]
sensor_instance = "index"
names = ["ix", "iy", "iz"]
units = "N"
[[channels]]
sensor_instance = "middle"
pattern = 'm[xyz]'
units = "N"
[rate]
hz = 100
[labels]
segments = "segments.csv"
unit = "s"
""")
    ds = read_dataset(import_csv(src, tmp_path / "out", tmp_path / "mapping.toml"))
    rec = ds.recordings.set_index("recording_id")
    assert len(rec) == 16
    row = rec.loc["slip/pvc_10mms/middle"]
    assert (row["sensor_instance"], row["material"], row["speed_mm_s"], row["trial"]) == (
        "middle",
        "PVC",
        10.0,
        "slip/pvc_10mms",
    )
    assert row["channels"] == ("mx", "my", "mz")
    assert (
        rec.loc["slip/pvc_10mms/index", "trial"] == "slip/pvc_10mms"
    )  # the two fingers share the trial
    assert np.isnan(rec.loc["press/cork_40mms/index", "speed_mm_s"])
    np.testing.assert_array_equal(
        ds.samples["slip/cork_40mms/index"],
        files["slip/cork_40mms.csv"][["ix", "iy", "iz"]].to_numpy(),
    )
    labels = ds.slip_labels["slip/pvc_10mms/index"]
    assert labels.tolist() == [0] * 100 + [1] * 150 + [0] * 50  # [1.0 s, 2.5 s) at 100 Hz
    assert (ds.slip_labels["press/pvc_10mms/index"] == -1).all()  # not in the table: unlabelled


def test_onsets_from_file_names_and_drops_unlabelled(tmp_path):
    """Segments from the mapping: the onset (in samples) is part of each file's name; what follows
    the offset is a drop, unlabelled; a file without an onset is labelled no-slip throughout."""
    src = tmp_path / "src"
    for name in ("grip_onset40_end70.csv", "grip_onset10_end.csv", "still.csv"):
        _write(src / name, pd.DataFrame({"p": np.arange(100) % 7}))
    mapping = {
        "recording": {"sensor_type": "P", "sensor_instance": "thumb", "scenario": "press"},
        "rules": [
            {
                "regex": r"grip_onset(?P<slip_onset>\d+)_end(?P<slip_offset>\d*)\.csv",
                "scenario": "hold-slip",
            }
        ],
        "channels": {"names": ["p"]},
        "rate": {"hz": 500},
        "labels": {"unit": "sample", "after_offset": "unlabelled", "unlisted": "no-slip"},
    }
    ds = read_dataset(import_csv(src, tmp_path / "out", mapping))
    assert ds.slip_labels["grip_onset40_end70"].tolist() == [0] * 40 + [1] * 30 + [-1] * 30
    assert (
        ds.slip_labels["grip_onset10_end"].tolist() == [0] * 10 + [1] * 90
    )  # no offset: slips to the end
    assert ds.slip_labels["still"].tolist() == [0] * 100
    assert list(ds.recordings["scenario"]) == ["hold-slip", "hold-slip", "press"]
    np.testing.assert_array_equal(ds.samples["still"][:, 0], np.arange(100) % 7)


def test_bad_segments_are_named(tmp_path):
    src = tmp_path / "src"
    _write(src / "a.csv", pd.DataFrame({"p": np.arange(50)}))
    pd.DataFrame({"file": ["a.csv", "b.csv"], "onset": [10, 20], "offset": [20, 30]}).to_csv(
        tmp_path / "seg.csv", index=False
    )
    mapping = {
        "recording": {"sensor_type": "P", "sensor_instance": "u", "scenario": "slip"},
        "channels": {"names": ["p"]},
        "rate": {"hz": 100},
        "labels": {"segments": "seg.csv"},
    }
    with pytest.raises(
        DataError, match=r"seg.csv: line 3: file 'b.csv' is not among the imported files"
    ):
        import_csv(src, tmp_path / "out", mapping, base=tmp_path)
    pd.DataFrame({"file": ["a.csv"], "onset": [40], "offset": [60]}).to_csv(
        tmp_path / "seg.csv", index=False
    )
    with pytest.raises(
        DataError,
        match=r"seg.csv: line 2: slip segment \[40, 60\) does not fit .*a.csv \(50 samples\)",
    ):
        import_csv(src, tmp_path / "out", mapping, base=tmp_path)
    pd.DataFrame({"file": ["a.csv"], "onset": ["soon"]}).to_csv(tmp_path / "seg.csv", index=False)
    with pytest.raises(
        DataError, match=r"seg.csv: line 2: column 'onset': non-numeric value 'soon'"
    ):
        import_csv(src, tmp_path / "out", mapping, base=tmp_path)


# ----------------------------------------------------------------------------- bad files: file, line, column
def _one_file(tmp_path, text: str, **mapping) -> tuple[Path, dict]:
    src = tmp_path / "src"
    src.mkdir(exist_ok=True)
    (src / "r.csv").write_text(text)
    base = {
        "comment": "#",
        "recording": {"sensor_type": "S", "sensor_instance": "u", "scenario": "slip"},
        "channels": {"pattern": r"taxel_\d+"},
        "rate": {"hz": 60},
    }
    for key, value in mapping.items():
        base[key] = {**base.get(key, {}), **value} if isinstance(value, dict) else value
    return src, base


GOOD = [f"{i},{i + 1},{i % 2}\n" for i in range(20)]
HEAD = "t,taxel_12,taxel_13\n"


def _lines(before: int, bad: str) -> str:
    """A header, ``before`` good rows, the bad row, more good rows: the bad row is line before + 2."""
    return HEAD + "".join(GOOD[:before]) + bad + "".join(GOOD[before:])


@pytest.mark.parametrize(
    "text, extra, message",
    [
        (
            _lines(15, "# a comment, then a blank line\n\n7,abc,3\n"),
            {},
            r"r.csv: line 19: column 'taxel_12': non-numeric value 'abc'",
        ),
        (_lines(6, "7,,3\n"), {}, r"r.csv: line 8: column 'taxel_12': empty value$"),
        (_lines(6, "7,nan,3\n"), {}, r"r.csv: line 8: column 'taxel_12': non-numeric value 'nan'$"),
        (_lines(6, "7,NA,3\n"), {}, r"r.csv: line 8: column 'taxel_12': non-numeric value 'NA'$"),
        (
            _lines(6, "7,1\n"),
            {},
            r"r.csv: line 8: 2 fields, but the header \(line 1\) names 3 columns: a short row",
        ),
        (_lines(6, "7,inf,3\n"), {}, r"r.csv: line 8: column 'taxel_12': non-finite value 'inf'$"),
        (
            _lines(6, "7,-Infinity,3\n"),
            {},
            r"r.csv: line 8: column 'taxel_12': non-finite value '-Infinity'$",
        ),
        (
            _lines(6, "7,1,3,4\n"),
            {},
            r"r.csv: line 8: 4 fields, but the header \(line 1\) names 3 columns: value '4' has no column",
        ),
        (
            "t,taxel_12,taxel_13\n" + "0,1,2\n1,2,3\n1,3,3\n",
            {"rate": {"time_column": "t"}},
            r"r.csv: line 4: column 't': time does not increase",
        ),
        (
            "t,taxel_12,state\n" + "0,1,hold\n1,2,hold\n2,2,slide\n",
            {"labels": {"column": "state", "slip": ["slip"], "no_slip": ["hold"]}},
            r"r.csv: line 4: column 'state': label 'slide' is not one of",
        ),
        ("t,x\n0,1\n1,2\n", {}, r"r.csv: no column matches the channel pattern"),
        ("t,taxel_1\n0,1\n", {}, r"r.csv: 1 data row\(s\); a recording needs at least 2"),
        ("", {}, r"r.csv: empty file"),
        (
            "t,taxel_1\n0,1\n1,2\n",
            {"recording": {"scenario": "hold-slip"}},
            r"r.csv: scenario hold-slip needs per-sample labels",
        ),
        (
            "t,taxel_1\n0,1\n1,2\n",
            {"channels": {"pattern": r"taxel_\d+", "count": 48}},
            r"r.csv: 1 channel columns .* the mapping expects 48",
        ),
        (
            "t,taxel_1\n0,99999999999999999\n1,2\n",
            {},
            r"r.csv: line 2: column 'taxel_1': integer 99999999999999999 beyond 2\*\*53",
        ),
    ],
)
def test_bad_files_are_named_by_line_and_column(tmp_path, text, extra, message):
    src, mapping = _one_file(tmp_path, text, **extra)
    with pytest.raises(DataError, match=message):
        import_csv(src, tmp_path / "out", mapping)
    assert not (tmp_path / "out").exists()


def test_rates_beyond_tolerance_name_the_recordings(tmp_path):
    src = tmp_path / "src"
    for name, rate in (("slow", 50.0), ("fast", 60.0)):
        _write(
            src / f"{name}.csv", pd.DataFrame({"t": np.arange(10) / rate, "taxel_0": np.arange(10)})
        )
    mapping = {
        "recording": {"sensor_type": "S", "sensor_instance": "u", "scenario": "slip"},
        "channels": {"pattern": "taxel_.*"},
        "rate": {"time_column": "t"},
    }
    with pytest.raises(
        DataError,
        match=r"sensor 'S' unit 'u': sampling rates differ by 20 %.*lowest 50 Hz in recording\(s\) 'slow'.*"
        r"highest 60 Hz in recording\(s\) 'fast'",
    ):
        import_csv(src, tmp_path / "out", mapping)


@pytest.mark.parametrize(
    "mapping, message",
    [
        ({"chanels": {}}, r"unknown key 'chanels' in the mapping"),
        (
            {"channels": {"names": ["a"], "pattern": "b"}},
            r"\[channels\] needs exactly one of names",
        ),
        (
            {"channels": {"names": ["taxel_0"]}, "labels": {"column": "state"}},
            r"\[labels\].column needs slip",
        ),
        (
            {"channels": {"names": ["taxel_0"]}, "rules": [{"scenario": "press"}]},
            r"\[\[rules\]\] #1 needs a glob or a regex",
        ),
        (
            {"channels": {"names": ["taxel_0"]}, "rate": {"hz": -5}},
            r"\[rate\].hz must be a number > 0",
        ),
        (
            {"channels": {"names": ["taxel_0"]}, "recording": {"regex": "("}},
            r"\[recording\].regex '\(' is not a regular expression",
        ),
        (
            {"channels": [{"names": ["taxel_0"]}, {"names": ["taxel_1"]}]},
            r"\[\[channels\]\] #1 needs sensor_instance",
        ),
    ],
)
def test_bad_mappings_name_the_key(mapping, message):
    with pytest.raises(UsageError, match=message):
        load_mapping(mapping)


def test_mapping_problems_found_while_importing(tmp_path):
    src = tmp_path / "src"
    for name in ("a/x.csv", "b/x.csv"):
        _write(src / name, pd.DataFrame({"taxel_0": [1, 2, 3]}))
    mapping = {
        "recording": {
            "sensor_type": "S",
            "sensor_instance": "u",
            "scenario": "slip",
            "recording_id": "{stem}",
        },
        "channels": {"names": ["taxel_0"]},
        "rate": {"hz": 60},
    }
    with pytest.raises(UsageError, match=r"a/x.csv and b/x.csv both give recording_id 'x'"):
        import_csv(src, tmp_path / "out", mapping)
    with pytest.raises(
        UsageError, match=r"material = '\{objekt\}': no value for 'objekt' in a/x.csv"
    ):
        import_csv(
            src,
            tmp_path / "out",
            {
                **mapping,
                "recording": {
                    **mapping["recording"],
                    "recording_id": "{path}",
                    "material": "{objekt}",
                },
            },
        )
    with pytest.raises(UsageError, match=r"no scenario for a/x.csv"):
        import_csv(
            src,
            tmp_path / "out",
            {**mapping, "recording": {"sensor_type": "S", "sensor_instance": "u"}},
        )
    with pytest.raises(DataError, match=r"a/x.csv: the path does not match \[recording\].regex"):
        import_csv(
            src,
            tmp_path / "out",
            {
                **mapping,
                "recording": {**mapping["recording"], "recording_id": "{path}", "regex": "b/.*"},
            },
        )
    with pytest.raises(UsageError, match=r"files = '/etc/\*': a glob selects files under SRC"):
        import_csv(src, tmp_path / "out", {**mapping, "files": "/etc/*"})
    with pytest.raises(DataError, match=r"no file matches files = \['\*\.txt'\]"):
        import_csv(src, tmp_path / "out", {**mapping, "files": "*.txt"})
    assert not (tmp_path / "out").exists()


def test_cli_import_and_validate(tmp_path, cli):
    _taxel_trials(tmp_path / "src", n_trials=2)
    (tmp_path / "mapping.toml").write_text(_toml_block("taxel_"))
    code, out, err = cli(["dataset", "import", "csv", str(tmp_path / "src"), str(tmp_path / "out")])
    assert code == 2 and "needs --config" in err
    code, out, err = cli(
        [
            "dataset",
            "import",
            "csv",
            str(tmp_path / "src"),
            str(tmp_path / "out"),
            "--config",
            str(tmp_path / "mapping.toml"),
        ]
    )
    assert code == 0, err
    code, out, err = cli(["dataset", "validate", str(tmp_path / "out")])
    assert code == 0 and "2 recordings in 2 trials" in out
    bad = tmp_path / "src" / "taxels" / "wood" / "trial_1.csv"
    bad.write_text(bad.read_text().replace("\n", "\n1,x," + "1," * 47 + "hold\n", 1))
    code, out, err = cli(
        [
            "dataset",
            "import",
            "csv",
            str(tmp_path / "src"),
            str(tmp_path / "out2"),
            "--config",
            str(tmp_path / "mapping.toml"),
        ]
    )
    assert code == 2 and "trial_1.csv: line 2: column 'taxel_0': non-numeric value 'x'" in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "out2").exists()


# ----------------------------------------------------------------------------- CSV shapes: never a shifted column
def _pac_ele(
    rows_end: str, header_end: str, newline: str = "\n", bom: str = ""
) -> tuple[str, np.ndarray]:
    """A BioTac-like file: t, pac1..pac22, ele1..ele19, with the given line ends; and its
    numbers (t, pac, ele), each column distinct so that a shift shows."""
    names = ["t"] + [f"pac{i}" for i in range(1, 23)] + [f"ele{i}" for i in range(1, 20)]
    values = np.arange(5)[:, None] * 1000 + np.arange(len(names))[None, :]
    values[:, 0] = np.arange(5) * 10  # t in ms at 100 Hz
    lines = [",".join(names) + header_end] + [",".join(map(str, r)) + rows_end for r in values]
    return bom + newline.join(lines) + newline, values


@pytest.mark.parametrize(
    "rows_end, header_end, newline, bom",
    [
        (",", "", "\n", ""),  # the files: every row ends in a comma, the header does not
        (",", ",", "\n", ""),  # both end in a comma
        ("", ",", "\n", ""),  # only the header does
        (",,", "", "\r\n", "\ufeff"),  # two trailing commas, Windows line ends, a byte-order mark
    ],
)
def test_trailing_delimiters_are_read_unshifted(tmp_path, rows_end, header_end, newline, bom):
    text, values = _pac_ele(rows_end, header_end, newline, bom)
    src = tmp_path / "src"
    src.mkdir()
    (src / "r.csv").write_bytes(text.encode())
    base = {
        "recording": {"sensor_type": "BioTac", "sensor_instance": "ff", "scenario": "slip"},
        "rate": {"time_column": "t", "time_unit": "ms"},
    }
    by_pattern = read_dataset(
        import_csv(src, tmp_path / "p", {**base, "channels": {"pattern": r"pac\d+", "count": 22}})
    )
    np.testing.assert_array_equal(by_pattern.samples["r"], values[:, 1:23])  # pac1 holds pac1
    assert by_pattern.recordings["sampling_rate_hz"].iloc[0] == 100.0
    by_name = read_dataset(
        import_csv(src, tmp_path / "n", {**base, "channels": {"names": ["ele1", "ele19"]}})
    )
    np.testing.assert_array_equal(by_name.samples["r"], values[:, [23, 41]])  # ele19 is not empty


@pytest.mark.parametrize(
    "text, message",
    [
        # every row has one value more than the header names: a name is missing
        (
            "a,b,c\n1,2,3,4\n5,6,7,8\n",
            r"line 2: 4 fields, but the header \(line 1\) names 3 columns: value '4' has no column",
        ),
        # the header ends in a comma, but the rows hold a value there: a nameless column
        (
            "a,b,c,\n1,2,3\n5,6,7,8\n",
            r"line 3: 4 fields, but the header \(line 1\) names 3 columns: value '8'",
        ),
        # one ragged row among trailing-comma rows, after skipped and comment lines
        (
            "logger v2\n# units: N\na,b,c\n1,2,3,\n\n5,6\n",
            r"line 6: 2 fields, but the header \(line 3\) names 3 columns: a short row",
        ),
        (
            "a,b,a\n1,2,3\n4,5,6\n",
            r"line 1: column name 'a' appears twice in the header \(columns 1 and 3\)",
        ),
        (",,\n1,2,3\n", r"line 1: the header names no column"),
    ],
)
def test_ragged_rows_are_refused_by_line(tmp_path, text, message):
    src = tmp_path / "src"
    src.mkdir()
    (src / "r.csv").write_text(text)
    mapping = {
        "skip_rows": 1 if text.startswith("logger") else 0,
        "comment": "#",
        "recording": {"sensor_type": "S", "sensor_instance": "u", "scenario": "slip"},
        "channels": {"names": ["a", "b"]},
        "rate": {"hz": 100},
    }
    with pytest.raises(DataError, match=r"r\.csv: " + message):
        import_csv(src, tmp_path / "out", mapping)
    assert not (tmp_path / "out").exists()


# ----------------------------------------------------------------------------- hold-slip trials, per-file labels
def _holds(src: Path, names: dict[str, list[str]]) -> None:
    for name, states in names.items():
        _write(src / name, pd.DataFrame({"p": np.arange(len(states)) % 5, "state": states}))


def test_hold_slip_trial_that_never_slips_is_kept(tmp_path):
    src = tmp_path / "src"
    _holds(src, {"held.csv": ["hold"] * 30, "slipped.csv": ["hold"] * 10 + ["slip"] * 20})
    mapping = {
        "recording": {"sensor_type": "P", "sensor_instance": "u", "scenario": "hold-slip"},
        "channels": {"names": ["p"]},
        "rate": {"hz": 100},
        "labels": {
            "column": "state",
            "slip": ["slip"],
            "no_slip": ["hold"],
            "unlabelled": ["drop"],
        },
    }
    ds = read_dataset(import_csv(src, tmp_path / "out", mapping))
    assert ds.slip_labels["held"].tolist() == [0] * 30  # all of it hold, as the reader keeps it
    # from segments: a file without one is no-slip throughout where unlisted says so
    plain = {**mapping, "labels": {"unlisted": "no-slip"}, "channels": {"names": ["p"]}}
    ds = read_dataset(import_csv(src, tmp_path / "seg", plain))
    assert (ds.slip_labels["held"] == 0).all()
    _holds(src, {"held.csv": ["drop"] * 30})  # no hold at all: refused, naming the file
    with pytest.raises(
        DataError, match=r"held.csv: scenario hold-slip: no sample labelled no-slip"
    ):
        import_csv(src, tmp_path / "bad", mapping)


def test_after_offset_per_file_and_per_segment(tmp_path):
    """Drops are unlabelled after the slip by default of this mapping; one file holds again after
    its slip (a rule says so), and one segment of the table is followed by an unlabelled stretch."""
    src = tmp_path / "src"
    for name in ("drop.csv", "regrip.csv", "twice.csv"):
        _write(src / name, pd.DataFrame({"p": np.arange(100) % 7}))
    pd.DataFrame(
        {
            "file": ["drop.csv", "regrip.csv", "twice.csv", "twice.csv"],
            "onset": [40, 40, 10, 60],
            "offset": [70, 70, 20, 80],
            "after_offset": ["", "", "unlabelled", "no-slip"],
        }
    ).to_csv(tmp_path / "seg.csv", index=False)
    mapping = {
        "recording": {"sensor_type": "P", "sensor_instance": "u", "scenario": "hold-slip"},
        "rules": [{"glob": "regrip.csv", "after_offset": "no-slip"}],
        "channels": {"names": ["p"]},
        "rate": {"hz": 100},
        "labels": {"segments": "seg.csv", "after_offset": "unlabelled"},
    }
    ds = read_dataset(import_csv(src, tmp_path / "out", mapping, base=tmp_path))
    assert ds.slip_labels["drop"].tolist() == [0] * 40 + [1] * 30 + [-1] * 30
    assert ds.slip_labels["regrip"].tolist() == [0] * 40 + [1] * 30 + [0] * 30
    assert ds.slip_labels["twice"].tolist() == [0] * 10 + [1] * 10 + [-1] * 40 + [1] * 20 + [0] * 20
    bad = {**mapping, "rules": [{"glob": "regrip.csv", "after_offset": "hold"}]}
    with pytest.raises(
        UsageError, match=r"after_offset of .*regrip.csv is 'hold'; it must be one of"
    ):
        import_csv(src, tmp_path / "bad", bad, base=tmp_path)
    table = pd.read_csv(tmp_path / "seg.csv").fillna("")
    table.loc[2, "after_offset"] = "dropped"
    table.to_csv(tmp_path / "seg.csv", index=False)
    with pytest.raises(
        DataError, match=r"seg.csv: line 4: column 'after_offset': 'dropped' is not one of"
    ):
        import_csv(src, tmp_path / "bad", mapping, base=tmp_path)


# ----------------------------------------------------------------------------- fields from metadata files
def _sessions(src: Path, rates: dict[str, float]) -> None:
    for session, rate in rates.items():
        for k in (1, 2):
            t = np.arange(50) / rate
            _write(
                src / session / f"trial_{k}.csv", pd.DataFrame({"p": np.round(np.sin(t * 7), 6)})
            )


BASE = {
    "files": "*/*.csv",
    "recording": {"sensor_type": "P", "sensor_instance": "u", "scenario": "slip"},
    "channels": {"names": ["p"]},
}


def test_rate_from_a_metadata_file_per_folder(tmp_path):
    src = tmp_path / "src"
    _sessions(src, {"monday": 120.0, "tuesday": 119.5})
    (src / "monday" / "info.json").write_text('{"logger": "v2", "rate_hz": 120}')
    (src / "tuesday" / "info.json").write_text('{"logger": "v2", "rate_hz": 119.5}')
    mapping = {
        **BASE,
        "metadata": [{"table": "{parent}/info.json", "fields": {"sampling_rate_hz": "rate_hz"}}],
    }
    rec = read_dataset(import_csv(src, tmp_path / "out", mapping)).recordings
    assert dict(zip(rec["recording_id"], rec["sampling_rate_hz"])) == {
        "monday/trial_1": 120.0,
        "monday/trial_2": 120.0,
        "tuesday/trial_1": 119.5,
        "tuesday/trial_2": 119.5,
    }
    (src / "tuesday" / "info.json").unlink()
    with pytest.raises(
        DataError,
        match=r"tuesday/info.json: not found \(\[\[metadata\]\] #1.table for tuesday/trial_1.csv\)",
    ):
        import_csv(src, tmp_path / "bad", mapping)


def test_rate_and_speed_from_one_table_keyed_by_file_name(tmp_path):
    src = tmp_path / "src"
    _sessions(src, {"a": 60.0, "b": 60.0})
    (src / "log.csv").write_text(
        "file,hz,speed\n"
        "a/trial_1.csv,60,10\na/trial_2.csv,59.9,20\nb/trial_1.csv,60.1,\nb/trial_2.csv,60,40\n"
    )
    entry = {
        "table": "log.csv",
        "key": "file",
        "fields": {"sampling_rate_hz": "hz", "speed_mm_s": "speed"},
    }
    rec = read_dataset(import_csv(src, tmp_path / "out", {**BASE, "metadata": [entry]})).recordings
    assert rec["sampling_rate_hz"].tolist() == [60.0, 59.9, 60.1, 60.0]
    assert rec["speed_mm_s"].tolist()[:2] == [10.0, 20.0] and np.isnan(rec["speed_mm_s"].iloc[2])
    # keyed by a column from the path: a TOML list of sessions
    (src / "sessions.toml").write_text(
        '[[session]]\nname = "a"\nrate = 50\n[[session]]\nname = "b"\nrate = 50.5\n'
    )
    by_session = {
        "table": "sessions.toml",
        "key": "name",
        "match": "{parent}",
        "fields": {"sampling_rate_hz": "rate"},
    }
    rec = read_dataset(
        import_csv(src, tmp_path / "toml", {**BASE, "metadata": [by_session]})
    ).recordings
    assert rec["sampling_rate_hz"].tolist() == [50.0, 50.0, 50.5, 50.5]
    # a record missing, twice, or the table imported as a recording: named
    entry = {**entry, "fields": {"sampling_rate_hz": "hz"}}
    (src / "log.csv").write_text("file,hz\na/trial_1.csv,60\n")
    with pytest.raises(
        DataError, match=r"log.csv: no record with file = 'a/trial_2.csv', for a/trial_2.csv"
    ):
        import_csv(src, tmp_path / "bad", {**BASE, "metadata": [entry]})
    (src / "log.csv").write_text("file,hz\na/trial_1.csv,60\na/trial_1.csv,61\n")
    with pytest.raises(
        DataError, match=r"log.csv: line 2 and .*log.csv: line 3: both have file = 'a/trial_1.csv'"
    ):
        import_csv(src, tmp_path / "bad", {**BASE, "metadata": [entry]})
    with pytest.raises(
        UsageError, match=r"the table log.csv is also selected as a recording by files"
    ):
        import_csv(src, tmp_path / "bad", {**BASE, "files": "**/*.csv", "metadata": [entry]})
    with pytest.raises(UsageError, match=r"\[\[metadata\]\] #1.fields: 'rate' is not a field"):
        load_mapping({**BASE, "metadata": [{"table": "x.csv", "fields": {"rate": "hz"}}]})


def test_a_csv_name_not_utf8_and_a_json_key_twice_are_named(tmp_path):
    """The importers' share of the column-name faults: a bit flip that leaves a header byte
    that is not UTF-8 (named by line and column), and a metadata key given twice (json keeps
    the last one without a word)."""
    src = tmp_path / "src"
    _sessions(src, {"monday": 120.0})
    data = bytearray((src / "monday" / "trial_2.csv").read_bytes())
    data[0] ^= 0x80  # 'p' -> 0xf0: the header's first name is no longer UTF-8
    (src / "monday" / "trial_2.csv").write_bytes(bytes(data))
    with pytest.raises(
        DataError, match=r"trial_2.csv: line 1, column 1: byte 0 \(0xf0\) is not UTF-8 text"
    ):
        import_csv(src, tmp_path / "bad", {**BASE, "rate": {"hz": 120}})
    (src / "monday" / "trial_2.csv").unlink()
    (src / "monday" / "info.json").write_text('{"rate_hz": 120, "rate_hz": 12}')
    mapping = {
        **BASE,
        "metadata": [{"table": "{parent}/info.json", "fields": {"sampling_rate_hz": "rate_hz"}}],
    }
    with pytest.raises(
        DataError, match=r"info.json: not valid JSON \(key 'rate_hz' is given twice"
    ):
        import_csv(src, tmp_path / "bad", mapping)
    assert not (tmp_path / "bad").exists()


def _two_settings(src: Path) -> None:
    """Files of two fingers logged at two rate settings, the setting in the folder's name."""
    for rate in (50, 60):
        for k in range(2):
            t = np.arange(40) / rate
            frame = pd.DataFrame({"t": t, "a0": np.arange(40) % 7, "b0": np.arange(40) % 5})
            _write(src / f"{rate}hz" / f"trial_{k}.csv", frame)


def _settings_mapping(instance: str) -> dict:
    return {
        "files": ["*/*.csv"],
        "recording": {
            "regex": r"(?P<rate>\d+)hz/trial_\d\.csv",
            "sensor_type": "Pad",
            "scenario": "slip",
        },
        "channels": [
            {"sensor_instance": f"left-{instance}", "names": ["a0"]},
            {"sensor_instance": f"right-{instance}", "names": ["b0"]},
        ],
        "rate": {"time_column": "t"},
    }


def test_channel_groups_take_templates_as_recording_fields_do(tmp_path):
    """The rate refusal's advice (a sensor_instance per setting) works in [[channels]]: its
    templates are filled from the file's path, and a misspelled one is refused."""
    _two_settings(tmp_path / "src")
    ds = read_dataset(import_csv(tmp_path / "src", tmp_path / "out", _settings_mapping("{rate}")))
    units = ds.recordings.groupby("sensor_instance")["sampling_rate_hz"].unique()
    assert {k: v.tolist() for k, v in units.items()} == {
        "left-50": [50.0],
        "left-60": [60.0],
        "right-50": [50.0],
        "right-60": [60.0],
    }
    with pytest.raises(
        UsageError,
        match=r"\[\[channels\]\] #1.sensor_instance = 'left-\{rtae\}': no value for 'rtae' in "
        r"50hz/trial_0.csv \(known: file, name, parent, path, rate, stem\)",
    ):
        import_csv(tmp_path / "src", tmp_path / "no", _settings_mapping("{rtae}"))
