"""Importers from published tactile slip datasets into the slipbench format."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd

from .data import write_dataset
from .errors import DataError

BIOTACSP_DOS_SLIP = ("n", "e", "s", "w", "cw", "aw")  # translational and rotational slip directions
BIOTACSP_DOS_TOUCH = "t"  # stable contact without slip


def biotacsp_dos(src: str | Path, out: str | Path, rate_hz: float = 100.0) -> Path:
    """Import BioTacSP-DoS (Zapata-Impata, Gil, Torres, Sensors 19(3):523, 2019).

    ``src`` is its ``csvs`` folder: one subfolder per class (``n e s w cw aw``: slip, ``t``:
    touch), one CSV per recording with the 24 electrode channels ``ff_e1..ff_e24``. Slip folders
    become scenario ``slip``, touch becomes ``press``; the object (the file name without its
    running number; "strippes" is the striped object) becomes ``material``; speed is unknown.
    """
    src = Path(src)
    rows, samples = [], {}
    for folder in (*BIOTACSP_DOS_SLIP, BIOTACSP_DOS_TOUCH):
        for path in sorted((src / folder).glob("*.csv")):
            frame = pd.read_csv(path)
            channels = [c for c in frame.columns if c.startswith("ff_e")]
            if len(channels) != 24:
                raise DataError(f"{path}: expected 24 electrode columns ff_e1..ff_e24, found {len(channels)}")
            obj = re.sub(r"\d+$", "", path.stem).replace("strippes", "striped")
            rid = f"{folder}/{path.stem}"
            samples[rid] = frame[channels].to_numpy(dtype=np.float32)
            rows.append(dict(
                recording_id=rid, sensor_type="BioTacSP", sensor_instance="ff",
                scenario="press" if folder == BIOTACSP_DOS_TOUCH else "slip", material=obj, speed_mm_s=None,
                sampling_rate_hz=rate_hz, channels=tuple(channels), units=("raw",) * 24,
                source="BioTacSP-DoS (Zapata-Impata et al. 2019), direction " + folder,
            ))
    if not rows:
        raise DataError(f"{src}: no BioTacSP-DoS recordings (expected class folders {', '.join(BIOTACSP_DOS_SLIP)}, t of CSV files)")
    return write_dataset(out, pd.DataFrame(rows), samples)


IMPORTERS = {"biotacsp-dos": biotacsp_dos}
