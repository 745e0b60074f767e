"""Tables -> text: Markdown and LaTeX renderers (formatting only)."""

from __future__ import annotations

import pandas as pd

from .tables import Table, escape


def to_markdown(table: Table) -> str:
    """Markdown: caption in bold, one pipe table, notes in italics."""
    header = [*table.row_headers, *table.columns]
    frame = pd.DataFrame([[*r, *c] for r, c in zip(table.rows, table.cells)], columns=header)
    body = frame.to_markdown(index=False, stralign="right", disable_numparse=True)
    parts = [f"**{table.caption}** {table.group}.", "", body]
    parts += [""] + [f"_{n}_" for n in table.notes] if table.notes else []
    return "\n".join(parts)


def to_latex(table: Table) -> str:
    """A LaTeX ``table`` float in the paper's style (vertical rules, sensor name on the first row
    of its group, ``\\cline`` between fingers). Uses only the LaTeX kernel: no packages.

    Written by hand rather than with ``Styler.to_latex``: that needs booktabs and multirow, and
    has no way to express the per-sensor rate header of Table II.
    """
    n_rows, n_cols = len(table.row_headers), len(table.columns)
    first = n_rows + 1
    spec = "|" + "|".join(["c"] * (n_rows + n_cols)) + "|"
    lines = [r"\begin{table}[!t]", rf"\caption{{{escape(table.caption)}}}", r"\centering",
             rf"\begin{{tabular}}{{{spec}}}", r"\hline"]
    heads = " & ".join(rf"\textbf{{{escape(h)}}}" for h in table.row_headers)
    lines.append(rf"{heads} & \multicolumn{{{n_cols}}}{{c|}}{{\textbf{{{escape(table.group)}}}}}\\")
    lines.append(rf"\cline{{{first}-{n_rows + n_cols}}}")
    latex_cols = table.latex_columns or [escape(c) for c in table.columns]
    lines.append(" & " * n_rows + " & ".join(latex_cols) + r"\\")
    lines.append(r"\hline")
    previous: tuple[str, ...] | None = None
    for i, (labels, cells) in enumerate(zip(table.rows, table.cells)):
        shown = list(labels)
        if n_rows > 1 and previous is not None and labels[0] == previous[0]:
            shown[0] = ""  # the sensor name once per group, as the paper's multirow
        lines.append(" & ".join(escape(x) for x in [*shown, *cells]) + r"\\")
        nxt = table.rows[i + 1] if i + 1 < len(table.rows) else None
        lines.append(rf"\cline{{2-{n_rows + n_cols}}}" if n_rows > 1 and nxt is not None and nxt[0] == labels[0] else r"\hline")
        previous = labels
    lines.append(r"\end{tabular}")
    if table.label:
        lines.append(rf"\label{{{table.label}}}")
    for note in table.notes:
        lines.append(rf"\par\footnotesize {escape(note)}")
    lines.append(r"\end{table}")
    return "\n".join(lines)


def standalone_latex(body: str) -> str:
    """Wrap table floats in a minimal document that compiles with the LaTeX kernel alone."""
    return "\n".join([r"\documentclass{article}", r"\usepackage[utf8]{inputenc}", r"\begin{document}", body,
                      r"\end{document}", ""])
