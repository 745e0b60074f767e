"""The stats wing: deciding. Figures, intervals and verdicts; never how they are written.

The cluster bootstrap (``bootstrap``), a cell's figures with intervals and paired changes
(``metrics``), joint intervals over fingers and seeds from stored predictions (``joint``), the
leaderboard's rank tests (``leaderboard``) and compare's per-cell and summary verdicts
(``compare``). May import: ``store``, ``data`` and the contract; never ``report`` or ``app``.

scipy.stats and statsmodels are loaded where a figure needs them (``scipy.stats.t`` through
scipy's lazy submodules, statsmodels inside its functions' callers): importing them costs about
a second, which a command that only reads stored rows (a cached rerun's tables) never pays.
"""
