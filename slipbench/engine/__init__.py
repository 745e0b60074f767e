"""The engine wing: a run from plan to stored rows.

Plugins by id from entry points and folders (``registry``), every cell's windows and keys
computed once (``plan``), one model fitted and its test sets scored in a worker (``fitting``),
serial, process-pool and dask executors (``executors``), the loop that records each cell
(``runner``) and what a dataset can support before a run (``check``). May import: ``stats``,
``stream``, ``data``, ``store`` and the contract.
"""
