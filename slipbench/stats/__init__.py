"""The stats wing: what every verdict shares. Figures, intervals and paired changes; never how
they are written.

The cluster bootstrap (``bootstrap``), a cell's figures with intervals and paired changes
(``metrics``), a protocol's mean change (``pooled``), joint intervals over fingers and seeds from
stored predictions (``joint``), every paired change and its state (``contrast``, its retraining
noise from ``noise``), changes across datasets (``meta``), the columns that name a cell and an
entrant (``factors``) and the leaderboard's ranks and pairs (``leaderboard``). The gate
(``slipbench.gate``) and the history (``slipbench.history``) build on it. May import: ``store``,
``data`` and the contract; never ``gate``, ``history``, ``report`` or ``app``.
"""
