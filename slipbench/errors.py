"""Errors that the CLI turns into one clear line and a distinct exit code."""


class SlipbenchError(Exception):
    """Base class: the message names what is wrong and where."""

    exit_code = 2


class DataError(SlipbenchError):
    """A dataset or results file breaks its format (exit code 2)."""


class UsageError(SlipbenchError):
    """A bad option, name or parameter (exit code 2)."""


class PluginError(SlipbenchError):
    """A plugin failed to import or raised while running (exit code 3)."""

    exit_code = 3
