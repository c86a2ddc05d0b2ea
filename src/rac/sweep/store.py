"""The sweep's store: one JSON file per finished task, ``OUT/tasks/KEY.json``, keyed by
:meth:`rac.sweep.task.TaskSpec.key` (a hash of the scenario file, the template, the settings, the task and
its options). Each file is written atomically (a temporary file and a rename), so a sweep stopped at
any moment leaves only whole rows; a re-run reads them back instead of running their tasks again.

Example::

    store = Store(Path("driving.out/sweep"))
    if not store.has(spec.key()):
        store.put(spec.key(), run_task(spec))
    row = store.get(spec.key())
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import IO

from rac.core.files import atomic_write

__all__ = ["TASKS_FOLDER", "Store", "write_text"]

#: The store's sub-folder of the sweep's output folder.
TASKS_FOLDER = "tasks"


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
