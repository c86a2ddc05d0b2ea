"""The house rules of src/rac, read from the code's own imports (Python's ``ast``).

Each rule fails with the offending file and line:

- no import cycle between modules, counting imports inside functions;
- no name starting with ``_`` imported from another module (what is shared is public);
- the layers (:data:`LAYERS`): each package imports only the packages below it, e.g. ``lang``
  nothing of rac but ``core`` and itself, ``check`` only ``core``, ``lang`` and ``ir``, the targets
  only ``core``, ``ir``, ``model`` and ``runtime``, the engine never ``targets``, ``check`` or
  ``lang``; only ``cli`` (and ``python -m rac``) imports ``cli``;
- at most a handful of modules directly under ``src/rac``;
- one owner of the scenario: no module but :data:`SCENARIO_OWNER` imports or calls commonroad-io's
  loader ``load_scenario`` (every other one asks the owner, so all read the same planning problem);
- no ``getattr``/``hasattr`` probing a checked file for ``automaton``, ``model_data``, ``scenario`` or
  ``sources``: what holds them is typed (:class:`rac.model.program.CheckedProgram`,
  :class:`rac.compiler.CompileResult`), and isinstance picks among them.

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


#: The one module that loads a `model` block's scenario (docs/architecture.md, "One owner per fact"),
#: and the module defining the loader it calls.
SCENARIO_OWNER = "rac.model.checks"
LOADER_MODULE = "rac.model.commonroad"
#: The attributes of a checked file that are read by type, never probed for.
PROGRAM_ATTRIBUTES = {"automaton", "model_data", "scenario", "sources"}


def test_one_owner_loads_the_scenario() -> None:
    found = []
    for module, path in MODULES.items():
        if module in (SCENARIO_OWNER, LOADER_MODULE):
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and any(a.name == "load_scenario" for a in node.names):
                found.append(f"{path.relative_to(SRC.parents[1])}:{node.lineno}: {module} imports load_scenario")
            elif isinstance(node, ast.Call):
                func = node.func
                name = func.id if isinstance(func, ast.Name) else func.attr if isinstance(func, ast.Attribute) else ""
                if name == "load_scenario":
                    found.append(f"{path.relative_to(SRC.parents[1])}:{node.lineno}: {module} calls load_scenario")
    assert not found, (f"only {SCENARIO_OWNER} loads scenarios (ask it: rac.model.checks.load, "
                       "rac.model.program.CheckedProgram.of):\n" + "\n".join(found))


def test_no_probing_for_a_checked_files_parts() -> None:
    found = []
    for module, path in MODULES.items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
                    and node.func.id in ("getattr", "hasattr") and len(node.args) >= 2
                    and isinstance(node.args[1], ast.Constant)
                    and node.args[1].value in PROGRAM_ATTRIBUTES):
                found.append(f"{path.relative_to(SRC.parents[1])}:{node.lineno}: {module} probes "
                             f"{node.func.id}(..., {node.args[1].value!r})")
    assert not found, ("a checked file's parts are typed: accept CompileResult | CheckedProgram | ir.Automaton "
                       "and use isinstance:\n" + "\n".join(found))
