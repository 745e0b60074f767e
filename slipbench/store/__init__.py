"""The store wing: where results live and how they are found again.

One Parquet row per cell, written atomically and readable after any crash (``results``), and the
content addresses that make a cached cell safe to reuse: canonical keys over data, code,
parameters, seed and random-stream scheme (``keys``). May import: the contract only.
"""
