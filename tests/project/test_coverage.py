"""Issue 24: every source module of ``src/rac`` is imported by at least one test module.

An ast scan of ``tests/**/*.py`` collects the modules named by ``import rac.x.y``,
``from rac.x.y import ...`` and ``from rac.x import y`` (when ``rac.x.y`` is a module). Every module
of the package but the ``__init__`` files and ``__main__`` must be among them, or be listed in
:data:`NOT_YET` with a reason; a module listed there that a test does import fails the test too, so
the list only shrinks.
"""

from __future__ import annotations

import ast
from pathlib import Path

import rac

TESTS = Path(__file__).resolve().parents[1]
PACKAGE = Path(rac.__file__).resolve().parent

#: Modules no test imports yet, each with the reason; remove an entry when its test lands.
NOT_YET: dict[str, str] = {
}


def source_modules(package: Path = PACKAGE) -> set[str]:
    """The dotted names of the package's modules, but ``__init__`` and ``__main__``."""
    names = set()
    for path in package.rglob("*.py"):
        if path.stem in {"__init__", "__main__"}:
            continue
        parts = path.relative_to(package.parent).with_suffix("").parts
        names.add(".".join(parts))
    return names


def imported_modules(tree: ast.AST, known: set[str]) -> set[str]:
    """The ``rac`` modules a test module's syntax tree imports (``from rac.x import y`` counts
    ``rac.x.y`` when that is a module in ``known``, else ``rac.x``)."""
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names if alias.name.split(".")[0] == "rac")
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module \
                and node.module.split(".")[0] == "rac":
            found.add(node.module)
            found.update(f"{node.module}.{alias.name}" for alias in node.names
                         if f"{node.module}.{alias.name}" in known)
    return found


def covered_modules(known: set[str]) -> set[str]:
    covered = set()
    for path in TESTS.rglob("*.py"):
        covered |= imported_modules(ast.parse(path.read_text(encoding="utf-8"), str(path)), known)
    return covered & known


def test_the_scan_reads_every_import_form() -> None:
    known = {"rac.a.b", "rac.a.c", "rac.d", "rac.e.f"}
    tree = ast.parse("import rac.a.b\nfrom rac.a import c, helper\nfrom rac.d import thing\n"
                     "import os\nfrom . import rac\n")
    assert imported_modules(tree, known) & known == {"rac.a.b", "rac.a.c", "rac.d"}


def test_source_modules_leave_out_init_and_main() -> None:
    modules = source_modules()
    assert "rac.compiler" in modules
    assert not any(name.endswith(("__init__", "__main__")) for name in modules)


def test_every_module_is_imported_by_a_test() -> None:
    known = source_modules()
    covered = covered_modules(known)
    uncovered = sorted(known - covered - set(NOT_YET))
    assert not uncovered, "modules no test imports (add a test, or list them in NOT_YET with a reason):\n" \
        + "\n".join(uncovered)


def test_not_yet_lists_only_uncovered_modules() -> None:
    known = source_modules()
    stale = sorted(set(NOT_YET) & covered_modules(known))
    unknown = sorted(set(NOT_YET) - known)
    assert not stale, f"covered now, remove from NOT_YET: {stale}"
    assert not unknown, f"not modules of rac, remove from NOT_YET: {unknown}"
