"""The Parquet dataset format, version 1: its files, columns and the limits the reader holds.

A dataset is a folder holding two Parquet files (see ``datasets.md``):

``recordings.parquet``
    one row per recording: ``recording_id``, ``sensor_type``, ``sensor_instance``,
    ``scenario`` (one of :data:`SCENARIOS`), ``material``, ``speed_mm_s``, ``sampling_rate_hz``,
    ``channels``, ``units``, ``source`` and optionally ``trial`` and ``univariate_channels``.
``samples.parquet``
    one row per sample: ``recording_id``, ``sample_index`` (0, 1, ... per recording, rows in any
    order), ``values`` (one number per channel) and optionally ``slip`` (bool; null = unlabelled).

Both files carry ``slipbench.format_version = "1"`` in their schema metadata; written by
:func:`~slipbench.data.write.write_dataset`, also the content fingerprint (and the recordings
file a digest of its table), and a CRC checksum on every page. This module only
names the layout; :mod:`slipbench.data.read` and :mod:`slipbench.data.write` hold the files to it.
"""

from __future__ import annotations

import pyarrow as pa

from slipbench.vocabulary import SENSOR_TYPE, SLIPS

FORMAT_VERSION = "1"
VERSION_KEY = b"slipbench.format_version"
# Written since page checksums came in (readers verify them where stored): the content
# fingerprint in both files' metadata, and a digest of the recordings table in recordings.parquet.
FINGERPRINT_KEY = b"slipbench.fingerprint"
RECORDINGS_DIGEST_KEY = b"slipbench.recordings_digest"
# What the dataset is and how to cite it, where its writer knows (`dataset fetch` writes both,
# from the dataset's card): free text in recordings.parquet's metadata, outside the fingerprint.
SOURCE_KEY = b"slipbench.source"
CITATION_KEY = b"slipbench.citation"
RECORDINGS_FILE = "recordings.parquet"
SAMPLES_FILE = "samples.parquet"
FORMAT_KEYS = frozenset({VERSION_KEY, FINGERPRINT_KEY, RECORDINGS_DIGEST_KEY})
SCENARIOS = ("slip", "press", "free-space", "hold-slip")
# Rates of one unit may differ by this fraction of the lowest and still pool (at their median).
# A logger's clock and dropped frames move a nominal 60 Hz between 59.7 and 60.0 Hz (0.5 %);
# a changed rate setting moves it by far more (50 -> 60 Hz is 20 %). 1 % moves a 100 ms window
# by at most 1 ms and a frequency by 1 %, less than one bin of a window shorter than 100 samples.
RATE_TOLERANCE = 0.01
# Integers beyond 2**53 have no exact float64: refused rather than rounded.
EXACT_INT = 2**53
# A sample's magnitude at most, whatever its type: 2**53 (9.0e15) leaves a detector's arithmetic
# room (a fourth power summed over 10**18 values stays finite in float64, a square in float32:
# 8.1e31 < 3.4e38); beyond, it overflows to infinity and the detector is blamed for the data.
MAX_MAGNITUDE = float(EXACT_INT)

RECORDINGS_SCHEMA = pa.schema(
    [
        ("recording_id", pa.string()),
        (SENSOR_TYPE, pa.string()),
        ("sensor_instance", pa.string()),
        ("scenario", pa.string()),
        ("material", pa.string()),
        ("speed_mm_s", pa.float64()),
        ("sampling_rate_hz", pa.float64()),
        ("channels", pa.list_(pa.string())),
        ("units", pa.list_(pa.string())),
        ("source", pa.string()),
        ("trial", pa.string()),
    ]
)
FORMAT_COLUMNS = tuple(RECORDINGS_SCHEMA.names)
# Columns that may be absent from the file: a recording is then its own trial; its length is
# then not checked (written by write_dataset, it catches rows lost at a recording's end); the
# univariate signal then uses all its channels.
OPTIONAL = {"trial", "n_samples", "univariate_channels"}
N_SAMPLES = pa.field("n_samples", pa.int64())
# The channels the paper's reduction s_t = ||a_t|| - ||a_{t-1}|| uses (a BioTac SP's pac, beside
# its electrodes); absent, null or empty: all of them. Outside FORMAT_COLUMNS so that a dataset
# without it keeps its fingerprint; the fingerprint hashes it where a recording names any.
UNIVARIATE_CHANNELS = pa.field("univariate_channels", pa.list_(pa.string()))
# Columns that may hold nulls: free-space has no material, pressing has no speed.
NULLABLE = {"material", "speed_mm_s", "source", "trial"}
STRING_COLUMNS = (
    "recording_id",
    SENSOR_TYPE,
    "sensor_instance",
    "scenario",
    "material",
    "source",
    "trial",
)
# Derived by the reader: channels per recording, the rate every recording of a unit pools at, and
# whether the recording slips at all (SLIPS: a hold-slip trial may hold throughout).
DERIVED_COLUMNS = ("n_channels", "unit_rate_hz", "n_samples", SLIPS)
IN_MEMORY = "in-memory dataset"
