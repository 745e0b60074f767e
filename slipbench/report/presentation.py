"""A protocol's layout as the report shows it: what its cells are (its
:class:`~slipbench.protocol.Layout`) with how they look (its
:class:`~slipbench.protocol.Presentation`), one object that every table and figure reads. The
report finds both in the protocol's result rows (:func:`slipbench.protocol.described`), never in
the registry: built-in and plugin protocols alike."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from slipbench.protocol import BaseProtocol, Layout, Presentation


@dataclass(frozen=True)
class ShownLayout(Presentation, Layout):
    """A layout with its presentation: the fields of both (what each means is said there)."""

    def __post_init__(self) -> None:
        Layout.__post_init__(self)
        Presentation.__post_init__(self)
        if self.figure == "with-without" and not self.pair:
            raise ValueError("a 'with-without' figure needs Layout.pair")


def shown(layout: Layout, presentation: Presentation | None, protocol: str) -> ShownLayout:
    """``layout`` with ``presentation`` (none: the defaults), captioned "Protocol {protocol}."
    where the presentation gives no caption."""
    look = presentation or Presentation()
    if not look.caption:
        look = dataclasses.replace(look, caption=f"Protocol {protocol}.")
    what = {f.name: getattr(layout, f.name) for f in dataclasses.fields(Layout)}
    return ShownLayout(**what, **dataclasses.asdict(look))


def shown_protocol(protocol: BaseProtocol, name: str) -> ShownLayout:
    """How a report shows ``protocol``, registered as ``name``: its layout with its
    presentation, as its result rows record them."""
    if not isinstance(protocol.layout, Layout):
        raise ValueError(f"protocol {name!r} declares no Layout")
    return shown(protocol.layout, protocol.presentation, name)


__all__ = ["ShownLayout", "shown", "shown_protocol"]
