"""The analysis wing: the paper's section IV, spectral differences of slip and non-slip windows.

``spectral`` computes amplitude spectra, bootstrapped bands and the most significant band per
sensor, without training a detector. May import: ``engine``, ``stats``, ``stream``, ``data``,
``store`` and the contract.
"""
