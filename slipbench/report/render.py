"""Blocks -> text: the one interface every format's renderer implements, and the formats by
name. A format is one module of this wing (``markdown``, ``latex``, ``html``) whose
``RENDERER`` is a :class:`Renderer`; :func:`slipbench.report.document.render` feeds it a
report's blocks in order. Adding a format is its module and its line in :data:`FORMATS`."""

from __future__ import annotations

import importlib
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

if TYPE_CHECKING:  # the commands read FORMATS at start-up: nothing heavy loads with it
    from slipbench.report.blocks import Heading, Table, Text

#: each format's name (``--format``) -> the module of this wing that renders it; the modules are
#: imported when a report is rendered, so that the commands start without them
FORMATS = {"md": "markdown", "latex": "latex", "html": "html"}


@dataclass(frozen=True)
class Drawn:
    """A figure as a renderer places it: its file stem, its caption, the files drawn already
    (suffix -> path relative to the report, ``{".png": "plots/x.png"}``) and ``png``, which
    gives the figure's PNG bytes (read from its file, else drawn now; None where the rows hold
    nothing to draw)."""

    stem: str
    caption: str
    paths: dict[str, str]
    png: Callable[[], bytes | None]


class Renderer(ABC):
    """One document in one format. A renderer is made for one document (``standalone``: a
    whole document, not only its tables, where the format tells the two apart), is given the
    blocks in order, each one returning its text ("" for what the format does not show), and
    joins them in :meth:`document`.

    ``name`` is the format's name, ``suffix`` its files' suffix; ``cross_links``: a link may
    point into another file's section (an appendix's), else it shows its label alone;
    ``appendix``: a report in this format may move its detail to an appendix file;
    ``embeds_figures``: the format shows every figure without figure files (it draws them)."""

    name: ClassVar[str]
    suffix: ClassVar[str]
    cross_links: ClassVar[bool] = False
    appendix: ClassVar[bool] = True
    embeds_figures: ClassVar[bool] = False

    def __init__(self, standalone: bool = False) -> None:
        self.standalone = standalone

    @abstractmethod
    def heading(self, block: Heading) -> str:
        """A heading, its text escaped."""

    @abstractmethod
    def paragraph(self, block: Text) -> str:
        """A paragraph, its text escaped, with its link."""

    @abstractmethod
    def table(self, block: Table) -> str:
        """A table with its caption, headers and notes."""

    @abstractmethod
    def figure(self, drawn: Drawn) -> str:
        """A figure with its caption, or "" where the format has no file of it to show."""

    @abstractmethod
    def document(self, parts: list[str]) -> str:
        """The document from the texts of its blocks, in order (empty ones left out)."""


def renderer(fmt: str, standalone: bool = False) -> Renderer:
    """The renderer of format ``fmt`` (one of :data:`FORMATS`: its module's ``RENDERER``) for
    one document."""
    if fmt not in FORMATS:
        raise ValueError(f"unknown report format {fmt!r}; one of {', '.join(FORMATS)}")
    cls: type[Renderer] = importlib.import_module(f"slipbench.report.{FORMATS[fmt]}").RENDERER
    return cls(standalone)


__all__ = ["FORMATS", "Drawn", "Renderer", "renderer"]
