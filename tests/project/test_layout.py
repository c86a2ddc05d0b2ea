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
- one sample's meaning written once: a state array's columns by name from :mod:`rac.model.sample`
  (no bare integer column), the int32 limits only from :mod:`rac.core.numbers`, ``collide()`` only
  from :func:`rac.model.sample.collides`, a guard walked by :class:`rac.ir.GuardFold`;
- no ``except Exception`` (nor bare ``except:``) outside :data:`CATCH_ALL`, each with its reason;
- every exception class of ``src/rac`` derives from ``RacError`` (``rac.core.diagnostics``);
- every import inside a function body says why it is there (a comment on its line or the line above).

docs/architecture.md shows the same layers.
"""

from __future__ import annotations

import ast
import io
import tokenize
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src" / "rac"

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
        " (the layers of tests/project/test_layout.py)")


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


#: The names under which src/rac holds state arrays (rows of :mod:`rac.model.sample`'s columns): the
#: value of a subscript, a variable or the last attribute (``graph.states``, ``layer.ego``).
STATE_ARRAYS = {"state", "states", "row", "rows", "ego", "frame", "before", "after", "moved", "chosen", "current",
                "frontier", "key", "place", "block", "start"}
#: The module that names the columns.
COLUMNS_MODULE = "rac.model.sample"
#: Packages whose arrays have layouts of their own: plots and renders read (x, y, head) paths in metres.
OWN_LAYOUTS = ("rac.output",)


def _literal_column(node: ast.expr) -> bool:
    """An integer literal (``4``, ``-1``), a slice of them (``:7``, ``5:7``, ``1:``) or a tuple of them."""
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        node = node.operand
    if isinstance(node, ast.Constant):
        return isinstance(node.value, int) and not isinstance(node.value, bool)
    if isinstance(node, ast.Slice):
        bounds = [b for b in (node.lower, node.upper) if b is not None]
        return node.step is None and bool(bounds) and all(_literal_column(b) for b in bounds)
    if isinstance(node, ast.Tuple):
        return bool(node.elts) and all(_literal_column(e) for e in node.elts)
    return False


def bare_state_columns() -> Iterator[str]:
    """``states[:, 4]``, ``rows[inverse, :7]``, ``runs.states[:, k, 5]``: a subscript of two or more indices
    of an array named as a state array (:data:`STATE_ARRAYS`) whose last index, the column, is an integer
    literal."""
    for module, path in MODULES.items():
        if module == COLUMNS_MODULE or module.startswith(OWN_LAYOUTS):
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not (isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Tuple)
                    and len(node.slice.elts) >= 2 and _literal_column(node.slice.elts[-1])
                    and not (isinstance(node.slice.elts[0], ast.Constant) and node.slice.elts[0].value is Ellipsis)):
                continue
            value = node.value
            name = value.id if isinstance(value, ast.Name) else value.attr if isinstance(value, ast.Attribute) else ""
            if name in STATE_ARRAYS:
                yield f"{path.relative_to(SRC.parents[1])}:{node.lineno}: {ast.unparse(node)}"


def test_state_columns_are_named() -> None:
    """A state array's columns are named once, in :mod:`rac.model.sample` (``Ego.HEAD``, ``ACTION``,
    ``GraphColumn.K``, ``PRODUCT_EGO``), never indexed by a bare integer elsewhere in src/rac.

    Scope: subscripts ``a[rows, column]`` and ``a[runs, k, column]`` of arrays named as :data:`STATE_ARRAYS`
    (a variable or an attribute: ``graph.states``), whose column is an integer literal, a slice or a tuple
    of them. Not checked: one-index rows (``row[0]``), ``a[..., c]`` (the obstacles' ``(n, O, 4)``
    states), arrays under other names (action ``pairs``, ``truth``, an observation ``out``) and
    :data:`OWN_LAYOUTS`: layouts of their own."""
    found = list(bare_state_columns())
    assert not found, "state columns by bare integers (name them from rac.model.sample):\n" + "\n".join(found)


#: The int32 limits as numbers: only :mod:`rac.core.numbers` writes them (``INT32_MAX``, ``INT32_MIN``,
#: ``INT32_LOW``, ``INT32_BOUND``).
INT32_LITERALS = {2**31 - 1, 2**31, 2**32}


def int32_literals() -> Iterator[str]:
    """A number literal equal to ``2**31 - 1``, ``2**31`` or ``2**32`` (an int or a float; a sign is a
    separate node, so ``-2147483648`` is found too), or the expressions ``2**31``, ``2**32``, ``1 << 31``,
    ``1 << 32`` and ``2**31 - 1`` written out."""
    for module, path in MODULES.items():
        if module == "rac.core.numbers":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            number = None
            if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) \
                    and not isinstance(node.value, bool):
                number = node.value
            elif isinstance(node, ast.BinOp) and isinstance(node.op, (ast.Pow, ast.LShift)) \
                    and isinstance(node.left, ast.Constant) and isinstance(node.right, ast.Constant):
                if (node.left.value, node.right.value) in {(2, 31), (2, 32)} and isinstance(node.op, ast.Pow) \
                        or (node.left.value, node.right.value) in {(1, 31), (1, 32)}:
                    number = 2**31
            if number is not None and number in INT32_LITERALS:
                yield f"{path.relative_to(SRC.parents[1])}:{node.lineno}: {ast.unparse(node)}"


def test_int32_limits_only_from_core_numbers() -> None:
    """The int32 limits are written once, in :mod:`rac.core.numbers`; every other module of src/rac imports
    them (text in docstrings and messages may still say the numbers)."""
    found = list(int32_literals())
    assert not found, "int32 limits written out (import them from rac.core.numbers):\n" + "\n".join(found)


def collide_comparisons() -> Iterator[str]:
    """A comparison with the collision distance (``td``, ``_td``, ``td_d``, ``self._td``, ``native.td_d``)."""
    for module, path in MODULES.items():
        if module == COLUMNS_MODULE:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Compare):
                for operand in (node.left, *node.comparators):
                    name = operand.id if isinstance(operand, ast.Name) else (
                        operand.attr if isinstance(operand, ast.Attribute) else "")
                    if name in {"td", "_td", "td_d"}:
                        yield f"{path.relative_to(SRC.parents[1])}:{node.lineno}: {ast.unparse(node)}"


def test_collide_is_defined_once() -> None:
    """``collide()`` is ``mindist() < TD`` in one place, :func:`rac.model.sample.collides`: the scalar and
    batch model, exploration, the product, the evaluator, simulation and episodes call it, none compares
    with the collision distance itself."""
    found = list(collide_comparisons())
    assert not found, "collide() computed outside rac.model.sample:\n" + "\n".join(found)


#: Modules that may test a guard node's connective themselves: rac.ir (the fold, and ir.inputs' table
#: with its own cache), check.linear (which builds guards: ``not not g`` simplified) and the Python
#: target's printer (the same simplification when printing).
GUARD_WALKERS = {"rac.ir", "rac.ir.inputs", "rac.check.linear", "rac.targets.python"}


def guard_connective_tests() -> Iterator[str]:
    """``isinstance(x, ir.BNot)``, ``isinstance(x, (ir.BAnd, ...))``: a walk over the connectives."""
    for module, path in MODULES.items():
        if module in GUARD_WALKERS:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "isinstance"
                    and len(node.args) == 2):
                names = {n.attr if isinstance(n, ast.Attribute) else n.id for n in ast.walk(node.args[1])
                         if isinstance(n, (ast.Attribute, ast.Name))}
                if names & {"BNot", "BAnd", "BOr"}:
                    yield f"{path.relative_to(SRC.parents[1])}:{node.lineno}: {ast.unparse(node)}"


def test_guards_are_walked_by_the_fold() -> None:
    """A guard's meaning is given as leaves and combinations to :class:`rac.ir.GuardFold` (the interpreter,
    the batch runtime, the product, the compositional transfer); only :data:`GUARD_WALKERS` test the
    connectives (the printers dispatch by node name, ``print_BAnd``, with their operator tables)."""
    found = list(guard_connective_tests())
    assert not found, "isinstance chains over guard connectives (use rac.ir.GuardFold):\n" + "\n".join(found)


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


def _type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def function_local_imports(tree: ast.AST) -> Iterator[ast.Import | ast.ImportFrom]:
    """The import statements inside a function body (at any depth below a ``def`` or ``lambda``),
    skipping ``if TYPE_CHECKING:`` blocks."""

    def visit(node: ast.AST, inside: bool) -> Iterator[ast.Import | ast.ImportFrom]:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _type_checking(child):
                continue
            if inside and isinstance(child, (ast.Import, ast.ImportFrom)):
                yield child
            yield from visit(child, inside or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)))

    yield from visit(tree, False)


def uncommented_local_imports() -> Iterator[str]:
    for path in sorted(SRC.rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        comments: dict[int, str] = {}  # line -> its comment (tokenize: a `#` inside a string is no comment)
        only_comment: set[int] = set()  # lines holding a comment and nothing else
        for token in tokenize.generate_tokens(io.StringIO(text).readline):
            if token.type == tokenize.COMMENT:
                comments[token.start[0]] = token.string
                if not token.line[:token.start[1]].strip():
                    only_comment.add(token.start[0])
        for node in function_local_imports(ast.parse(text)):
            said = [comments[n].lstrip("#").strip() for n in range(node.lineno, node.end_lineno + 1) if n in comments]
            if node.lineno - 1 in only_comment:
                said.append(comments[node.lineno - 1].lstrip("#").strip())
            if not any(said):
                yield f"{path.relative_to(SRC.parents[1])}:{node.lineno}: {ast.unparse(node)}"


def test_function_local_imports_say_why() -> None:
    """An import belongs at the top of its module; one inside a function body (at any depth, ``if
    TYPE_CHECKING:`` blocks exempt) stays only at a seam, with a one-line reason as a comment on one of
    its lines or on the line just above: a heavy third-party library the module's light users must not
    load (``# numpy: rac fmt and a syntax error never load it``), or an import cycle (``# cycle:
    rac.engine.product imports this module``). Scope: every module of src/rac; the comment's words are
    not checked, only that there are some."""
    found = list(uncommented_local_imports())
    assert not found, ("imports inside functions without a reason (move them to the top, or say why on "
                       "the line or the line above):\n" + "\n".join(found))


def test_test_modules_have_distinct_names() -> None:
    """pytest imports test files by their base name (the folders have no __init__.py): two files of one
    name in different folders stop the whole run at collection."""
    tests = SRC.parents[1] / "tests"
    seen: dict[str, list[str]] = {}
    for path in sorted(tests.rglob("test_*.py")):
        seen.setdefault(path.name, []).append(str(path.relative_to(tests)))
    assert not {name: paths for name, paths in seen.items() if len(paths) > 1}


def test_tests_import_no_private_names_of_rac() -> None:
    """The house rule holds for the tests too: what a test needs of rac is public (a ``_name`` may change
    without notice)."""
    tests = SRC.parents[1] / "tests"
    found = []
    for path in sorted(tests.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "rac":
                found += [f"{path.relative_to(tests)}:{node.lineno}: {node.module}.{alias.name}" for alias in node.names
                          if alias.name.startswith("_") and not alias.name.startswith("__")]
    assert not found, "\n".join(found)


#: What the repository's top level holds (the brief's layout, the CI script and the project's own files).
TOP_LEVEL = {".ci", ".gitignore", "README.md", "pyproject.toml", "benchmarks", "docs", "examples", "grammar", "src",
             "stdlib", "tests"}


def test_nothing_stray_at_the_top_level() -> None:
    """A file a test or a command left in the checkout and a commit took along (a generated ``b.py`` was
    committed once) is not part of the project: the tracked top level is the layout's."""
    import shutil  # only here: the rule reads git's index, not the working tree
    import subprocess  # only here: as above

    root = SRC.parents[1]
    git = shutil.which("git")
    if git is None or not (root / ".git").exists():
        pytest.skip("not a git checkout: the tracked files are not known")
    listed = subprocess.run([git, "ls-files"], cwd=root, capture_output=True, text=True, check=True).stdout
    tracked = {line.split("/", 1)[0] for line in listed.splitlines() if line}
    assert tracked <= TOP_LEVEL, sorted(tracked - TOP_LEVEL)
