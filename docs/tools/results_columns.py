"""The results columns page, ``docs/reference/results-columns.md``, written from the results schema
(:mod:`slipbench.store.columns`): ``python docs/tools/results_columns.py > docs/reference/results-columns.md``.
``tests/store/test_columns.py`` checks that the committed page is what this writes."""

from __future__ import annotations

from slipbench.store.columns import GROUPS

HEAD = """\
# Results columns

Every column a result row may hold (`results.parquet`, `cells/<key>.parquet`), written from the
results schema in `slipbench/store/columns.py` by `docs/tools/results_columns.py`; the store
refuses a row with a column it does not declare, or a number outside the values its column
allows (NaN passes where the column is not "finite"). A file without row digests (another tool,
an older slipbench) is read with its numbers checked against them. A protocol adds its own
cell-key columns (those its `cell` column names). A row holds the columns of what its cell
computed: a skipped cell has `status` and `reason`, a streaming cell no window figures.

## Adding a figure

Two files: its entry in `FIGURES` of `slipbench/store/columns.py`, and its computation. The entry
is a `Figure(name, unit, meaning, ...)` that says which cells hold it (`kind`: windowed or
streamed), how tables head and show it (`label`, `called`, `display`, `decimals`), which
direction is worse (`worse`), which windows it is the share of (`rate`) and whether the CI gate
reads it (`tolerance`, its default). Its interval columns (`_lo`, `_hi`, and `_se`,
`_wilson_lo/_hi`, `op_` as the entry says) follow from it. Every table, test, gate and verdict
takes its figures from the schema (`figures()`, `names()`), never from a list of its own
(`tests/test_architecture.py` fails on one); the computation returns the entry's names, and
this page is regenerated.
"""


def page() -> str:
    parts = [HEAD]
    for title, columns in GROUPS.items():
        parts.append(
            f"\n## {title}\n\n| column | type | unit | values | meaning |\n"
            "| --- | --- | --- | --- | --- |\n"
        )
        parts += [
            f"| `{c.name}` | {c.type} | {c.unit} | {c.allowed} | {c.meaning} |\n" for c in columns
        ]
    return "".join(parts)


if __name__ == "__main__":
    print(page(), end="")
