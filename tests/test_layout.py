"""The house rules of src/rac, read from the code's own imports (Python's ``ast``).

Each rule fails with the offending file and line:

- no import cycle between modules, counting imports inside functions;
- no name starting with ``_`` imported from another module (what is shared is public);
- the layers (:data:`LAYERS`): each package imports only the packages below it, e.g. ``lang``
  nothing of rac but ``core`` and itself, ``check`` only ``core``, ``lang`` and ``ir``, the targets
  only ``core``, ``ir``, ``model`` and ``runtime``, the engine never ``targets``, ``check`` or
  ``lang``; only ``cli`` (and ``python -m rac``) imports ``cli``;
- at most a handful of modules directly under ``src/rac``.
- no ``except Exception`` (nor bare ``except:``) outside :data:`CATCH_ALL`, each with its reason;
- every exception class of ``src/rac`` derives from ``RacError`` (``rac.core.diagnostics``).

docs/architecture.md shows the same layers.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "rac"

#: package -> the packages its modules may import (its own always allowed). ``rac`` is the top level.
LAYERS: dict[str, set[str]] = {
    "core": set(),
    "lang": {"core"},
    "ir": {"core", "lang"},
    "check": {"core", "lang", "ir"},
    "model": {"core", "ir"},
    "runtime": {"core", "ir"},
    "targets": {"core", "ir", "model", "runtime"},
    "engine": {"core", "ir", "model", "runtime"},
    "output": {"core", "ir", "model"},
    "learning": {"core", "lang", "ir", "check", "model", "runtime", "engine", "output", "rac.compiler"},
    "verify": {"core", "lang", "ir", "check", "model", "runtime", "engine", "learning", "output", "rac.compiler"},
    "studies": {"core", "lang", "ir", "check", "model", "runtime", "engine", "learning", "output", "verify",
                "rac.compiler"},
    "sweep": {"rac", "rac.compiler", "core", "lang", "ir", "check", "model", "runtime", "engine", "output",
              "learning", "verify", "studies"},
    "cli": {"rac", "rac.compiler", "core", "lang", "ir", "check", "model", "runtime", "targets", "engine",
            "output", "learning", "verify", "studies", "sweep"},
}
#: The order in which the layers are listed (lowest first).
ORDER = ["rac", "rac.compiler", "core", "lang", "ir", "check", "model", "runtime", "targets", "engine", "output",
         "learning", "verify", "studies", "sweep", "cli"]
#: The modules directly under src/rac and what each may import.
TOP = {
    "rac": {"rac", "rac.compiler", "core", "runtime"},  # __init__: load, loads, compile_file, CheckError
    "rac.__main__": {"cli"},
    "rac.compiler": {"core", "lang", "ir", "check", "model"},
    "rac.gym": set(),  # registers the gymnasium ids by entry-point strings: imports gymnasium only
}


@dataclass(frozen=True)
class Import:
    module: str  # the importing module
    target: str  # the imported module
    name: str  # the imported name ("" for `import x`)
    file: Path
    line: int

    def __str__(self) -> str:
        return f"{self.file.relative_to(SRC.parents[1])}:{self.line}: {self.module} imports {self.target}" + (
            f".{self.name}" if self.name else "")


def modules() -> dict[str, Path]:
    found = {}
    for path in sorted(SRC.rglob("*.py")):
        parts = list(path.relative_to(SRC.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        found[".".join(parts)] = path
    return found


MODULES = modules()


def owner(name: str) -> str:
    """The module that defines ``name`` (a module, or a name inside one)."""
    while name not in MODULES and "." in name:
        name = name.rsplit(".", 1)[0]
    return name


def imports() -> Iterator[Import]:
    for module, path in MODULES.items():
        package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")[:len(package.split(".")) - (node.level - 1)]
                    source = ".".join(base + ([node.module] if node.module else []))
                else:
                    source = node.module or ""
                if source != "rac" and not source.startswith("rac."):
                    continue
                for alias in node.names:
                    full = f"{source}.{alias.name}"
                    if full in MODULES:
                        yield Import(module, full, "", path, node.lineno)
                    else:
                        yield Import(module, owner(source), alias.name, path, node.lineno)
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name == "rac" or alias.name.startswith("rac."):
                        yield Import(module, owner(alias.name), "", path, node.lineno)


IMPORTS = [i for i in imports() if i.target != i.module]


def layer(module: str) -> str:
    parts = module.split(".")
    return module if module in TOP else parts[1]


def private_attributes() -> Iterator[str]:
    """``module._name`` where ``module`` is an imported rac module (``from rac.engine import storm``,
    then ``storm._check(...)``): a private name reached through the module instead of imported."""
    for module, path in MODULES.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        aliases = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module and not node.level:
                for alias in node.names:
                    if f"{node.module}.{alias.name}" in MODULES:
                        aliases[alias.asname or alias.name] = f"{node.module}.{alias.name}"
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.asname and alias.name in MODULES:
                        aliases[alias.asname] = alias.name
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases
                    and node.attr.startswith("_") and not node.attr.startswith("__")
                    and aliases[node.value.id] != module):
                yield (f"{path.relative_to(SRC.parents[1])}:{node.lineno}: {module} uses "
                       f"{aliases[node.value.id]}.{node.attr}")


def test_no_private_names_cross_modules() -> None:
    private = [str(i) for i in IMPORTS if i.name.startswith("_") and not i.name.startswith("__")]
    private += private_attributes()
    assert not private, "private names imported from another module (make them public):\n" + "\n".join(private)


def test_the_layers() -> None:
    wrong = []
    for item in IMPORTS:
        source, target = layer(item.module), layer(item.target)
        if source == target or (source not in TOP and target == source):
            continue
        allowed = TOP[source] if source in TOP else LAYERS[source]
        if target not in allowed:
            wrong.append(f"{item}  ({source} may import {', '.join(sorted(allowed)) or 'nothing of rac'})")
    assert not wrong, "imports across the layers:\n" + "\n".join(wrong)


def test_every_module_belongs_to_a_layer() -> None:
    assert {layer(m) for m in MODULES} <= set(LAYERS) | set(TOP)


def test_no_import_cycles() -> None:
    edges: dict[str, dict[str, Import]] = {}
    for item in IMPORTS:
        edges.setdefault(item.module, {}).setdefault(item.target, item)
    state: dict[str, int] = {}
    stack: list[str] = []
    cycles = []

    def visit(node: str) -> None:
        state[node] = 1
        stack.append(node)
        for target in edges.get(node, {}):
            if state.get(target) == 1:
                loop = stack[stack.index(target):] + [target]
                cycles.append(" -> ".join(loop) + "\n    " + "\n    ".join(
                    str(edges[a][b]) for a, b in zip(loop, loop[1:])))
            elif target not in state:
                visit(target)
        stack.pop()
        state[node] = 2

    for module in MODULES:
        if module not in state:
            visit(module)
    assert not cycles, "import cycles:\n" + "\n".join(cycles)


def test_a_handful_of_modules_at_the_top() -> None:
    top = sorted(p.name for p in SRC.glob("*.py"))
    assert top == ["__init__.py", "__main__.py", "compiler.py", "gym.py"], top


@pytest.mark.parametrize("package", sorted(LAYERS))
def test_every_package_says_what_it_holds_and_may_import(package: str) -> None:
    init = SRC / package / "__init__.py"
    docstring = ast.get_docstring(ast.parse(init.read_text(encoding="utf-8"))) if init.exists() else None
    assert docstring, f"src/rac/{package}/__init__.py needs a docstring saying what the package holds"
    said = " ".join(docstring.split("May import:", 1)[-1].split()) if "May import:" in docstring else None
    expected = ", ".join(sorted(LAYERS[package], key=ORDER.index)) or "nothing of rac"
    assert said == f"{expected}.", (
        f"src/rac/{package}/__init__.py: its docstring should end with the line `May import: {expected}.`"
        " (the layers of tests/test_layout.py)")


#: The handlers that may catch every ``Exception`` (or bare ``except:``), ``file:function`` -> why. A
#: handler whose last statement is a bare ``raise`` (a cleanup that lets the failure go on) needs no entry.
CATCH_ALL: dict[str, str] = {
    "cli/main.py:_main": "the last-resort handler: a bug in rac is reported as an internal error (exit 3)",
    "learning/wrappers.py:step": "the user's inputs callable may raise anything: said with the state things are in",
    "sweep/task.py:run_task": "a task's failure is data (a row): the sweep goes on",
    "sweep/work.py:execute": "a task's failure is data (a row, saying where): the sweep goes on",
    "sweep/run.py:run_tasks": "a worker's result (a stand-in's, or unpickling it) may raise anything: a row",
    # commonroad-io raises a bare `Exception()` on a bad file: caught, and re-raised unless
    # rac.model.commonroad.reader_failure knows it as the library's
    "model/commonroad.py:load_scenario": "commonroad-io's failures (reader_failure) become a ScenarioError",
    "model/commonroad.py:_diagnose": "commonroad-io's failures (reader_failure) name the element at fault",
    "model/commonroad.py:_box": "commonroad-io's and shapely's failures (reader_failure): a shape rac cannot bound",
    "output/render.py:_read": "commonroad-io's failures (reader_failure) become a RenderError",
}


def catch_alls() -> Iterator[tuple[str, int]]:
    """``(file:function, line)`` of each handler catching ``Exception``/``BaseException`` or bare."""
    for path in sorted(SRC.rglob("*.py")):
        where = str(path.relative_to(SRC))

        def visit(node: ast.AST, function: str, where: str = where) -> Iterator[tuple[str, int]]:
            for child in ast.iter_child_nodes(node):
                name = child.name if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)) else function
                if isinstance(child, ast.ExceptHandler):
                    caught = child.type.elts if isinstance(child.type, ast.Tuple) else [child.type]
                    broad = child.type is None or any(
                        isinstance(c, ast.Name) and c.id in ("Exception", "BaseException") for c in caught)
                    reraises = isinstance(child.body[-1], ast.Raise) and child.body[-1].exc is None
                    if broad and not reraises:
                        yield f"{where}:{function}", child.lineno
                yield from visit(child, name)

        yield from visit(ast.parse(path.read_text(encoding="utf-8")), "<module>")


def test_no_catch_all_outside_the_allow_list() -> None:
    found = list(catch_alls())
    wrong = [f"src/rac/{site.split(':')[0]}:{line} ({site})" for site, line in found if site not in CATCH_ALL]
    assert not wrong, ("`except Exception` (or bare `except:`) catches rac's own bugs too; catch the concrete "
                       "types, or add the site to CATCH_ALL with the reason:\n" + "\n".join(wrong))
    stale = set(CATCH_ALL) - {site for site, _ in found}
    assert not stale, f"CATCH_ALL names sites without a catch-all: {sorted(stale)}"


def test_every_exception_class_derives_from_rac_error() -> None:
    import builtins

    bases: dict[str, set[str]] = {}
    where: dict[str, str] = {}
    for path in sorted(SRC.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ClassDef):
                names = {b.id if isinstance(b, ast.Name) else b.attr for b in node.bases
                         if isinstance(b, (ast.Name, ast.Attribute))}
                bases.setdefault(node.name, set()).update(names)
                where[node.name] = f"{path.relative_to(SRC.parents[1])}:{node.lineno}"

    def ancestors(name: str, seen: frozenset[str] = frozenset()) -> set[str]:
        found = set()
        for base in bases.get(name, set()) - seen:
            found |= {base} | ancestors(base, seen | {name})
        return found

    def builtin_exception(name: str) -> bool:
        value = getattr(builtins, name, None)
        return isinstance(value, type) and issubclass(value, BaseException)

    exceptions = [n for n in bases if any(builtin_exception(a) for a in ancestors(n))]
    assert "RacError" in exceptions
    wrong = [f"{where[n]}: {n}" for n in exceptions if n != "RacError" and "RacError" not in ancestors(n)]
    assert not wrong, "exception classes that do not derive from rac.core.diagnostics.RacError:\n" + "\n".join(wrong)
