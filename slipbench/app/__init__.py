"""The app wing: what a user types. The click commands, benchmark files and detector costs.

``cli`` holds the command group and ``main`` with its exit codes; ``commands/`` one module per
command; ``options`` the options they share; ``selection`` plugins chosen by id or ``all``;
``benchspec`` reads ``bench.toml`` into its parsed form and ``benchfile`` runs it; ``bench``
measures detectors' costs; ``info`` summarises a dataset. May import: every wing.
"""
