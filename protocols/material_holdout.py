"""Material (Van Wyk & Falco, section VII.A, Table III): window 50 at full rate. Per material,
the model trained on all materials is tested on that material's test windows (slip at every
speed plus pressing on it), and a model trained without any data on that material (slip or
pressing; free-space has no material and stays) is tested on the same windows: the paper's
starred numbers."""

from __future__ import annotations

from slipbench.base import BaseProtocol, Cell, Part
from slipbench.data import sensor_pairs

WINDOW = 50


def holdout_cells(recordings, name: str, levels, test_column: str | None = None, window: int = WINDOW):
    """Cells "with" and "without" explicit training on each level of column ``name``, per sensor.

    Test windows are those whose ``test_column`` (default: ``name``) equals the level; the
    "without" model trains on windows whose ``name`` differs from it.
    """
    for sensor in sensor_pairs(recordings):
        for level in levels:
            test = Part((sensor,), "test", ((test_column or name, "==", level),))
            key = {"sensor_type": sensor[0], "sensor_instance": sensor[1], name: level}
            yield Cell({**key, "training": "with"}, Part((sensor,), "train"), test, window)
            yield Cell({**key, "training": "without"}, Part((sensor,), "train", ((name, "!=", level),)), test, window)


class MaterialHoldout(BaseProtocol):
    name = "material-holdout"
    table = {
        "title": "Slip state classification accuracy (%) with and without (*) explicit training of each material",
        "rows": ["sensor_type", "sensor_instance"], "columns": "material", "pair": "training",
    }

    def cells(self, recordings):
        materials = sorted(recordings["material"].dropna().unique(), key=_paper_order)
        return holdout_cells(recordings, "material", materials)


def _paper_order(material: str):
    order = ["aluminum", "PVC", "neoprene", "cardboard", "plywood"]
    return (order.index(material), "") if material in order else (len(order), material)
