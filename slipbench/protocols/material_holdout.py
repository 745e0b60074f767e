"""Material (Van Wyk & Falco, section VII.A, Table III): window 50 at full rate. Per material,
the model trained on all materials is tested on that material's test windows (slip at every
speed plus pressing on it), and a model trained without any data on that material (slip or
pressing; free-space has no material and stays) is tested on the same windows: the paper's
starred numbers."""

from __future__ import annotations

from slipbench.protocol import HoldoutProtocol, Layout, Presentation
from slipbench.vocabulary import MATERIALS, SENSOR_TYPE


class MaterialHoldout(HoldoutProtocol):
    """Each material with and without explicit training (the paper's Table III)."""

    layout = Layout(rows=(SENSOR_TYPE, "sensor_instance"), column="material", pair="training")
    presentation = Presentation(
        "Slip state classification with and without (*) explicit training of indicated materials "
        "across sensors.",
        title="Material",
        group="with Material",
        figure="with-without",
        paper_table="material-holdout",
    )
    holdout_column = "material"

    def levels(self, recordings):
        return sorted(recordings["material"].dropna().unique(), key=_paper_order)


def _paper_order(material: str):
    return (MATERIALS.index(material), "") if material in MATERIALS else (len(MATERIALS), material)
