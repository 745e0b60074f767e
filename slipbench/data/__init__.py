"""The data wing: a dataset from disk, an importer or the simulation, to windows of the signal.

The Parquet format (``schema``, ``read``, ``write``, ``canonical``, ``fingerprint``, ``format``
with the in-memory ``Dataset``, ``integrity``), the importers of labs' recordings
(``importers/``), published datasets by their cards (``card``, ``fetch``, ``download``), the simulated
design of experiments and its cache (``synth``, ``defaults``), the univariate signal and its
windows, balancing and splits (``signals``), datasets combined for transfer (``transfer``) and toy
windows for tests and benchmarks (``toy``). May import: the contract only.
"""
