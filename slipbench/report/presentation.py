"""How the built-in protocols' tables and figures look: captions, titles, column labels, figure
kinds and axes, the published table each matches. A protocol's :class:`~slipbench.protocol.Layout`
says what its cells are (rows, column, pair, split, metrics); the report decides how they look,
here. A plugin protocol keeps the presentation keywords its ``Layout`` passes, as its defaults."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

from slipbench.protocol import Layout
from slipbench.store.columns import FALSE_ALARMS


@dataclass(frozen=True)
class Presentation:
    """The presentation fields of a :class:`~slipbench.protocol.Layout`: what each means is
    documented there."""

    caption: str = ""
    title: str = ""
    group: str = ""
    merge_rows: bool = False
    column_label: str | None = None
    note_column: str | None = None
    figure: str | None = None
    x: str | None = None
    x_label: str = ""
    log_base: int = 0
    paper_table: str | None = None


_WINDOW_CAPTION = (
    "Slip state classification at various window sizes across three types of sensors and fingers."
)

# (protocol id, layout column): a protocol with several layouts (window-size in samples or in
# milliseconds) has one presentation per layout, told apart by the column.
PRESENTATIONS: dict[tuple[str, str], Presentation] = {
    ("window-size", "window"): Presentation(
        _WINDOW_CAPTION,
        title="Window size",
        group="at Window Size",
        note_column="window_ms",
        figure="curve",
        x_label="window (samples)",
        log_base=10,
        paper_table="window-size",
    ),
    ("window-size", "window_ms"): Presentation(
        _WINDOW_CAPTION,
        title="Window size",
        group="at Window Size (ms)",
        note_column="window",
        figure="curve",
        x_label="window (ms)",
        log_base=10,
    ),
    ("sampling-rate", "downsample"): Presentation(
        "Slip state classification at various sampling rates (Hz) across sensors and fingers, window {window} "
        "downsampled. Superscripts indicate the sensor type for the selected sampling rate.",
        title="Sampling rate",
        group="at Sampling Rate",
        column_label="rate_hz",
        figure="curve",
        x="rate_hz",
        x_label="sampling rate (Hz)",
        log_base=2,
        paper_table="sampling-rate",
    ),
    ("material-holdout", "material"): Presentation(
        "Slip state classification with and without (*) explicit training of indicated materials across sensors.",
        title="Material",
        group="with Material",
        figure="with-without",
        paper_table="material-holdout",
    ),
    ("speed-holdout", "speed_mm_s"): Presentation(
        "Slip state classification with and without (*) explicit training of indicated speeds across sensors.",
        title="Slip speed",
        group="at Speed",
        figure="with-without",
        paper_table="speed-holdout",
    ),
    ("cross-instance", "test_instance"): Presentation(
        "Classification trained and tested on data from one or all fingers of a single sensor type.",
        title="Cross-instance transfer",
        merge_rows=True,
        figure="matrix",
        paper_table="cross-instance",
    ),
    ("streaming", "window"): Presentation(
        "Slip onsets detected, their delays and false alarms while streaming test recordings, per sensor unit.",
        title="Streaming",
        group="At the detector's own threshold (0.5)",
        figure="tradeoff",
        x=FALSE_ALARMS.name,
        x_label="false alarms per minute",
    ),
}


def presented(protocol: str | Sequence[str], layout: Layout) -> Layout:
    """``layout`` as the report shows it: with the presentation of ``protocol`` (its id, or the
    ids of its class and the classes it derives from, nearest first, so that a plugin's
    subclass of a built-in protocol looks like it) where this module has one for the layout's
    column, else with the presentation the layout passes (a plugin's), its caption "Protocol
    {id}." where it gives none."""
    ids = [protocol] if isinstance(protocol, str) else list(protocol)
    shown = next(
        (PRESENTATIONS[i, layout.column] for i in ids if (i, layout.column) in PRESENTATIONS), None
    )
    if shown is not None:
        return dataclasses.replace(layout, **dataclasses.asdict(shown))
    return layout if layout.caption else dataclasses.replace(layout, caption=f"Protocol {ids[0]}.")


def lineage(name: str, cls: type) -> list[str]:
    """``name`` and the registry ids of the protocol classes ``cls`` derives from, nearest
    first: what :func:`presented` looks a presentation up by."""
    from slipbench.engine.registry import protocols
    from slipbench.protocol import BaseProtocol

    bases = [c for c in cls.__mro__[1:] if issubclass(c, BaseProtocol) and c is not BaseProtocol]
    return [name, *(protocols.id_of(c) for c in bases)]


__all__ = ["PRESENTATIONS", "Presentation", "lineage", "presented"]
