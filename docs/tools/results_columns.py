"""The results columns page, ``docs/reference/results-columns.md``, written from the results schema
(:mod:`slipbench.store.columns`): ``python docs/tools/results_columns.py > docs/reference/results-columns.md``.
``tests/store/test_columns.py`` checks that the committed page is what this writes."""

from __future__ import annotations

from slipbench.store.columns import GROUPS

HEAD = """\
# Results columns

Every column a result row may hold (`results.parquet`, `cells/<key>.parquet`), written from the
results schema in `slipbench/store/columns.py` by `docs/tools/results_columns.py`; the store
refuses a row with a column it does not declare. A protocol adds its own cell-key columns (those
its `cell` column names). A row holds the columns of what its cell computed: a skipped cell has
`status` and `reason`, a streaming cell no window figures.

## Adding a figure

One entry: a `Figure(name, unit, meaning)` in `WINDOWED_FIGURES` (windowed cells) or
`STREAMED_FIGURES` (streaming cells) of `slipbench/store/columns.py`. Its interval columns
(`_lo`, `_hi`, and `_se`, `_wilson_lo/_hi`, `op_` as the entry says) follow from it; the code
that computes the figure returns those names, and this page is regenerated.
"""


def page() -> str:
    parts = [HEAD]
    for title, columns in GROUPS.items():
        parts.append(
            f"\n## {title}\n\n| column | type | unit | meaning |\n| --- | --- | --- | --- |\n"
        )
        parts += [f"| `{c.name}` | {c.type} | {c.unit} | {c.meaning} |\n" for c in columns]
    return "".join(parts)


if __name__ == "__main__":
    print(page(), end="")
