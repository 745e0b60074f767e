"""The report wing: saying. Result rows rendered in the paper's layout, with what stands behind them.

The report's outline (``outline``: each protocol's layout as its rows record it, ``presentation``),
rows to tables (``tables``), the whole document (``document``), its header (``provenance``), the
leaderboard's and compare's text (``leaderboard``, ``compare``), the paper's findings
(``findings``), its published numbers (``paper``) and figures (``plots``); tables and blocks to
text through one interface (``render``), one module per format (``markdown``, ``latex``,
``html``). May import: every wing below it but the engine and ``analysis``, and the contract: a
report reads only the results store.
"""
