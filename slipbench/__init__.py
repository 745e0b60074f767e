"""slipbench: a benchmark and measurement methodology for tactile slip detectors."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("slipbench")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0.0.0+unknown"
