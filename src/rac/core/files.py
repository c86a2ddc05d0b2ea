"""Writing a file so that a reader never sees half of it (:func:`atomic_write`).

Example::

    from rac.core.files import atomic_write

    atomic_write("out.xml", lambda f: f.write(data))
"""

from __future__ import annotations

import os
import secrets
from collections.abc import Callable
from pathlib import Path
from typing import IO

__all__ = ["atomic_write"]


def atomic_write(path: str | os.PathLike[str], write: Callable[[IO[bytes]], object]) -> Path:
    """Call ``write(file)`` on a new temporary file next to ``path``, then move it onto ``path``
    (:func:`os.replace`): an interrupted write leaves ``path`` as it was, never truncated.

    On any error the temporary file is removed and ``path`` is left as it was. Used for every
    PNG, GIF and generated scene rac writes.

    Example::

        atomic_write("out.png", lambda f: figure.savefig(f, format="png"))
    """
    target = Path(path)
    # open(..., "xb") rather than tempfile.mkstemp: mkstemp creates the file 0600, and os.replace
    # would carry that mode over to the file; "xb" honours the umask like any ordinary file
    temporary = target.with_name(f".{target.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
    try:
        try:
            file = open(temporary, "xb")
        except OSError as exc:  # a missing folder, no permission: said of the file asked for, not the temporary
            raise type(exc)(exc.errno, exc.strerror, os.fspath(target)) from exc
        with file:
            write(file)
        os.replace(temporary, target)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise
    return target
