"""`slipbench list`: the detectors and protocols the registries can load, with their status,
description and parameters, as text or JSON."""

from __future__ import annotations

import json

import click

from slipbench.app.options import plugins_option
from slipbench.app.selection import add_plugin_folders
from slipbench.engine import registry

REFERENCE = "the reference: the baseline every table will compare against"


@click.command("list")
@plugins_option()
@click.option("--json", "as_json", is_flag=True, help="Machine-readable: one object per plugin.")
@click.option(
    "--check",
    is_flag=True,
    help="Import every plugin to check that it loads (by default an installed plugin is read "
    "from its source, which is fast, and imported when selected).",
)
def list_plugins(plugins: tuple[str, ...], as_json: bool, check: bool) -> None:
    """The detectors and protocols that can be selected: status, description, where each comes
    from (package and version, or plugin file), parameters, and which detector is the reference
    baseline. Installed plugins are read from their source where it declares these plainly
    (``read``: "source"), else imported ("import"); plugin files are always imported."""
    add_plugin_folders(plugins)
    found = {
        kind: [reg.describe(n, check=check) for n in reg.names()]
        for kind, reg in (("detectors", registry.detectors), ("protocols", registry.protocols))
    }
    if as_json:
        click.echo(json.dumps(found, indent=2, default=repr))
        return
    for kind, entries in found.items():
        click.echo(f"{kind}:")
        for e in entries:
            state = e["status"] + (f" ({e['detail']})" if e["detail"] else "")
            click.echo(f"  {e['name']:<18} {state if e['status'] != 'ok' else e['description']}")
            click.echo(f"      from {e['from']}")
            if "inputs" in e:
                click.echo(f"      reads {' and '.join(e['inputs'])} (--input)")
            if e.get("reference"):
                click.echo(f"      {REFERENCE}")
            for name, p in e["parameters"].items():
                click.echo(
                    f"      {name}={p['default']!r}"
                    + (f"  ({p['constraint']})" if p["constraint"] else "")
                )
