"""The plugins a command line selects: plugin folders added to the registries, plugins loaded
by name or all of them ('all' runs the ones that load and notes the others), and options set on
the plugins that take them.

A plugin whose declared optional dependency is not installed (minirocket without aeon) is a
state, not a failure: 'all' and benchmark files skip it with one line naming it and its install
hint; named on its own it is refused before any work (exit 3, with the hint). Rows of results
written before they recorded their plugins' layouts get them from the registry here
(:func:`recorded_plugins`), for the report, which reads only rows."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import TYPE_CHECKING

from slipbench.engine import registry
from slipbench.engine.registry import Plugin
from slipbench.errors import PluginError, SlipbenchError, UsageError
from slipbench.vocabulary import INPUTS

if TYPE_CHECKING:
    import pandas as pd

    from slipbench.base import BaseDetector


def add_plugin_folders(folders: tuple[str, ...]) -> None:
    for folder in folders:
        registry.add_plugin_folder(folder)


def skip_line(kind: str, name: str, why: str) -> str:
    """The one line that says an unavailable plugin is skipped, and how to install what it needs."""
    return f"skipped {kind} {name!r}: unavailable here, {why}"


def require_available(reg: registry.Registry, name: str) -> None:
    """Refuse a plugin named on its own whose optional dependency is not installed (exit 3)."""
    why = reg.unavailable(name)
    if why:
        raise PluginError(f"{reg.kind} {name!r} is unavailable here: {why}")


def available(reg: registry.Registry, names: list[str], echo: Callable[[str], None]) -> list[str]:
    """``names`` without the unavailable plugins, each of those named by ``echo`` in one line;
    a plugin that fails to import is left in, for the caller to report."""
    out = []
    for name in names:
        try:
            why = reg.unavailable(name)
        except PluginError:
            why = ""
        if why:
            echo(skip_line(reg.kind, name, why))
        else:
            out.append(name)
    return out


def load_plugins(
    reg: registry.Registry[Plugin],
    name: str,
    broken: list[str],
    echo: Callable[[str], None] = print,
) -> dict[str, Plugin]:
    """The plugin called ``name`` (or every plugin, for 'all'), made with its defaults. With 'all',
    a plugin that fails to load is noted in ``broken`` and the others run; an unavailable one is
    skipped with a line to ``echo``. Named on its own, an unavailable plugin is refused."""
    if name != "all":
        require_available(reg, name)
        return {name: reg.get(name)()}
    out: dict[str, Plugin] = {}
    skipped: list[str] = []
    for n in reg.names():
        try:
            why = reg.unavailable(n)
            if why:
                skipped.append(skip_line(reg.kind, n, why))
                continue
            out[n] = reg.get(n)()
        except PluginError as exc:
            broken.append(str(exc))
    if not out:
        raise PluginError("; ".join(broken + skipped) or f"no {reg.kind} is registered")
    for line in skipped:
        echo(line)
    return out


def select_plugins(
    reg: registry.Registry[Plugin],
    names: tuple[str, ...] | list[str],
    broken: list[str],
    echo: Callable[[str], None] = print,
) -> dict[str, Plugin]:
    """The plugins named by a repeated option, each value an id, a comma list of ids or 'all'
    (``--detector holweg --detector lstm``, ``--detector holweg,lstm``): every one of them, in
    the order given, each once. Before, a repeated option silently kept only its last value.
    What 'all' means depends on what is installed, so 'all' names each plugin it selects and
    where it comes from, one line each to ``echo`` (:func:`provenance_line`)."""
    out: dict[str, Plugin] = {}
    wanted = check_ids(reg, names)
    for name in wanted:
        for n, plugin in load_plugins(reg, name, broken, echo).items():
            out.setdefault(n, plugin)
    if not out:
        raise UsageError(f"no {reg.kind} named: give an id, a comma list of ids or 'all'")
    if "all" in wanted:
        for n in out:
            echo(provenance_line(reg, n))
    return out


def check_ids(reg: registry.Registry, names: tuple[str, ...] | list[str]) -> list[str]:
    """The ids a repeated option names (each value an id, a comma list or 'all'), every one
    checked against the registry (:meth:`~slipbench.engine.registry.Registry.check_name`)
    before any plugin is imported."""
    wanted = [n.strip() for value in names for n in value.split(",") if n.strip()]
    for name in wanted:
        if name != "all":
            reg.check_name(name)
    return wanted


def provenance_line(reg: registry.Registry, name: str) -> str:
    """``all: protocol 'window-size' from built in (slipbench 0.1.0)``: the line 'all' prints
    per selected plugin; the place is the one ``slipbench list`` shows."""
    return f"all: {reg.kind} {name!r} from {reg.provenance(name)}"


def with_options(plugins: dict, options: dict, kind: str) -> dict:
    """Each option set on the plugins that take it; one that none takes is a usage error."""
    for name, value in options.items():
        takers = [p for p in plugins.values() if name in p.get_params()]
        if not takers:
            raise UsageError(
                f"no selected {kind} takes the parameter {name!r}; parameters: "
                + "; ".join(
                    f"{n}: {', '.join(p.get_params()) or 'none'}" for n, p in plugins.items()
                )
            )
        for plugin in takers:
            plugin.set_params(**{name: value})
    return plugins


def readable(
    name: str, detector: BaseDetector, asked: str, echo: Callable[[str], None]
) -> list[str]:
    """The inputs (``univariate``, ``channels``) a detector runs with when ``asked`` for one of
    them or ``both``: those it declares; a detector that reads none of them is left out with a
    line to ``echo`` (a run of it would be refused)."""
    takes = type(detector).inputs
    wanted = list(INPUTS) if asked == "both" else [asked]
    chosen = [kind for kind in wanted if kind in takes]
    left = [kind for kind in wanted if kind not in takes]
    if left:
        echo(
            f"detector {name!r} reads the {' and '.join(takes)} input only: "
            + ("left out" if not chosen else f"no run with the {' and '.join(left)} input")
        )
    return chosen


def _missing(rows: pd.DataFrame, column: str) -> pd.Series:
    """(n_rows,) bool: rows that do not record ``column`` (absent, null or "")."""
    import pandas as pd

    if column not in rows:
        return pd.Series(True, index=rows.index)
    return rows[column].isna() | rows[column].astype(str).eq("")


def recorded_plugins(rows: pd.DataFrame) -> pd.DataFrame:
    """``rows`` with what rows written before results recorded it lack, from the registered
    plugins: each protocol's layout and presentation, made with the options its rows ran with
    (:func:`slipbench.protocol.described`), and whether each detector is the reference. A
    report reads these from the rows, never from the registry; a plugin that cannot be loaded
    leaves its rows as they are (the report then lays them out from their cell keys, and says
    so)."""
    import pandas as pd

    from slipbench.protocol import described

    out = rows.copy()
    for (name, given), part in rows[_missing(rows, "protocol_layout")].groupby(
        [rows["protocol"], rows.get("protocol_params", pd.Series("{}", index=rows.index))],
        dropna=False,
    ):
        try:
            params = json.loads(given) if isinstance(given, str) else {}  # absent: the defaults
            made = registry.protocols.get(str(name))(**params)
        except (SlipbenchError, TypeError, ValueError, json.JSONDecodeError):
            continue
        for column, value in described(made).items():
            out.loc[part.index, column] = value
    for name, part in rows[_missing(rows, "detector_reference")].groupby("detector"):
        try:
            reference = bool(registry.detectors.get(str(name)).reference)
        except SlipbenchError:
            continue
        out.loc[part.index, "detector_reference"] = reference
    return out
