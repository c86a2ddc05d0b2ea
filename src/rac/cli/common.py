"""What the ``rac`` commands share: exit codes, where outputs go, reading a `.ra` file, writing files
atomically.

Exit codes: 0 clean (warnings allowed), 1 errors in the input (or a query not satisfied), 2 bad
usage or a file that cannot be read or written (standard output too: full, or closed), 3 an internal
error (a bug in rac), 4 a query that was not decided (``rac verify``: an *unknown* or *unsupported*
verdict and none that fails), 130 stopped by Ctrl-C and 143 by SIGTERM (every command takes SIGTERM as it
takes Ctrl-C, :func:`terminate_as_interrupt`: what was answered before is shown).
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import fcntl
import os
import signal
import sys
import tempfile
import time
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path

from rac.core.diagnostics import Diagnostic, RacError, error, render_json, render_text
from rac.core.files import written_by_rac
from rac.core.source import SourceFile, Span
from rac.engine.budget import default_max_bytes, parse_size
from rac.output.paths import OUTPUT_CONVENTION, OUTPUT_SUFFIX, output_folder

__all__ = ["EXIT_ERRORS", "EXIT_INTERNAL", "EXIT_INTERRUPTED", "EXIT_OK", "EXIT_TERMINATED", "EXIT_UNDECIDED",
           "EXIT_USAGE", "OUTPUT_CONVENTION", "OUTPUT_SUFFIX", "SOURCE_SUFFIX", "STALE_SECONDS", "FileWriteError",
           "NotRegularFile", "StdoutError", "as_json", "check_writable", "held_source", "how_stopped",
           "interrupted_by", "interrupts_as_such", "load_budget",
           "locked",
           "output_folder", "overwrites_source", "overwrites_source_in", "print_diagnostics", "resource_limit",
           "same_file", "size_argument", "stdout_unwritable", "stopping_signal", "terminate_as_interrupt", "unreadable",
           "unusable_file", "unwritable", "usage_error", "write_all_atomically", "write_atomically"]

EXIT_OK, EXIT_ERRORS, EXIT_USAGE, EXIT_INTERNAL, EXIT_UNDECIDED = 0, 1, 2, 3, 4
#: The exit code after Ctrl-C (128 + SIGINT), as the shell reports it.
EXIT_INTERRUPTED = 130
#: The exit code after SIGTERM (128 + 15), as the shell reports a process it ended.
EXIT_TERMINATED = 143

#: The suffix of the files rac reads: no output of an engine command (verify, simulate, render,
#: preanalyse, experiment) has it, so their output folder may hold the input file under it.
SOURCE_SUFFIX = ".ra"
#: A writer's temporary file older than this (seconds) was left by a writer that was killed: the
#: next write of the same file removes it. A live writer writes its text at once, in far less time.
STALE_SECONDS = 3600
#: Why :func:`check_writable` refuses an existing file that may not be written (its E0009 has its own hint).
READ_ONLY = "the file is read-only"


#: The signals :func:`terminate_as_interrupt` turned into ``KeyboardInterrupt`` in this command (what
#: :func:`how_stopped` says); emptied each time it is entered.
_STOPPED_BY: list[int] = []


@contextlib.contextmanager
def terminate_as_interrupt() -> Iterator[list[int]]:
    """In here SIGTERM (``timeout``, a batch system's time limit, ``kill``) stops the command as Ctrl-C does
    (``KeyboardInterrupt``): what was answered before is shown and the files finished stay, where Python's
    default ended the process on the spot, printing nothing. Yields a list that receives the signal's number
    when it came (the exit code is then :data:`EXIT_TERMINATED`)."""
    came: list[int] = []
    _STOPPED_BY.clear()

    def stop(number: int, frame: object) -> None:
        came.append(number)
        _STOPPED_BY.append(number)
        raise KeyboardInterrupt

    try:
        previous = signal.signal(signal.SIGTERM, stop)
    except ValueError:  # not the main thread: signals cannot be handled here
        yield came
        return
    try:
        yield came
    finally:
        signal.signal(signal.SIGTERM, previous)


def stopping_signal() -> str:
    """The signal that stopped a command which met ``KeyboardInterrupt``: ``"SIGTERM"`` when SIGTERM came
    (:func:`terminate_as_interrupt`), else ``"SIGINT"`` (Ctrl-C)."""
    return "SIGTERM" if _STOPPED_BY else "SIGINT"


def how_stopped() -> str:
    """How a command that met ``KeyboardInterrupt`` was stopped, for its message: ``"terminated (SIGTERM)"``
    when SIGTERM came (:func:`terminate_as_interrupt`), else ``"interrupted"`` (Ctrl-C)."""
    return "terminated (SIGTERM)" if _STOPPED_BY else "interrupted"


def interrupted_by(exc: BaseException) -> bool:
    """Whether ``exc`` is Ctrl-C (or SIGTERM, :func:`terminate_as_interrupt`) or was raised because of it: a C
    extension whose import it stopped (stormpy's, matplotlib's: pybind11 modules) raises ``ImportError:
    initialization failed`` from the ``KeyboardInterrupt``, which is no bug in rac."""
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:  # a chain may loop back on itself
        if isinstance(current, KeyboardInterrupt):
            return True
        seen.add(id(current))
        current = current.__cause__ or current.__context__
    return False


@contextlib.contextmanager
def interrupts_as_such() -> Iterator[None]:
    """In here an exception raised because of Ctrl-C or SIGTERM (:func:`interrupted_by`) is re-raised as the
    ``KeyboardInterrupt`` it was, so that the command shows what it answered before and exits 130 or 143 instead
    of reporting an internal error (exit 3) and dropping those answers."""
    try:
        yield
    except Exception as exc:
        if interrupted_by(exc):
            raise KeyboardInterrupt from exc
        raise


def as_json(args: argparse.Namespace) -> bool:
    """Whether the command was asked for ``--format json`` (commands without the option: no)."""
    return getattr(args, "format", None) == "json"


def with_ok(document: Mapping[str, object], status: int) -> dict[str, object]:
    """``document`` with ``"ok"`` added: true exactly when the command exits with ``status`` 0, for every
    command alike; a command decides its exit status first and prints the document from it, so the two never
    disagree."""
    return {**document, "ok": status == EXIT_OK}


def print_diagnostics(diagnostics: Iterable[Diagnostic], sources: Mapping[str, SourceFile] | None = None,
                      structured: bool = False) -> None:
    """The one place a command prints diagnostics it does not fold into a document of its own: with
    ``structured`` (``--format json``) a JSON array on standard output, what a script parses (never text
    there), else text on standard error (with the source line when ``sources`` has the file)."""
    if structured:
        print(render_json(diagnostics))
    else:
        print(render_text(diagnostics, sources or {}), file=sys.stderr)


def usage_error(message: str, *, notes: Iterable[str] = (), hints: Iterable[str] = ()) -> Diagnostic:
    """E0014: an option's value (or a combination of options) the command cannot use, found after the
    arguments were parsed (exit 2)."""
    return error("E0014", message, None, notes=notes, hints=hints)


def unusable_file(message: str, *, notes: Iterable[str] = (), hints: Iterable[str] = (),
                  span: Span | None = None) -> Diagnostic:
    """E0015: a file that passes ``rac check`` but that the command cannot run on (no ``model`` block,
    a run that leaves the int32 range, an experiment without a safe strategy; exit 1); ``span``: the place in
    the file it is due to (a run's value beyond int32: the `model` block's `exponent`, or the binding)."""
    return error("E0015", message, span, notes=notes, hints=hints)


def resource_limit(message: str, *, hints: Iterable[str] = ()) -> Diagnostic:
    """E0016: the work needs more than the memory or state budget (``--max-memory``, ``--max-states``)
    or the machine allows; the input is not at fault (exit 2)."""
    return error("E0016", message, None, hints=hints)


def unreadable(path: Path, exc: OSError) -> Diagnostic:
    """E0008: ``path`` cannot be read."""
    reason = exc.strerror or str(exc)
    if isinstance(exc, IsADirectoryError):
        reason = "it is a directory"
    return error("E0008", f"cannot read `{path}`: {reason}", None,
                 hints=["pass the path of a .ra file"])


def same_file(output: Path, source: Path) -> bool:
    """Whether writing ``output`` would overwrite ``source`` (the same file, by any path or link)."""
    try:
        return output.exists() and os.path.samefile(output, source)
    except OSError:
        return False


def overwrites_source(output: Path, source: Path) -> Diagnostic:
    """E0009: ``output`` is the input file itself (nothing was written)."""
    return error("E0009", f"cannot write `{output}`: it is the input file `{source}`", None,
                 hints=["choose another output file; rac never overwrites the `.ra` file it reads"])


def not_generated(output: Path) -> Diagnostic | None:
    """E0009 when ``output`` is a file with content that rac did not write (no :data:`rac.core.files.GENERATED_MARK`
    in its first 4 KB): ``rac compile`` replaces only its own outputs, never a user's file."""
    try:
        if not output.is_file() or output.stat().st_size == 0:
            return None
        with output.open("rb"):
            pass
    except OSError:
        return None  # unreadable: writing reports it (check_writable, write_atomically)
    if written_by_rac(output):
        return None
    return error("E0009", f"cannot write `{output}`: it exists and rac did not write it", None,
                 notes=["rac compile replaces only the files it wrote (they begin by saying so)"],
                 hints=["choose another output file, or remove this one first if it may go"])


def held_source(folder: Path, source: Path) -> Path | None:
    """The path by which ``source`` (its name, or the file a link leads to) lies in ``folder`` or below
    it under a name not ending in :data:`SOURCE_SUFFIX`, so that an output written there may replace it;
    None when it lies elsewhere. An engine command's outputs have names of their own (``runs.csv``, a
    query's ``NAME.png``, temporaries beside them), none ending in ``.ra``."""
    out = Path(os.path.realpath(folder))
    entry = Path(os.path.realpath(source.parent)) / source.name  # the name itself, a link not followed
    for path in dict.fromkeys((entry, Path(os.path.realpath(source)))):
        if not path.name.endswith(SOURCE_SUFFIX) and path.is_relative_to(out):
            return source if path == entry else path
    return None


def overwrites_source_in(folder: Path, held: Path, source: Path) -> Diagnostic:
    """E0009: the output folder ``folder`` holds the input file ``source`` (as ``held``) under a name an
    output may take (nothing was written)."""
    also = "" if held == source else f" (as `{held}`)"
    return error("E0009", f"cannot write into `{folder}`: it holds the input file `{source}`{also}, which an "
                          "output may replace", None,
                 hints=[f"choose another folder with -o, or name the input FILE{SOURCE_SUFFIX} (no output has "
                        f"that suffix); rac never overwrites the `{SOURCE_SUFFIX}` file it reads"])


class NotRegularFile(RacError, OSError):
    """An existing path that is not a regular file (a FIFO, a device, a socket): rac replaces only
    regular files, where a rename would swap a pipe or a device node for a file."""

    def __init__(self, path: Path) -> None:
        super().__init__(errno.EINVAL, "it is not a regular file (a pipe or a device?)", str(path))


def check_writable(path: Path) -> None:
    """Raise the ``OSError`` that writing ``path`` is bound to meet, known before anything is written:
    ``path`` is a folder (``IsADirectoryError``), or exists and is no regular file (:class:`NotRegularFile`)
    or read-only (``PermissionError``), or its name is too long (the file system's own error)."""
    if not path.name or path.is_dir():  # `-o /`, `-o .`: os.replace would fail, or name no file
        raise IsADirectoryError(errno.EISDIR, "it is a directory", str(path))
    if path.exists() and not path.is_file():  # is_file follows a link: a link to a FIFO is refused too
        raise NotRegularFile(path)
    # a rename needs only the folder's permission: without this a read-only file was replaced where
    # writing it (open) is refused, as every editor and formatter refuses it
    if path.exists() and not os.access(path, os.W_OK):
        raise PermissionError(errno.EACCES, READ_ONLY, str(path))


def unwritable(path: Path, exc: OSError, *, kept: str | None = None) -> Diagnostic:
    """E0009: ``path`` cannot be written (nothing was; or, when work was written before it, ``kept`` says what
    stands)."""
    reason = exc.strerror or str(exc)
    # the hint names the remedy of the condition: a folder is not the problem with a long name
    hint = {errno.ENAMETOOLONG: "use a shorter name (a file system allows about 255 bytes per name)",
            errno.ENOTDIR: "a part of the path is a file, not a folder: choose another path",
            errno.EISDIR: "name a file, not a folder",
            # mkdir of the output folder (-o DIR) over a file: "File exists" alone sent users to the permissions
            errno.EEXIST: "a file stands where a folder is needed (an engine command's -o names a folder, not a "
                          "file): choose another path",
            errno.ENOSPC: "free some space on the disk or write elsewhere",
            errno.EROFS: "the file system is read-only: write elsewhere"}.get(
        exc.errno or 0, "check that the folder exists and is writable")
    if isinstance(exc, NotRegularFile):
        hint = "rac replaces only regular files: choose the path of a file, or a new one"
    elif exc.errno == errno.EACCES and reason == READ_ONLY:
        hint = "make it writable (`chmod u+w`) if it may change"
    return error("E0009", f"cannot write `{path}`: {reason}", None, hints=[f"{hint}; {kept or 'nothing was written'}"])


class StdoutError(RacError):
    """Standard output cannot be written (full disk, closed, ...): the user's or the environment's
    condition, not a bug in rac; ``cause`` says why."""

    def __init__(self, cause: OSError) -> None:
        super().__init__(f"cannot write standard output: {cause}")
        self.cause = cause


def stdout_unwritable(exc: OSError) -> Diagnostic:
    """E0009: standard output cannot be written (what was printed before may be incomplete)."""
    reason = "it is closed" if exc.errno == errno.EBADF else exc.strerror or str(exc)
    return error("E0009", f"cannot write `<standard output>`: {reason}", None,
                 hints=["send the output where it can be written (another redirect, a disk with free space, "
                        "or -o FILE where the command has it); what was printed may be incomplete"])


@contextlib.contextmanager
def locked(path: Path) -> Iterator[None]:
    """Hold an advisory lock (``flock``) on the folder of ``path`` while rac reads and rewrites it:
    ``rac fmt`` and ``rac tune`` on one file at once take turns instead of losing each other's work.
    The folder, not a lock file beside ``path``: nothing is left behind, and the lock survives the
    rename that replaces the file. Without a folder that can be opened there is no lock (nor a write).
    A symbolic link's target's folder: that is where the file is rewritten (:func:`write_all_atomically`),
    so rac on the link and rac on the file itself take turns too."""
    fd: int | None = None
    with contextlib.suppress(OSError):
        fd = os.open(Path(os.path.realpath(path)).parent, os.O_RDONLY)
        fcntl.flock(fd, fcntl.LOCK_EX)
    try:
        yield
    finally:
        if fd is not None:
            os.close(fd)  # closing releases the lock


def _remove_stale_temporaries(path: Path) -> None:
    """Remove ``.NAME.*.tmp`` files beside ``path`` that a killed writer left (older than
    :data:`STALE_SECONDS`); a failure to look or remove is no reason to fail the write."""
    cutoff = time.time() - STALE_SECONDS
    with contextlib.suppress(OSError):
        for leftover in path.parent.glob(f".{path.name}.*.tmp"):
            with contextlib.suppress(OSError):
                if leftover.stat().st_mtime < cutoff:
                    leftover.unlink()


class FileWriteError(RacError):
    """Writing ``path`` failed with ``cause``; raised by :func:`write_all_atomically`."""

    def __init__(self, path: Path, cause: OSError) -> None:
        super().__init__(f"cannot write {path}: {cause}")
        self.path = path
        self.cause = cause


def write_atomically(path: Path, text: str) -> None:
    """Write via a temporary file in the same folder and a rename: never a half-written file.
    Raises the ``OSError`` of the failure."""
    try:
        write_all_atomically([(path, text)])
    except FileWriteError as failure:
        raise failure.cause from None


def write_all_atomically(files: Sequence[tuple[Path, str]]) -> None:
    """Write several files so that, on error, none of them changed: every text goes to a
    temporary file first, and the renames happen only once all of them are written. A file with
    hard links is rewritten in place instead (after its temporary copy is complete), so the links
    stay; temporaries a killed writer left are removed (:data:`STALE_SECONDS`).
    Raises :class:`FileWriteError` naming the file that failed."""
    resolved: list[tuple[Path, str]] = []
    for path, text in files:
        try:  # a name too long, a "folder" that is a file: OSError here too
            # a folder, a FIFO or a device: os.replace would fail only after the earlier files were
            # replaced, or swap the FIFO or device node for a file
            check_writable(path)
            # a symbolic link stays one: its target is rewritten
            resolved.append((Path(os.path.realpath(path)) if path.is_symlink() else path, text))
        except OSError as exc:
            raise FileWriteError(path, exc) from exc
    files = resolved
    temporaries: list[tuple[Path, str]] = []
    mask = os.umask(0)  # the mode a new file would get (mkstemp makes 0600)
    os.umask(mask)
    try:
        for path, text in files:
            directory = path.parent if str(path.parent) else Path(".")
            _remove_stale_temporaries(path)
            try:
                fd, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
                temporaries.append((path, temporary))
                with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as handle:
                    handle.write(text)
                os.chmod(temporary, path.stat().st_mode & 0o777 if path.exists() else 0o666 & ~mask)
            except OSError as exc:
                raise FileWriteError(path, exc) from exc
        for path, temporary in temporaries:
            try:
                if _linked(path):  # a hard link stays one: the text goes into the file itself, the
                    # complete temporary copy written first (the disk had room for it)
                    try:
                        with open(path, "w", encoding="utf-8", newline="\n") as handle:
                            handle.write(dict(files)[path])
                    except OSError as exc:  # never half a file here: the complete copy replaces it
                        os.replace(temporary, path)
                        raise OSError(exc.errno, f"{exc.strerror}; `{path}` has all of the new text, but as a "
                                                 "new file: its other hard links may hold part of it") from exc
                    os.unlink(temporary)
                else:
                    os.replace(temporary, path)
            except OSError as exc:
                raise FileWriteError(path, exc) from exc
    except BaseException:
        for _, temporary in temporaries:
            Path(temporary).unlink(missing_ok=True)
        raise


def _linked(path: Path) -> bool:
    """Whether ``path`` is a file with more than one hard link (a rename would break them)."""
    try:
        return path.stat().st_nlink > 1
    except OSError:
        return False


def load_budget(args: argparse.Namespace) -> int:
    """The memory budget of the scenario's load: ``--max-memory``, else the engine's default (half the machine)."""

    return args.max_memory or default_max_bytes()


def size_argument(text: str) -> int:
    """An argparse ``type`` for a memory size such as ``512M`` or ``4G`` (``--max-memory``,
    ``--task-memory``): the bytes, more than 0."""

    try:
        size = parse_size(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    if size <= 0:
        raise argparse.ArgumentTypeError(f"`{text}` must be more than 0 bytes")
    return size
