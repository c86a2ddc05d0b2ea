"""The sweep's store: one JSON file per finished task, ``OUT/tasks/KEY.json``, keyed by
:meth:`rac.sweep.task.TaskSpec.key` (a hash of the scenario file, the template, the settings, the task and
its options). Each file is written atomically (a temporary file and a rename), so a sweep stopped at
any moment leaves only whole rows; a re-run reads them back instead of running their tasks again.

Example::

    store = Store(Path("driving.out/sweep"))
    if not store.has(spec.key()):
        store.put(spec.key(), run_task(spec))
    row = store.get(spec.key())

A sweep holds its output folder for its life (:func:`holding`): two sweeps into one folder at once would
interleave their ``results.*``, so the second is refused (:class:`FolderBusy`), naming the first one's process.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import socket
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from rac.core.diagnostics import RacError
from rac.core.files import atomic_write

__all__ = ["LOCK_FILE", "TASKS_FOLDER", "FolderBusy", "Store", "holding", "write_text"]

#: The store's sub-folder of the sweep's output folder.
TASKS_FOLDER = "tasks"
#: The lock file of a sweep's output folder (:func:`holding`), holding the running sweep's process id and host.
LOCK_FILE = ".rac-sweep.lock"


class FolderBusy(RacError):
    """Another sweep holds the output folder ``folder`` (:func:`holding`): its process ``pid`` on ``host``
    (None: not known yet, it had just taken the folder)."""

    def __init__(self, folder: Path, pid: int | None, host: str | None) -> None:
        self.folder, self.pid, self.host = folder, pid, host
        who = "another rac sweep" if pid is None else f"another rac sweep (process {pid}" + (
            f" on {host})" if host and host != socket.gethostname() else ")")
        super().__init__(f"{who} is running into the output folder {folder}: two sweeps there at once would "
                         "interleave their results.*; wait for it to end, or give this one another folder (-o DIR)")


def _holder(fd: int) -> tuple[int | None, str | None]:
    """The process id and host a lock file's holder wrote into it (None, None when it has not yet)."""
    with contextlib.suppress(OSError, ValueError):
        pid, _, host = os.pread(fd, 512, 0).decode("utf-8").strip().partition(" ")
        return int(pid), host or None
    return None, None


@contextlib.contextmanager
def holding(folder: Path) -> Iterator[None]:
    """Hold ``folder`` (created if need be) for one sweep while the block runs: an advisory lock (``flock``) on
    its :data:`LOCK_FILE`, which holds this process's id and host; :class:`FolderBusy` at once when another
    process holds it. A lock whose holder is gone (killed: the system releases its locks) is taken over; the file
    is removed at the end. Where the file system has no locks (some network mounts) there is no lock, as for
    ``rac fmt``'s; ``OSError`` when the folder cannot be created or the file written."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / LOCK_FILE
    fd = _lock(path, folder)
    if fd is None:  # no locks on this file system
        yield
        return
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()} {socket.gethostname()}\n".encode(), 0)
        yield
    finally:
        with contextlib.suppress(OSError):
            path.unlink()  # before the lock is released: a sweep that opened this file finds it gone (_lock)
        os.close(fd)


def _lock(path: Path, folder: Path) -> int | None:
    """The open, locked lock file ``path`` of ``folder``; None where the file system has no locks."""
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            pid, host = _holder(fd)
            os.close(fd)
            raise FolderBusy(folder, pid, host) from None
        except OSError:  # e.g. ENOLCK
            os.close(fd)
            return None
        try:  # the holder before may have removed the file between its open and this lock: lock the one there now
            current = os.stat(path).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            current = False
        if current:
            return fd
        os.close(fd)


def write_text(path: Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically (:func:`rac.core.files.atomic_write`); return the path."""

    def write(file: IO[bytes]) -> None:
        file.write(text.encode("utf-8"))

    return atomic_write(path, write)


class Store:
    """The finished tasks' rows under ``folder/tasks/``, one ``KEY.json`` each."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder / TASKS_FOLDER

    def path(self, key: str) -> Path:
        """The file of the task ``key``."""
        return self.folder / f"{key}.json"

    def get(self, key: str) -> dict[str, object] | None:
        """The stored row of ``key``; None when there is none, or when its file is not a row (e.g.
        edited by hand): such a task simply runs again."""
        try:
            row = json.loads(self.path(key).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None
        return row if isinstance(row, dict) and row.get("key") == key else None

    def has(self, key: str) -> bool:
        """Whether ``key`` has a usable stored row (the task need not run again)."""
        return self.get(key) is not None

    def put(self, key: str, row: dict[str, object]) -> Path:
        """Store ``row`` as the result of ``key`` (atomically; replaces an earlier one); returns its file.
        Raises ``OSError`` when the file cannot be written."""
        self.folder.mkdir(parents=True, exist_ok=True)
        path = self.path(key)
        write_text(path, json.dumps({**row, "key": key}, indent=1, default=str) + "\n")
        return path
