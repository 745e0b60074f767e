"""The stream wing: detectors scored as a robot would run them, on continuous recordings.

Slip onsets, detection delays and false alarms per minute with their intervals (``metrics``), and
the worker side of a streaming cell: a fitted detector's live ``Streamer`` pushed through each
test recording (``cell``). The live scorer itself is part of the contract (``slipbench.base``).
May import: the contract only.
"""
