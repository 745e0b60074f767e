"""The report wing: saying. Result rows rendered in the paper's layout, with what stands behind them.

The report's outline (``outline``), rows to tables (``tables``) and tables to Markdown, LaTeX and
HTML (``render``, ``html``), the whole document (``document``), its header (``provenance``), the
leaderboard's and compare's text (``leaderboard``, ``compare``), the paper's findings
(``findings``), its published numbers (``paper``) and figures (``plots``). May import: every wing
below it (``analysis`` excepted) and the contract.
"""
