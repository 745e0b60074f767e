"""mkdocs hooks: pages that live outside docs/ join the site as they are, never copied by hand.

- ARCHITECTURE.md and CHANGELOG.md stay at the repository's root (where contributors and the
  tests read them) and are served as ``architecture.md`` and ``changelog.md``.
- ``reports/``, the committed reproduction, is served under ``reports/`` with its figures, so
  every figure of the reproduction on the site is the committed run's own output.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

from mkdocs.config.defaults import MkDocsConfig
from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parents[2]
ROOT_PAGES = {"ARCHITECTURE.md": "architecture.md", "CHANGELOG.md": "changelog.md"}
REPORTS = "reports"
REPORT_SUFFIXES = (".md", ".png")  # the PDFs and LaTeX are for papers, not the site


def committed_files() -> dict[str, Path]:
    """The site path of each file served from outside docs/, and where it is."""
    found = {dest: ROOT / src for src, dest in ROOT_PAGES.items()}
    for path in sorted((ROOT / REPORTS).rglob("*")):
        if path.suffix in REPORT_SUFFIXES:
            found[path.relative_to(ROOT).as_posix()] = path
    return found


def on_files(files: Files, *, config: MkDocsConfig) -> Files:
    for dest, path in committed_files().items():
        files.append(File.generated(config, dest, abs_src_path=str(path)))
    return files


def command_help() -> str:
    """Every command's ``--help``, as the installed slipbench prints it, 80 columns wide."""
    import click

    from slipbench.app.cli import cli

    out: list[str] = []

    def add(command: click.Command, parent: click.Context | None, name: str) -> None:
        ctx = click.Context(
            command, info_name=name, parent=parent, terminal_width=80, max_content_width=80
        )
        if isinstance(command, click.Group):
            for sub in command.list_commands(ctx):
                found = command.get_command(ctx, sub)
                assert found is not None  # listed by the group itself
                add(found, ctx, sub)
            return
        out.extend([f"## `{ctx.command_path}`", "", "```text", ctx.get_help(), "```", ""])

    root = click.Context(cli, info_name="slipbench")
    for name in cli.list_commands(root):
        found = cli.get_command(root, name)
        assert found is not None  # listed by the group itself
        add(found, root, name)
    return "\n".join(out)


def benchmark_table() -> str:
    """One row per script of benchmarks/: its name and the first paragraph of its docstring."""
    rows = ["| script | what it measures |", "| --- | --- |"]
    for path in sorted((ROOT / "benchmarks").glob("*.py")):
        doc = ast.get_docstring(ast.parse(path.read_text())) or ""
        summary = " ".join(doc.split("\n\n")[0].split()).replace("|", "\\|")
        rows.append(f"| `benchmarks/{path.name}` | {summary} |")
    return "\n".join(rows)


def gate_plan() -> str:
    """The shipped bench's gate plan, from bench.toml and its committed calibration, as
    ``slipbench calibrate`` prints it."""
    from slipbench.app.benchfile import plan_runs
    from slipbench.app.benchspec import load_benchmark
    from slipbench.app.calibrate import status
    from slipbench.app.gateplan import plan_gate

    bench = load_benchmark(ROOT / "bench.toml")
    runs = plan_runs(bench, echo=lambda _: None, check_gate=False)
    lines = plan_gate(bench, runs, status(bench, runs)).lines()
    return "\n".join(["```text", *lines, "```"])


GENERATED = {"commands": command_help, "benchmarks": benchmark_table, "gate_plan": gate_plan}


def on_page_markdown(markdown: str, **kwargs: object) -> str:
    """``<!-- slipbench: NAME -->`` becomes what ``GENERATED[NAME]`` writes, at build time."""
    return re.sub(r"^<!-- slipbench: (\w+) -->$", lambda m: GENERATED[m[1]](), markdown, flags=re.M)
