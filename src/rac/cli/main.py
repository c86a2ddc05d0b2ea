"""The ``rac`` command: check, compile and format `.ra` files, tune their parameters
(:mod:`rac.cli.tune`), start one from the standard library (:mod:`rac.cli.new`); verify, simulate, render and
pre-analyse them with the native engine (:mod:`rac.cli.engine`).

Exit codes: :mod:`rac.cli.common` has them (``EXIT_*``); memory that ran out is 2 (a resource, not the
input), an internal error 3 (a bug in rac; set RAC_DEBUG=1 for the traceback), Ctrl-C 130 and SIGTERM 143
(taken as Ctrl-C is: what was answered before it is shown).
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import importlib
import os
import sys
from collections.abc import Sequence
from typing import TextIO

from rac.cli.arguments import COMMANDS, CommandLineError, build_parser
from rac.cli.common import (
    EXIT_ERRORS,
    EXIT_INTERNAL,
    EXIT_INTERRUPTED,
    EXIT_TERMINATED,
    EXIT_USAGE,
    StdoutError,
    as_json,
    how_stopped,
    interrupts_as_such,
    print_diagnostics,
    resource_limit,
    stdout_unwritable,
    terminate_as_interrupt,
    usage_error,
    with_ok,
)
from rac.core.diagnostics import RacError, display_text, json_text, render_text
from rac.core.resources import ScenarioTooLarge
from rac.engine.budget import EstimateExceeded


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``rac`` command; returns the exit code."""
    stderr = sys.stderr
    sys.stderr = StderrSafe(stderr)  # type: ignore[assignment]  # `rac check x.ra 2>&-`: still its own status
    try:
        return _main(argv)
    finally:
        sys.stderr = stderr


def _main(argv: Sequence[str] | None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse exits 2 on bad usage, 0 on --help
        return int(exc.code or 0)
    except CommandLineError as exc:  # bad usage under --format json: the usage as text, the error as JSON too
        return _command_line_error(exc)
    module, function = COMMANDS[args.command]
    stdout = sys.stdout
    safe = ReaderSafe(stdout)
    sys.stdout = safe  # `rac check ... | head`: the command still ends with its own status
    terminated: list[int] = []  # SIGTERM came: the exit code says so (143, not Ctrl-C's 130)
    try:
        # SIGTERM (`timeout`, a batch system's limit) as Ctrl-C: the command shows what it answered before it
        with terminate_as_interrupt() as terminated, interrupts_as_such():
            # only the command that runs is imported (rac --version and a usage error load none)
            status = getattr(importlib.import_module(module), function)(args)
            sys.stdout.flush()  # here, not at exit: a full disk is reported like any other write
        return EXIT_TERMINATED if terminated and status == EXIT_INTERRUPTED else status
    except StdoutError as exc:  # the environment's, not a bug: say what failed, exit 2
        print(render_text([stdout_unwritable(exc.cause)], {}), file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print(f"rac: {how_stopped()}", file=sys.stderr)
        status = EXIT_TERMINATED if terminated else EXIT_INTERRUPTED
        _last_document(args, safe, status, interrupted=True)
        return status
    except (ScenarioTooLarge, EstimateExceeded) as exc:  # refused before it starts: the budget is at fault
        print_diagnostics([resource_limit(f"resource limit: {exc}")], structured=as_json(args))
        return EXIT_USAGE
    except MemoryError as exc:  # the machine or the process limit ran out, not a bug and not a broken input
        if os.environ.get("RAC_DEBUG"):
            raise
        print_diagnostics([resource_limit(
            f"out of memory{': ' + str(exc) if str(exc) else ''}: rac needed more memory than this process "
            "may use (the machine's memory, or a limit such as `ulimit -v`); the input files are not at fault",
            hints=["raise the limit, or lower --max-memory (where the command has it) so that rac stops before "
                   "it"])], structured=as_json(args))
        return EXIT_USAGE
    except RacError as exc:
        if exc.diagnostic is None:  # a failure rac handles itself reached the top: a bug, reported below
            return _last_document(args, safe, _internal_error(exc), error=exc)
        # a failure in the user's words (after the checker): the one renderer, like rac check's findings
        print_diagnostics([exc.diagnostic], structured=as_json(args))
        return EXIT_ERRORS
    except Exception as exc:  # a bug in rac: say so plainly instead of a traceback
        return _last_document(args, safe, _internal_error(exc), error=exc)
    finally:
        sys.stdout = stdout


def _command_line_error(exc: CommandLineError) -> int:
    """A mistake in a command line that asks for ``--format json``: argparse's usage message on standard error,
    as without the option, and on standard output the one document a script reads, a JSON array of one E0014
    (the shape every command gives an error of the whole command). Returns :data:`EXIT_USAGE`."""
    exc.parser.print_usage(sys.stderr)
    print(f"{exc.parser.prog}: error: {exc.message}", file=sys.stderr)
    stdout = sys.stdout
    sys.stdout = ReaderSafe(stdout)  # a reader that left, a full disk: still exit 2, never a traceback
    try:
        print_diagnostics([usage_error(exc.message, hints=[f"`{exc.parser.prog} --help` lists its options and "
                                                           "the values they take"])], structured=True)
        sys.stdout.flush()
    except StdoutError as failure:
        print(render_text([stdout_unwritable(failure.cause)], {}), file=sys.stderr)
    finally:
        sys.stdout = stdout
    return EXIT_USAGE


def _last_document(args: argparse.Namespace, stdout: ReaderSafe, status: int, *, interrupted: bool = False,
                   error: Exception | None = None) -> int:
    """With ``--format json``, when the command stopped (Ctrl-C, SIGTERM, an internal error) before it printed
    anything: a JSON document on standard output all the same, ``{"command", "ok": false, "exit_code",
    "interrupted", "error"}``, so that a script reading it finds one document, as after any other outcome (the
    message stays on standard error). Returns ``status``."""
    if as_json(args) and not stdout.written:
        document = with_ok({"command": args.command, "exit_code": status, "interrupted": interrupted,
                            "error": None if error is None else f"internal error: {type(error).__name__}: {error}"},
                           status)
        with contextlib.suppress(StdoutError):  # nowhere to print it: the message on standard error stands
            print(json_text(document, indent=2))
            stdout.flush()
    return status


def _internal_error(exc: Exception) -> int:
    """Report ``exc`` as a bug in rac (exit 3); with RAC_DEBUG set, re-raise it for the traceback."""
    if os.environ.get("RAC_DEBUG"):
        raise exc
    print(f"rac: internal error: {type(exc).__name__}: {exc}\n"
          "This is a bug in rac; rerun with RAC_DEBUG=1 for the traceback and report it.", file=sys.stderr)
    return EXIT_INTERNAL


class ReaderSafe:
    """Standard output that outlives its reader. When the reader leaves (``rac check ... | head -1``),
    the rest of the output is dropped and the command goes on to its own exit status: a failed check
    stays failed whoever reads its first line.

    Any other failure to write (a full disk, a closed standard output) raises :class:`StdoutError`,
    once: later output is dropped, so that the report of it and the exit go through.
    """

    def __init__(self, stream: TextIO | None) -> None:
        self._stream = stream
        self.gone = False
        #: Whether the command printed anything (a JSON document, in part or whole).
        self.written = False

    def write(self, text: str) -> int:
        self.written = self.written or bool(text)
        if not self.gone:
            try:
                if self._stream is None:  # started with standard output closed (`rac ... >&-`)
                    raise OSError(errno.EBADF, "standard output is closed")
                # a file name that is not UTF-8 (`rac check $'bad\xff.ra'`) as the renderer shows it: a strict
                # UTF-8 standard output refused its surrogate escapes (an internal error, exit 3)
                return self._stream.write(display_text(text))
            except BrokenPipeError:
                self._reader_left()
            except OSError as exc:
                self._reader_left()
                raise StdoutError(exc) from exc
        return len(text)

    def flush(self) -> None:
        if not self.gone and self._stream is not None:
            try:
                self._stream.flush()
            except BrokenPipeError:
                self._reader_left()
            except OSError as exc:
                self._reader_left()
                raise StdoutError(exc) from exc

    def _reader_left(self) -> None:
        self.gone = True
        if self._stream is None:
            return
        try:  # later flushes of the real stream (at exit too) go to /dev/null, silently
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, self._stream.fileno())
            os.close(devnull)
        except (OSError, ValueError, AttributeError):
            pass

    def __getattr__(self, name: str):
        return getattr(self._stream, name)


class StderrSafe:
    """Standard error that never fails the command. Closed (``rac check x.ra 2>&-``) or unwritable
    (``2>/dev/full``), its messages are dropped: there is nowhere left to report that failure, and the
    command's exit status (its verdict, or the error it reports) is the one it would have had.
    """

    def __init__(self, stream: TextIO | None) -> None:
        self._stream = stream
        self.gone = stream is None

    def write(self, text: str) -> int:
        if not self.gone and self._stream is not None:
            try:
                return self._stream.write(display_text(text))  # as standard output's (ReaderSafe)
            except (OSError, ValueError):  # ValueError: the stream itself was closed
                self._drop()
        return len(text)

    def flush(self) -> None:
        if not self.gone and self._stream is not None:
            try:
                self._stream.flush()
            except (OSError, ValueError):
                self._drop()

    def _drop(self) -> None:
        self.gone = True
        try:  # the real stream's buffered text, flushed again at exit, goes to /dev/null, silently
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, self._stream.fileno())  # type: ignore[union-attr]
            os.close(devnull)
        except (OSError, ValueError, AttributeError):
            pass

    def isatty(self) -> bool:
        return not self.gone and self._stream is not None and self._stream.isatty()

    def __getattr__(self, name: str):
        return getattr(self._stream, name)


def entry() -> None:
    """The console script (and ``python -m rac``): :func:`main` on streams that cannot fail to encode."""
    # a stream whose encoding cannot say a character (PYTHONIOENCODING=ascii, a C locale, a Windows code
    # page) would end `rac check ü.ra` in an internal error: such a character is written as its escape
    for stream in (sys.stdout, sys.stderr):
        reconfigure = getattr(stream, "reconfigure", None)
        if reconfigure is not None and getattr(stream, "errors", "strict") == "strict":
            reconfigure(errors="backslashreplace")
    sys.exit(main())


if __name__ == "__main__":
    entry()
