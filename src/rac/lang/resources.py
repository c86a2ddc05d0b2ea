"""Locate the files rac ships: the grammar and the standard library.

An installed wheel carries them inside the package (``rac/grammar``,
``rac/stdlib``); a source checkout keeps them at the top of the repository.
"""

from __future__ import annotations

from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent.parent  # the rac package (this module is in rac/lang)
_REPOSITORY = _PACKAGE.parent.parent


def _first_existing(*candidates: Path) -> Path:
    for candidate in candidates:
        if candidate.exists():
            return candidate
    raise FileNotFoundError(f"rac is installed without {candidates[0].name}: reinstall the package")


def grammar_path() -> Path:
    """The lark grammar of the `.ra` language."""
    return _first_existing(_PACKAGE / "grammar" / "rac.lark", _REPOSITORY / "grammar" / "rac.lark")


def stdlib_dir() -> Path:
    """The folder of standard-library `.ra` files (e.g. ``driving.ra``)."""
    return _first_existing(_PACKAGE / "stdlib", _REPOSITORY / "stdlib")


def stdlib_file(name: str) -> Path:
    """Path of one standard-library file, e.g. ``stdlib_file("driving.ra")``."""
    path = stdlib_dir() / name
    if not path.exists():
        available = ", ".join(sorted(p.name for p in stdlib_dir().glob("*.ra")))
        raise FileNotFoundError(f"no stdlib file {name!r}; available: {available}")
    return path
