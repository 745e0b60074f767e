"""The built-in detectors page, ``docs/reference/detectors.md``, written from the registry: each
detector's id, what it reads and needs, its module's docstring and its parameters with their
defaults and constraints, so the page says what the code does:
``python docs/tools/detector_page.py > docs/reference/detectors.md``. ``tests/test_docs.py``
checks that the committed page is what this writes."""

from __future__ import annotations

import sys

from slipbench.base import BaseDetector
from slipbench.engine.registry import detectors
from slipbench.report.order import rank
from slipbench.vocabulary import DETECTOR_ORDER

PAGE = "docs/reference/detectors.md"
HEAD = """\
# Built-in detectors

Written from the registry by `docs/tools/detector_page.py`; do not edit by hand. `slipbench list`
shows the same for every detector installed on your machine, plugins included, with its status
there. What the paper's LSTM leaves open, and how slipbench chose: [The paper's LSTM](../explanation/lstm.md).
"""


def _cell(text: object) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def _module_text(cls: type) -> str:
    """The first paragraph of the detector's module docstring, on one line."""
    doc = sys.modules[cls.__module__].__doc__ or ""
    return " ".join(doc.strip().split("\n\n")[0].split())


def _built_in() -> list[str]:
    """The ids of the detectors slipbench ships, in the tables' order."""
    names = [
        n for n in detectors.names() if detectors.describe(n)["package"].startswith("slipbench ")
    ]
    return rank(names, DETECTOR_ORDER)


def _needs(cls: type[BaseDetector]) -> str:
    return f"`{cls.install_hint}`" if cls.requires else "nothing more"


def page() -> str:
    names = _built_in()
    described = {n: detectors.describe(n) for n in names}
    classes = {n: detectors.get(n) for n in names}
    out = [HEAD, "\n| id | reads | needs |\n| --- | --- | --- |\n"]
    for n in names:
        d, cls = described[n], classes[n]
        mark = " (the reference)" if d.get("reference") else ""
        out.append(
            f"| [`{n}`](#{n}){mark} | {' and '.join(d.get('inputs', []))} | {_needs(cls)} |\n"
        )
    reference = [n for n in names if described[n].get("reference")]
    out.append(
        "\nThe reference, the baseline every table compares the others against: "
        + ", ".join(f"`{n}`" for n in reference)
        + ".\n"
    )
    for n in names:
        d, cls = described[n], classes[n]
        out.append(f"\n## `{n}`\n\n{_module_text(cls)}\n\n")
        out.append(
            f"Class `{cls.__module__}.{cls.__qualname__}`; reads {' and '.join(d['inputs'])}"
        )
        out.append(f"; needs {_needs(cls)}.\n\n" if cls.requires else ".\n\n")
        out.append("| parameter | default | accepts |\n| --- | --- | --- |\n")
        for p, spec in d["parameters"].items():
            out.append(f"| `{p}` | `{spec['default']!r}` | {_cell(spec['constraint'])} |\n")
    return "".join(out)


if __name__ == "__main__":
    print(page(), end="")
