"""The `slipbench` command: the top-level click group, the commands it gathers from
``slipbench.app.commands`` (thin click commands, no logic beyond parsing and calling), and
``main``, which turns every error into its message and exit code."""

from __future__ import annotations

import importlib
import signal
import sys
import threading
import traceback
import warnings
from collections.abc import Iterator
from contextlib import contextmanager

import click

from slipbench.app.options import SuggestingGroup
from slipbench.errors import ENVIRONMENT_ERRNOS, SlipbenchError, environment_fault

EXIT_BUG = 70  # sysexits' EX_SOFTWARE: an internal error, reported with its traceback
EXIT_CODES = """Exit codes: 0 every cell ok or skipped; 1 compare found a regression; 2 bad usage or
bad data; 3 a plugin failed to load (failed cells listed too) or one named is unavailable; 4 the run finished but cells failed or timed out (listed);
5 an environment fault (disk full, read-only folder, permission); 70 a bug in slipbench (with
its traceback); 129, 130, 143 interrupted by SIGHUP, Ctrl-C (SIGINT), SIGTERM (128 + the
signal's number)."""

#: each command's module and attribute, imported only when that command runs (or its help
#: shows): `--version` and a mistyped command import none, `list` not what `evaluate` needs
COMMANDS = {
    "bench": "slipbench.app.commands.bench:bench",
    "calibrate": "slipbench.app.commands.calibrate:calibrate_command",
    "compare": "slipbench.app.commands.compare:compare_command",
    "dataset": "slipbench.app.commands.dataset:dataset",
    "evaluate": "slipbench.app.commands.evaluate:evaluate_command",
    "history": "slipbench.app.commands.history:history",
    "list": "slipbench.app.commands.list_plugins:list_plugins",
    "report": "slipbench.app.commands.report:report",
    "run": "slipbench.app.commands.run:run_command",
    "spectral": "slipbench.app.commands.spectral:spectral_cmd",
}


class LazyGroup(SuggestingGroup):
    """A group that imports a command's module when the command is asked for (click's
    documented pattern for lazily loaded subcommands)."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(COMMANDS)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in COMMANDS:
            return None
        module, attribute = COMMANDS[cmd_name].split(":")
        return getattr(importlib.import_module(module), attribute)


@click.group(cls=LazyGroup, epilog=EXIT_CODES)
@click.version_option(package_name="slipbench")
def cli() -> None:
    """Benchmark slip detectors on univariate tactile signals."""


INTERRUPTED = "interrupted{}; finished cells are kept, run the same command again to resume"
EXIT_SIGINT = 128 + signal.SIGINT  # what a shell reports for a process a signal ended
# what CI cancellation, `timeout`, `kill` and a closed terminal send: stop as Ctrl-C does
STOPPING = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name))


class Interrupted(BaseException):
    """A run stopped by SIGTERM or SIGHUP. Not an Exception, like KeyboardInterrupt: only the
    code that stops workers and keeps finished cells (``except BaseException``) sees it."""

    def __init__(self, signum: int) -> None:
        self.signum = signum
        super().__init__(signal.Signals(signum).name)


@contextmanager
def _signals_interrupt() -> Iterator[None]:
    """SIGTERM and SIGHUP raise Interrupted in the main thread while the block runs; a second
    one while the run stops is ignored. The previous handlers come back after."""
    if threading.current_thread() is not threading.main_thread():
        yield  # only the main thread may set handlers (a test or a caller's thread)
        return

    def interrupt(signum, frame) -> None:
        for other in STOPPING:
            signal.signal(other, signal.SIG_IGN)
        raise Interrupted(signum)

    previous = {signum: signal.signal(signum, interrupt) for signum in STOPPING}
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def _one_line_warning(message, *_where: object, **_line: object) -> None:
    """A warning as one line for the human (``warning: ...``), without the source line."""
    click.echo(f"warning: {message}", err=True)


def main(argv: list[str] | None = None) -> None:
    # the CLI's own warning format; catch_warnings restores Python's when main returns, so an
    # importer of slipbench (or a test calling main) keeps its own
    with warnings.catch_warnings():
        warnings.showwarning = _one_line_warning
        _main(argv)


def _main(argv: list[str] | None) -> None:
    try:
        with _signals_interrupt():
            cli.main(args=argv, prog_name="slipbench", standalone_mode=False)
    except click.exceptions.ClickException as exc:
        exc.show()
        sys.exit(exc.exit_code)
    except (click.exceptions.Abort, KeyboardInterrupt):  # click turns Ctrl-C into Abort
        click.echo(INTERRUPTED.format(""), err=True)
        sys.exit(EXIT_SIGINT)
    except Interrupted as exc:
        click.echo(INTERRUPTED.format(f" by {exc}"), err=True)
        sys.exit(128 + exc.signum)
    except SlipbenchError as exc:
        click.echo(f"error: {exc}", err=True)
        sys.exit(exc.exit_code)
    except OSError as exc:
        if exc.errno not in ENVIRONMENT_ERRNOS:
            _bug()
        fault = environment_fault(exc, exc.filename or "")
        click.echo(
            f"error: {fault}"
            if exc.filename
            else f"error: {fault.cause}, in a write whose path slipbench lost on the way (a bug "
            "in slipbench: please report it with the command)",
            err=True,
        )
        sys.exit(fault.exit_code)
    except Exception:  # noqa: BLE001 - anything else is a bug, and said to be one
        _bug()


def _bug() -> None:
    traceback.print_exc()
    click.echo(
        "error: this is a bug in slipbench or in a plugin, not a problem with your data or options; "
        "please report it with the traceback above",
        err=True,
    )
    sys.exit(EXIT_BUG)


if __name__ == "__main__":
    main()
