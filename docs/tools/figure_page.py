"""The figures page, ``docs/reference/figures.md``, written from the results schema
(:mod:`slipbench.store.columns`): every figure a cell computes, its unit, its meaning and the
columns that come with it: ``python docs/tools/figure_page.py > docs/reference/figures.md``.
``tests/test_docs.py`` checks that the committed page is what this writes."""

from __future__ import annotations

from slipbench.store.columns import STREAMED, WINDOWED, Figure, figures

PAGE = "docs/reference/figures.md"
HEAD = """\
# Figures

Written from the results schema (`slipbench/store/columns.py`) by `docs/tools/figure_page.py`; do not
edit by hand. Every figure a cell computes, with its unit, what it means and the columns that come
with it; each column on its own: [Results columns](results-columns.md); how the intervals are
made and how well they cover: [Statistics](../explanation/statistics.md).
"""
KINDS = (
    (
        "Of a windowed cell",
        "A cell that classifies test windows: each figure with its 95 % interval, a cluster "
        "bootstrap over the test trials.",
        figures(WINDOWED),
    ),
    (
        "Of a streaming cell",
        "A cell that streams whole test recordings through the detector: each figure at the "
        "detector's own threshold, with its 95 % interval over the test trials.",
        figures(STREAMED),
    ),
)


def _also(figure: Figure) -> str:
    """The columns besides the figure and its interval that the entry brings."""
    names = [c.name for c in figure.columns()]
    extra = [n for n in names if n not in (figure.name, f"{figure.name}_lo", f"{figure.name}_hi")]
    return ", ".join(f"`{n}`" for n in extra) or "none"


def page() -> str:
    out = [HEAD]
    for title, text, declared in KINDS:
        out.append(f"\n## {title}\n\n{text}\n\n")
        out.append(
            "| figure | unit | what it is | interval | also |\n| --- | --- | --- | --- | --- |\n"
        )
        for f in declared:
            out.append(
                f"| `{f.name}` | {f.unit} | {f.meaning} | `{f.name}_lo`, `{f.name}_hi` | "
                f"{_also(f)} |\n"
            )
    return "".join(out)


if __name__ == "__main__":
    print(page(), end="")
