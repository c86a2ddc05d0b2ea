"""What the ``rac`` commands share: exit codes, where outputs go, reading a `.ra` file, writing files
atomically.

Exit codes: 0 clean (warnings allowed), 1 errors in the input (or a query not satisfied), 2 bad
usage or a file that cannot be read or written, 3 an internal error (a bug in rac), 4 a query
that was not decided (``rac verify``: an *unknown* or *unsupported* verdict and none that fails).
"""

from __future__ import annotations

import argparse
import errno
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path

from rac.compiler import CompileResult, compile_file
from rac.core.diagnostics import Diagnostic, error
from rac.output.paths import OUTPUT_CONVENTION, OUTPUT_SUFFIX, output_folder
from rac.output.progress import notice

__all__ = ["EXIT_ERRORS", "EXIT_INTERNAL", "EXIT_OK", "EXIT_UNDECIDED", "EXIT_USAGE", "OUTPUT_CONVENTION",
           "OUTPUT_SUFFIX", "FileWriteError", "output_folder", "overwrites_source", "read_and_check", "same_file",
           "size_argument", "unreadable", "unwritable", "write_all_atomically", "write_atomically"]

EXIT_OK, EXIT_ERRORS, EXIT_USAGE, EXIT_INTERNAL, EXIT_UNDECIDED = 0, 1, 2, 3, 4



def unreadable(path: Path, exc: OSError) -> Diagnostic:
    """E0008: ``path`` cannot be read."""
    reason = exc.strerror or str(exc)
    if isinstance(exc, IsADirectoryError):
        reason = "it is a directory"
    return error("E0008", f"cannot read `{path}`: {reason}", None,
                 hints=["pass the path of a .ra file"])


def read_and_check(path: Path) -> tuple[CompileResult | None, Diagnostic | None]:
    """``rac check`` of one file, or the E0008 diagnostic when it cannot be read at all."""
    try:
        return compile_file(path, progress=notice()), None
    except OSError as exc:
        return None, unreadable(path, exc)


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


def unwritable(path: Path, exc: OSError) -> Diagnostic:
    """E0009: ``path`` cannot be written (nothing was)."""
    reason = exc.strerror or str(exc)
    return error("E0009", f"cannot write `{path}`: {reason}", None,
                 hints=["check that the folder exists and is writable; nothing was written"])


class FileWriteError(Exception):
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
    temporary file first, and the renames happen only once all of them are written.
    Raises :class:`FileWriteError` naming the file that failed."""
    for path, _ in files:
        if path.is_dir():  # os.replace would fail only after the earlier files were replaced
            raise FileWriteError(path, IsADirectoryError(errno.EISDIR, "it is a directory", str(path)))
    temporaries: list[tuple[Path, str]] = []
    # a symbolic link stays one: its target is rewritten
    files = [(Path(os.path.realpath(path)) if path.is_symlink() else path, text) for path, text in files]
    mask = os.umask(0)  # the mode a new file would get (mkstemp makes 0600)
    os.umask(mask)
    try:
        for path, text in files:
            directory = path.parent if str(path.parent) else Path(".")
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
                os.replace(temporary, path)
            except OSError as exc:
                raise FileWriteError(path, exc) from exc
    except BaseException:
        for _, temporary in temporaries:
            Path(temporary).unlink(missing_ok=True)
        raise


def size_argument(text: str) -> int:
    """An argparse ``type`` for a memory size such as ``512M`` or ``4G`` (``--max-memory``,
    ``--task-memory``): the bytes, more than 0."""
    from rac.engine.budget import parse_size

    try:
        size = parse_size(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    if size <= 0:
        raise argparse.ArgumentTypeError(f"`{text}` must be more than 0 bytes")
    return size
