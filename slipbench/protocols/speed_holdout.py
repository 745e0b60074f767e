"""Slip speed (Van Wyk & Falco, section VII.B, Table IV): window 50 at full rate. Per slip
speed, the model trained on all speeds and a model trained without that speed are tested on
that speed's test windows.

The paper pools non-slip data per arm speed, but pressing has no speed. Here each pressing
recording is assigned to one slip speed (column ``speed_group``): within its unit and material,
longest first, to the speed with the least pressing time so far, so every speed's test set holds
slip at that speed, free-space motion at that speed (there is none at 5 mm/s) and an equal share
of pressing time on every material (equal to within one recording). Training
"without" a speed drops the slip and free-space windows at that speed; pressing, having no
speed, stays. Across two datasets, each dataset's pressing goes to its own slip speeds.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from slipbench.protocol import HoldoutProtocol, Layout, Presentation
from slipbench.vocabulary import DATASET_SIDE, SENSOR_TYPE, SLIPS


def _speeds(recordings) -> list[float]:
    """The slip speeds: those of recordings that slip (a hold-slip trial that held throughout
    was never at its speed's slip)."""
    slipping = recordings[SLIPS].to_numpy(bool)
    return sorted(float(s) for s in recordings.loc[slipping, "speed_mm_s"].dropna().unique())


class SpeedHoldout(HoldoutProtocol):
    """Each slip speed with and without explicit training (the paper's Table IV)."""

    layout = Layout(rows=(SENSOR_TYPE, "sensor_instance"), column="speed_mm_s", pair="training")
    presentation = Presentation(
        "Slip state classification with and without (*) explicit training of indicated speeds "
        "across sensors.",
        title="Slip speed",
        group="at Speed",
        figure="with-without",
        paper_table="speed-holdout",
    )
    holdout_column = "speed_mm_s"
    test_column = "speed_group"  # pressing has no speed: columns() assigns it one

    def columns(self, recordings):
        if DATASET_SIDE not in recordings:
            return {"speed_group": self._groups(recordings)}
        # across two datasets, each side's pressing is shared among the speeds of that side
        group = recordings["speed_mm_s"].to_numpy(dtype=float).copy()
        for side in recordings[DATASET_SIDE].unique():
            rows = np.flatnonzero(recordings[DATASET_SIDE].eq(side).to_numpy())
            group[rows] = self._groups(recordings.iloc[rows])
        return {"speed_group": group}

    def _groups(self, recordings):
        speeds = _speeds(recordings)
        group = recordings["speed_mm_s"].to_numpy(dtype=float).copy()
        if not speeds:
            return group
        press = recordings[recordings["scenario"] == "press"]
        length = press["n_samples"] if "n_samples" in press else pd.Series(1, index=press.index)
        press = press.assign(_length=length).sort_values(
            ["_length", "recording_id"], ascending=[False, True]
        )
        for _, part in press.groupby(
            [SENSOR_TYPE, "sensor_instance", "material"], sort=False, dropna=False
        ):
            held = np.zeros(len(speeds))
            for index, n in zip(part.index, part["_length"]):
                turn = int(np.argmin(held))  # ties go to the slower speed
                held[turn] += n
                group[recordings.index.get_loc(index)] = speeds[turn]
        return group

    def levels(self, recordings):
        return _speeds(recordings)

    def why_no_cells(self, recordings):
        slipping = recordings[SLIPS].to_numpy(bool)
        if not slipping.any():
            return (
                f"no recording slips (scenarios {', '.join(sorted(set(recordings['scenario'])))}; "
                "slip speeds come from slip recordings and hold-slip trials that slip)"
            )
        return (
            f"none of its {int(slipping.sum())} slip recordings gives a speed (speed_mm_s is "
            "empty): there is no slip speed to hold out"
        )
