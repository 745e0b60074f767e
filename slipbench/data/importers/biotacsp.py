"""The published BioTac SP direction-of-slip dataset (BioTacSP-DoS, Zapata-Impata, Gil, Torres,
Sensors 19(3):523, 2019) as a mapping of the CSV importer."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import tomllib

from slipbench.data.importers.csv import import_csv

BIOTACSP_DOS_MAPPING = r"""
# BioTacSP-DoS (Zapata-Impata, Gil, Torres, Sensors 19(3):523, 2019): its csvs/ folder.
files = ["n/*.csv", "e/*.csv", "s/*.csv", "w/*.csv", "cw/*.csv", "aw/*.csv", "t/*.csv"]

[recording]
regex = '(?P<direction>[a-z]+)/(?P<material>.+?)\d*\.csv'   # folder = class, file = object + number
sensor_type = "BioTacSP"
sensor_instance = "ff"
scenario = "slip"
source = "BioTacSP-DoS (Zapata-Impata et al. 2019), direction {direction}"

[[rules]]
glob = "t/*.csv"          # touch: stable contact without slip
scenario = "press"

[map.material]
strippes = "striped"      # one file name misspells the striped object

[channels]
pattern = 'ff_e\d+'
count = 24
units = "raw"

[rate]
hz = 100.0
"""


def biotacsp_dos(
    src: str | Path,
    out: str | Path,
    rate_hz: float = 100.0,
    description: Mapping[bytes, str] | None = None,
) -> Path:
    """Import BioTacSP-DoS (Zapata-Impata, Gil, Torres, Sensors 19(3):523, 2019).

    ``src`` is its ``csvs`` folder: one subfolder per class (``n e s w cw aw``: slip, ``t``:
    touch), one CSV per recording with the 24 electrode channels ``ff_e1..ff_e24``. Slip folders
    become scenario ``slip``, touch becomes ``press``; the object (the file name without its
    running number; "strippes" is the striped object) becomes ``material``; speed is unknown.
    It is :data:`BIOTACSP_DOS_MAPPING` run through :func:`import_csv`; ``description`` goes to
    the dataset's metadata (``dataset fetch`` passes the card's source and citation).
    """
    mapping = tomllib.loads(BIOTACSP_DOS_MAPPING)
    mapping["rate"]["hz"] = rate_hz
    return import_csv(src, out, mapping, description=description)
