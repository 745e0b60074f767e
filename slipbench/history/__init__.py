"""The history wing: a benchmark over commits. Stored runs to series and their steps.

A history's series, their points over runs and their seed spread (``series``; every figure's
from integer codes made once: ``coded``), and the change points in a series, proposed by binary
segmentation (``segmentation``: ruptures' breakpoints, in numpy) and confirmed by the gate's
contrast, every proposal in one batch (``judging``, ``steps``); a series too short for the
search judged at its best cut on the runs' own intervals (``short``). The
runs themselves are stored and read by ``store.history`` (append-only, partitioned Parquet).
May import: ``gate``, ``stats``, ``store``, ``data`` and the contract; never ``engine``,
``report`` or ``app``.
"""
