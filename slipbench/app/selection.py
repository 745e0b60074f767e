"""The plugins a command line selects: plugin folders added to the registries, plugins loaded
by name or all of them ('all' runs the ones that load and notes the others), and options set on
the plugins that take them."""

from __future__ import annotations

from slipbench.engine import registry
from slipbench.engine.registry import Plugin
from slipbench.errors import PluginError, UsageError


def add_plugin_folders(folders: tuple[str, ...]) -> None:
    for folder in folders:
        registry.add_plugin_folder(folder)


def load_plugins(reg: registry.Registry[Plugin], name: str, broken: list[str]) -> dict[str, Plugin]:
    """The plugin called ``name`` (or every plugin, for 'all'), made with its defaults. With 'all',
    a plugin that fails to load is noted in ``broken`` and the others run."""
    if name != "all":
        return {name: reg.get(name)()}
    out: dict[str, Plugin] = {}
    for n in reg.names():
        try:
            out[n] = reg.get(n)()
        except PluginError as exc:
            broken.append(str(exc))
    if not out:
        raise PluginError("; ".join(broken))
    return out


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
