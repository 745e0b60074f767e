"""The gate wing: judging a change. Two result sets, paired cell by cell, to one verdict and its
exit code.

The gate's family of figures and tolerances (``gate``), the two sides a comparison reads paired
cell by cell (``sides``), each compared cell's change and its interval (``changes``), the
verdicts look by look (``compare``), the error spent over looks at more seeds (``sequential``),
what a pooled test can see (``power``), a bench's measured seed noise (``calibration``) and its
numbers against the base's own seeds (``calibration_check``), and channels cells against their
univariate twins, judged as compare judges (``reduction``). Built on what every verdict shares
(``stats``: the bootstrap, figures, contrasts, seed noise). May import: ``stats``, ``store``,
``data`` and the contract; never ``engine``, ``report`` or ``app``.
"""
