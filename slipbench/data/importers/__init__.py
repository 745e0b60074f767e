"""Importers into the slipbench format: a generic CSV importer driven by a mapping file
(:func:`import_csv`, :func:`load_mapping`), and the published datasets as mappings of it
(:data:`IMPORTERS`, by the name ``slipbench dataset import`` takes).

The mapping (TOML, documented with a full example in ``datasets.md``) says which files to read,
the metadata of each (from the mapping, with templates filled from patterns on file paths),
which columns are channels, where the sampling rate and the per-sample labels come from, and
which files form one trial.
"""

from collections.abc import Callable
from pathlib import Path

from slipbench.data.importers.biotacsp import BIOTACSP_DOS_MAPPING, biotacsp_dos
from slipbench.data.importers.csv import import_csv
from slipbench.data.importers.mapping import CsvMapping, load_mapping
from slipbench.data.importers.xela import xela_proactive

# each takes (src, out, description=...) and returns the dataset folder
IMPORTERS: dict[str, Callable[..., Path]] = {
    "biotacsp-dos": biotacsp_dos,
    "xela-proactive": xela_proactive,
}

__all__ = [
    "BIOTACSP_DOS_MAPPING",
    "IMPORTERS",
    "CsvMapping",
    "biotacsp_dos",
    "import_csv",
    "load_mapping",
    "xela_proactive",
]
