"""What guards a dataset's files against bit rot: a CRC checksum on every page, and the content
fingerprint stored when slipbench wrote them. The reader checks both where they are; a file
written by another tool may carry neither, and a flipped bit in it then reads as data.
"""

from __future__ import annotations

import shlex
from pathlib import Path

from slipbench.atomic import open_parquet
from slipbench.data.schema import FINGERPRINT_KEY, RECORDINGS_FILE, SAMPLES_FILE

#: the shortest way to a copy that carries both (a new folder; the content stays the same)
REWRITE = "slipbench dataset rewrite {path} NEW_FOLDER"


def page_checksums(file: Path) -> bool:
    """Whether every column chunk of ``file`` starts with a page that carries a CRC.

    pyarrow checks CRCs where a page has one but does not say whether it has; the page header
    does (Thrift compact protocol): fields 1-3 (type, sizes) are i32s, each written as 0x15 and
    a varint, and the CRC, when stored, is field 4, the next i32 (0x15). A writer stores CRCs
    on every page or on none, so each chunk's first page stands for the chunk.
    """
    md = open_parquet(file).metadata
    with open(file, "rb") as fh:
        for g in range(md.num_row_groups):
            for c in range(md.num_columns):
                chunk = md.row_group(g).column(c)
                fh.seek(
                    chunk.dictionary_page_offset
                    if chunk.has_dictionary_page
                    else chunk.data_page_offset
                )
                if not _crc_follows(fh.read(32)):
                    return False
    return md.num_row_groups > 0


def _crc_follows(header: bytes) -> bool:
    at = 0
    for _ in range(3):  # type, uncompressed size, compressed size
        if header[at : at + 1] != b"\x15":
            return False
        at += 1
        while at < len(header) and header[at] & 0x80:  # the varint's continuation bytes
            at += 1
        at += 1
    return header[at : at + 1] == b"\x15"


def unguarded(path: Path) -> list[str]:
    """One line per file of the dataset folder ``path`` in which bit rot would go unseen or be
    found late, and what to run about it; empty when both files carry both guards."""
    lines = []
    for name in (RECORDINGS_FILE, SAMPLES_FILE):
        file = path / name
        crc = page_checksums(file)
        stored = FINGERPRINT_KEY in (open_parquet(file).schema_arrow.metadata or {})
        if not crc and not stored:
            lines.append(
                f"{file}: no page checksums and no stored fingerprint (written by another tool, "
                "or by an older slipbench): a flipped bit in it cannot be detected"
            )
        elif not crc:
            lines.append(
                f"{file}: no page checksums: a damaged page is found only by the stored "
                "fingerprint, once the whole dataset is read"
            )
        elif not stored:
            lines.append(
                f"{file}: no stored fingerprint: pages are checked, but a change that keeps "
                "them whole (a rewrite by another tool) is not detected"
            )
    if lines:
        lines.append(f"`{REWRITE.format(path=shlex.quote(str(path)))}` writes a copy with both")
    return lines
