"""The stats wing: deciding. Figures, intervals and verdicts; never how they are written.

The cluster bootstrap (``bootstrap``), a cell's figures with intervals and paired changes
(``metrics``), joint intervals over fingers and seeds from stored predictions (``joint``), every
paired change and its state (``contrast``, its retraining noise from ``noise``), the
leaderboard's ranks and pairs (``leaderboard``) and compare's per-cell and summary verdicts
(``sides``, ``changes``, ``compare``). May import: ``store``, ``data`` and the contract; never
``report`` or ``app``.
"""
