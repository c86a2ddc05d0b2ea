"""The Python target: a standalone module (standard library only) that runs one automaton.

The generated class has the API of :class:`rac.runtime.interpreter.RewardAutomaton` (``reset``, ``step``,
``end``, ``location``, ``rewards``, ``objective``, ``samples``, ``time``, ``ended``, ``terminated``) and its exact
float semantics; it is straight-line code: one branch per location (found by halves past :data:`_CHAIN`),
guards inlined, rewards in locals while a sample is processed.

Example::

    from rac.compiler import compile_file
    from rac.targets.python import generate_python

    automaton = compile_file("stdlib/driving.ra").raise_for_errors()
    Path("driving_ra.py").write_text(generate_python(automaton, source_name="stdlib/driving.ra"))
    # elsewhere, without rac installed:  from driving_ra import Driving; ra = Driving()

Exactness of the printed arithmetic (every rewrite below is bit-for-bit the runtime's
``((c0 + c1*v1) + c2*v2) + ...``): ``1.0 * v`` is ``v``; ``a + (-c) * v`` is ``a - c * v``; the
first addition is commutative, so ``c0 + t1`` may print as ``t1 + c0``. No constant is ``-0.0``
(:func:`rac.runtime.semantics.to_float` refuses underflow), so no reward is ever ``-0.0``; hence adding a
zero rate is skipped, and ``0.0 + c * r`` prints as ``c * r`` for a reward ``r`` when ``c >= 1``
(the product cannot be ``-0.0``). Inputs may be ``-0.0``, so that shortcut never applies to them.
"""

from __future__ import annotations

import keyword
import re
import sys
import textwrap
from collections.abc import Iterable, Mapping
from fractions import Fraction
from functools import lru_cache
from importlib import resources
from pathlib import PurePath

import jinja2

from rac import ir
from rac.core.numbers import exact_decimal, exact_text
from rac.core.printing import COMPARISONS, Associativity, Level, Operator, OperatorTable, Printed, number, signed_sum
from rac.ir.text import GuardPrinter, format_guard
from rac.runtime.semantics import (
    NARROW_FLOATS,
    FloatAtoms,
    FloatLinear,
    assume_checks,
    check_automaton,
    float_atoms,
    float_linear,
    input_specs,
    to_float,
)

__all__ = ["PYTHON", "RESERVED_NAMES", "PythonGuards", "generate_python", "print_expr", "python_class_name"]

_TEMPLATE = "python_module.py.j2"
_LINE = 110
#: The most locations a step tells apart by a chain of ``loc == k`` tests (:func:`_dispatch`).
_CHAIN = 8
#: The most edges of a location one ``if``/``elif`` chain tests (:func:`_first_enabled`).
_EDGES = 256
#: The module-level names the generated module binds or reads: its imports and helpers, the builtins
#: its code and annotations use, and the dunders Python and tools look up on a module. The automaton's
#: class is the one module-level name a `.ra` file chooses (the grammar allows any ASCII identifier,
#: so no helper name is out of its reach); one of these gets a ``_`` appended (``float_``), since a
#: class named ``float`` would shadow the ``float`` the helpers call. Dunders lose their underscores.
#: tests/targets/test_python_names.py checks that this covers every global the generated code uses.
RESERVED_NAMES = frozenset({
    # imports and helpers of the template
    "annotations", "math", "numbers", "Mapping",
    "_key_error", "_mapping", "_boolean", "_duration", "_number", "_range_error", "_assume_error", "_array_hint",
    "_clip", "_one_value",
    # builtins called, raised or named in annotations (typing.get_type_hints evaluates those)
    "bool", "float", "int", "str", "bytes", "object", "dict", "tuple", "len", "isinstance", "type", "repr", "sorted",
    "getattr", "min", "max", "callable", "any",
    "property", "super", "ValueError", "KeyError", "RuntimeError", "OverflowError", "TypeError", "AttributeError",
    # (every dunder, `__all__` among them, is renamed too: see python_class_name)
})


# ---------------------------------------------------------------- the printer
#: Python's operators for guards: ``not`` binds looser than comparisons, and ``and``/``or`` are
#: associative (every guard value is a bool), so their chains need no parentheses.
PYTHON = OperatorTable(
    binary={
        "||": Operator(" or ", Level.OR, Associativity.ASSOCIATIVE),
        "&&": Operator(" and ", Level.AND, Associativity.ASSOCIATIVE),
        **COMPARISONS,
    },
    prefix={"!": Operator("not ", Level.NOT, Associativity.RIGHT)},
    true="True",
    false="False",
)


def _num(value: float) -> str:
    text = repr(float(value))
    if text in ("inf", "-inf", "nan"):
        raise ValueError(f"{value} cannot be printed as a Python literal")
    return text


class PythonGuards(GuardPrinter):
    """Prints guards as Python (:data:`PYTHON`); a numeric input is compared with a float as ``atoms`` (the
    automaton's :func:`rac.runtime.semantics.float_atoms`) says, else with ``float(threshold)``."""

    table = PYTHON

    def __init__(self, names: Mapping[str, str], atoms: FloatAtoms | None = None) -> None:
        super().__init__(names)
        self.atoms = atoms

    def print_BAtom(self, guard: ir.BAtom) -> Printed:
        compared = (guard.op, to_float(guard.threshold, "threshold")) if self.atoms is None else self.atoms(guard)
        if isinstance(compared, bool):
            return self.literal(compared)
        return self.infix(compared[0], Printed(self.names[guard.input], Level.ATOM), number(_num(compared[1])))

    def print_BNot(self, guard: ir.BNot) -> Printed:
        if isinstance(guard.operand, ir.BNot):  # every guard value is a bool: not not g == g
            return self.print(guard.operand.operand)
        return super().print_BNot(guard)


def print_expr(node: FloatLinear | ir.Guard, names: Mapping[str, str],
               never_negative_zero: Iterable[str] = (), *, precedence: int = Level.TOP,
               atoms: FloatAtoms | None = None) -> str:
    """Print a linear form (in float form, see :func:`rac.runtime.semantics.float_linear`) or a guard as Python.

    ``names`` maps each variable to the Python expression that holds it; ``never_negative_zero``
    lists the variables that can never hold ``-0.0`` (rewards). Guards print with ``not``/``and``/
    ``or``; ``precedence`` (a :class:`rac.core.printing.Level`: 0 none, 1 or, 2 and, 3 not) is the
    binding strength the context needs; ``atoms`` how numeric inputs compare (:class:`PythonGuards`).
    """
    if isinstance(node, tuple):
        return _linear(node, names, frozenset(never_negative_zero))
    printer = PythonGuards(names, atoms)
    return printer.operand(printer.print(node), precedence)


def _linear(form: FloatLinear, names: Mapping[str, str], safe: frozenset[str]) -> str:
    const, terms = form
    if not terms:
        return _num(const)

    def term(coef: float, name: str) -> tuple[bool, str]:
        magnitude = abs(coef)
        return coef < 0, names[name] if magnitude == 1.0 else f"{_num(magnitude)} * {names[name]}"

    (coef, name), rest = terms[0], terms[1:]
    first: list[tuple[bool, str]]
    if const == 0.0:
        if coef >= 1.0 and name in safe:
            first = [term(coef, name)]  # 0.0 + t == t: t is never -0.0
        else:
            first = [(False, "0.0"), term(coef, name)]
    elif coef < 0:
        first = [(False, _num(const)), term(coef, name)]
    else:
        first = [term(coef, name), (const < 0, _num(abs(const)))]
    return signed_sum([*first, *(term(coef, name) for coef, name in rest)])


#: The standard library's modules the generated module imports (tests/targets compare it with the text).
MODULE_IMPORTS = ("__future__", "math", "numbers", "collections", "struct")


def module_name_note(output: PurePath) -> str | None:
    """Why ``import NAME`` will not give the module written to ``output`` (None when it will): a file
    name that is no Python identifier, or the name of a standard-library module, which the file shadows
    for code run in its folder (``numbers.py``: the generated module, importing ``numbers``, imports itself,
    and so do ``fractions`` and ``decimal``)."""
    stem = output.stem
    if output.suffix != ".py" or not stem.isidentifier() or keyword.iskeyword(stem):
        return (f"`{output.name}` cannot be imported by name (`import` needs a `.py` file named by a Python "
                "identifier): name it e.g. `reward.py`, or load it with importlib")
    if stem in sys.stdlib_module_names:
        itself = ", the generated module included" if stem in MODULE_IMPORTS else ""
        return (f"`{output.name}` has the name of the standard library's `{stem}`: run from its folder, "
                f"`import {stem}` gives this file instead, in your code and in every library that imports it"
                f"{itself}; choose another name")
    return None


# ---------------------------------------------------------------- generation
def python_class_name(name: str) -> str:
    """The generated class's name for an automaton named ``name``: ``name`` itself, unless it is a
    keyword or one of :data:`RESERVED_NAMES` (then ``_`` is appended: ``float_``) or a dunder (then
    its underscores go: ``__init__`` -> ``init``)."""
    if not name.isidentifier():
        name = re.sub(r"\W", "_", name)
        if not name or name[0].isdigit():
            name = "_" + name
    if name.startswith("__") and name.endswith("__"):
        # dunders belong to Python: `module.__class__` is the module's type whatever the module binds,
        # and appending `_` would keep the name a dunder
        name = name.strip("_") or "Automaton"
    while keyword.iskeyword(name) or name in RESERVED_NAMES:
        name += "_"
    return name


def _py(value: object) -> str:
    """``repr``, with double-quoted strings (the house style) when they hold no quote; a string in ASCII
    (``ascii``: ``\\xfc`` for ``ü``, the same string once read), so that the module is ASCII (:func:`_ascii`)."""
    if not isinstance(value, str):
        return repr(value)
    text = ascii(value)
    if text.startswith("'") and "'" not in value and '"' not in value:
        return f'"{text[1:-1]}"'
    return text


def _ascii(text: str) -> str:
    """``text`` with every non-ASCII character escaped (``\\xfc``), for the module's comments. A module of
    ASCII alone reads the same in every encoding: written through standard output in Windows' cp1252
    (``rac compile ... > m.py``), a file name's ``ü`` was a byte Python refuses in a source file (it
    reads UTF-8), and a ``限`` one that cp1252 cannot encode."""
    return text.encode("ascii", "backslashreplace").decode("ascii")


def _pytuple(items: Iterable[object], column: int = 0, *, printed: bool = False) -> str:
    """A tuple literal (of already ``printed`` items, or of values); wrapped one item per line when it
    would not fit after ``column``."""
    parts = [str(item) if printed else _py(item) for item in items]
    if not parts:
        return "()"
    if len(parts) == 1:
        return f"({parts[0]},)"
    flat = "(" + ", ".join(parts) + ")"
    if column + len(flat) <= _LINE:
        return flat
    return "(\n" + "".join(f"        {part},\n" for part in parts) + "    )"


def _pydict(items: list[tuple[str, str]], column: int) -> str:
    """A dict display of already-printed keys and values; one item per line when too long."""
    flat = "{" + ", ".join(f"{k}: {v}" for k, v in items) + "}"
    if column + len(flat) <= _LINE:
        return flat
    return "{\n" + "".join(f"            {k}: {v},\n" for k, v in items) + "        }"


def _call(head: str, arguments: list[str], column: int) -> list[str]:
    """``head(arguments)`` on one line when it fits after ``column``, else one argument per line."""
    flat = f"{head}({', '.join(arguments)})"
    if column + len(flat) <= _LINE:
        return [flat]
    indent = head[: len(head) - len(head.lstrip())]
    return [f"{head}(", *(f"{indent}    {argument}," for argument in arguments), f"{indent})"]


def _ra_linear(linear: ir.Linear) -> str:
    """A linear form in `.ra` syntax, for documentation."""
    parts = [(coef < 0, name if abs(coef) == 1 else f"{_decimal(abs(coef))}*{name}") for name, coef in linear.terms]
    if linear.const or not parts:
        parts.append((linear.const < 0, _decimal(abs(linear.const))))
    return signed_sum(parts)


def _decimal(value: Fraction) -> str:
    """A number of the docstring as a `.ra` file writes it: ``0.1``, not ``1/10`` (``1 / 3``: no exact decimal)."""
    return exact_decimal(Fraction(value)) or exact_text(Fraction(value))


class _Generator:
    def __init__(self, automaton: ir.Automaton) -> None:
        self.a = automaton
        self.specs = input_specs(automaton)
        self.inputs = {s.name: f"i_{s.name}" for s in self.specs}
        self.rewards = {r: f"r_{r}" for r in automaton.rewards}
        self.slots = {r: f"_r_{r}" for r in automaton.rewards}
        self.names = {**self.inputs, **self.rewards}
        self.rates = [[float_linear(rate.scaled(automaton.period), "rate") for rate in loc.rates]
                      for loc in automaton.locations]
        held = {name for row in self.rates for form in row for _, name in form[1]}
        self.held = [s.name for s in self.specs if s.name in held]
        self.held_names = {name: f"h_{name}" for name in self.held}
        self.atoms = float_atoms(automaton)

    def expr(self, node: FloatLinear | ir.Guard, names: Mapping[str, str] | None = None) -> str:
        return print_expr(node, names or self.names, self.rewards.keys(), atoms=self.atoms)

    def updates(self, updates: Iterable[ir.Assignment]) -> list[str]:
        return [f"{self.rewards[u.reward]} = {self.expr(float_linear(u.value, 'update'))}" for u in updates]

    def read(self, body: str) -> list[str]:
        """Read and validate every input; an unused boolean is validated, its value not converted."""
        check: list[str] = []
        for clause in assume_checks(self.a):  # in source order: the first violated one is named
            check.append(f"if {self.expr(ir.BNot(clause.guard))}:")
            check += _call("    raise _assume_error", [_py(clause.label), *(
                f"({_py(name)}, {'int(' + self.inputs[name] + ')' if kind == 'int' else self.inputs[name]})"
                for name, kind in clause.reads)], 12)
        body = "\n".join([body, *check])
        # The common values (a dict, True/False, a float) are taken as they are, by identity tests;
        # only others go through the helpers, whose abstract-class checks (Mapping, numbers.Real)
        # cost more than the rest of a sample (benchmarks/run.py's step rows).
        lines = ["if type(inputs) is not dict:", "    _mapping(inputs, self.inputs)",
                 "try:", f"    if len(inputs) != {len(self.specs)}:", "        raise KeyError"]
        for spec in self.specs:
            var = self.inputs[spec.name]
            name = _py(spec.name)
            if spec.is_bool:
                used = re.search(rf"\b{var}\b", body) is not None
                lines += [f"    {var} = inputs[{name}]", f"    if {var} is not True and {var} is not False:",
                          f"        {var + ' = ' if used else ''}_boolean({name}, {var})"]
                continue
            low, high = _num_or_inf(spec.low), _num_or_inf(spec.high)
            lines += [f"    {var} = inputs[{name}]", f"    if type({var}) is not float:",
                      f"        {var} = _number({name}, {var}, {low}, {high})"]
            if spec.bounded:
                bad = [f"not {low} <= {var} <= {high}"]
            else:
                bad = [f"not math.isfinite({var})"]
                if spec.low != float("-inf"):
                    bad.append(f"{var} < {low}")
                if spec.high != float("inf"):
                    bad.append(f"{var} > {high}")
            if spec.kind == "int":
                bad.append(f"not {var}.is_integer()")
            lines += [f"    if {' or '.join(bad)}:",
                      f"        raise _range_error({_py(spec.name)}, {var}, {low}, {high})"]
        return lines + ["except KeyError:", "    raise _key_error(inputs, self.inputs) from None", *check]

    def finish(self, body: list[str], tail: list[str]) -> list[str]:
        """Wrap ``body`` with input reads, reward loads and stores, then ``tail``."""
        text = "\n".join(body + tail)
        loads = [f"{var} = self.{self.slots[r]}" for r, var in self.rewards.items()
                 if re.search(rf"\b{var}\b", text)]
        stores = [f"self.{self.slots[r]} = {var}" for r, var in self.rewards.items()
                  if re.search(rf"^\s*{var} = ", "\n".join(body), re.MULTILINE)]
        # the counts of `clip=True` are kept once the inputs are read: a call that raises changes nothing
        kept = ["if counts is not None:", "    self.clipped = counts"]
        return self.read(text) + kept + loads + body + stores + tail

    def step(self) -> list[str]:
        a = self.a
        body: list[str] = []
        if self.held:
            body += ["if self._samples:"]
            body += [f"    {h} = self._h_{name}" for name, h in self.held_names.items()]
            body += ["else:"]
            body += [f"    {h} = {self.inputs[name]}" for name, h in self.held_names.items()]
        held_names = {**self.rewards, **self.held_names}
        branches: list[tuple[int, list[str]]] = []
        moves = False
        for index in range(len(a.locations)):
            lines = []
            for reward, form in zip(a.rewards, self.rates[index]):
                var = self.rewards[reward]
                const, terms = form
                if not terms:
                    if const != 0.0:  # r + 0.0 == r: rewards are never -0.0
                        lines.append(f"{var} = {var} {'-' if const < 0 else '+'} {_num(abs(const))}")
                else:
                    lines.append(f"{var} = {var} + ({self.expr(form, held_names)})")
            cases = []
            for edge in a.edges[index]:
                inner = self.updates(edge.updates)
                if edge.target != index:
                    inner.append(f"loc = {edge.target}")
                    moves = True
                cases.append((self.expr(edge.guard), inner))
            lines += _first_enabled(cases)
            if lines:
                branches.append((index, lines))
        if branches:
            body.append("loc = self._loc")
            body += _dispatch(branches)
            if moves:
                body.append("self._loc = loc")
        ends = a.ending
        if ends is not None:  # `episode ends when`: the end clauses with this sample's inputs, and the run ends
            body.append(f"if {self.expr(ends)}:")
            body += ["    " + line for line in self.end_clauses() + ["self._ended = True", "self._terminated = True"]]
        tail = [f"self._h_{name} = {self.inputs[name]}" for name in self.held]
        tail += ["self._samples += 1"]
        return self.finish(body, tail + self.objective())

    def end(self) -> list[str]:
        return self.finish(self.end_clauses(), ["self._ended = True"] + self.objective())

    def end_clauses(self) -> list[str]:
        """Every ``at end`` clause whose guard holds, in order (the locals of rewards and inputs)."""
        body: list[str] = []
        for clause in self.a.end_clauses:
            inner = self.updates(clause.updates)
            if not inner:
                continue
            if clause.guard == ir.TRUE:
                body += inner
            else:
                body.append(f"if {self.expr(clause.guard)}:")
                body += ["    " + line for line in inner]
        return body

    def objective(self) -> list[str]:
        return [f"objective = {self.expr(float_linear(self.a.objective, 'objective'))}",
                "reward = objective - self._objective",
                "self._objective = objective",
                "return reward"]

    def docstring(self, class_name: str) -> str:
        a = self.a
        lines = [f"Reward automaton ``{a.name}``.", "", "Inputs (one value each per sample):"]
        for item in a.inputs:
            bounds = ""
            if item.low is not None or item.high is not None:
                low = "-inf" if item.low is None else _decimal(item.low)
                high = "inf" if item.high is None else _decimal(item.high)
                bounds = f" in [{low}, {high}]"
            lines.append(f"    {item.name}: {item.kind}{bounds}")
        facts = []
        if a.parameters:  # the module runs one value of each: the one `rac check` checked
            facts.append("Parameters, as checked: " + ", ".join(
                f"{q.name} = {_decimal(q.value)} (declared in [{_decimal(q.low)}, {_decimal(q.high)}])"
                for q in a.parameters))
        if a.assumptions:  # as written in the .ra file, as the errors quote them
            facts.append("Assumed of every input valuation: " + "; ".join(q.text for q in a.assumptions))
        ends = a.ending
        if ends is not None:
            facts.append(f"The run ends after a sample whose inputs satisfy: {format_guard(ends)}")
        facts += [
            f"Rewards: {', '.join(a.rewards)} (each starts at 0)",
            f"Objective: {_ra_linear(a.objective)}",
            "Locations: " + ", ".join(loc.name + (" (initial)" if i == a.initial else "")
                                      for i, loc in enumerate(a.locations)),
            f"Sample period: {_decimal(a.period)} s; horizon: {_decimal(a.horizon)} s ({a.steps} samples).",
        ]
        for fact in facts:  # the docstring is indented by 4 in the class
            lines += textwrap.wrap(fact, _LINE - 4, subsequent_indent="    ", break_on_hyphens=False)
        lines += [
            "",
            "``step(inputs)`` processes one sample and returns the objective's increase, so the",
            "rewards of a run sum to the objective's final value; ``end(inputs)`` applies the",
            "``at end`` clauses once; ``reset()`` starts a new run.",
        ]
        if ends is not None:
            lines += [
                "When a sample ends the run, ``step`` applies the ``at end`` clauses itself,",
                "``terminated`` is true, and ``end`` returns 0.0.",
            ]
        return "\n".join(lines)


def _dispatch(branches: list[tuple[int, list[str]]]) -> list[str]:
    """The ``lines`` of each location (``(index, lines)``, by index) run when ``loc`` is its index: an
    ``if``/``elif`` chain of at most :data:`_CHAIN` tests, else the two halves under ``if loc < k``/``else``.

    Python's syntax tree nests every ``elif`` in the one before, and a chain of about 2,500 (an automaton
    of that many locations, which rac checks in seconds) exceeded the compiler's recursion limit: the module
    could not be imported (RecursionError during compilation). Split, it nests log2(n) deep, and a step
    makes that many tests rather than up to n."""
    if len(branches) <= _CHAIN:
        chain: list[str] = []
        for k, (index, lines) in enumerate(branches):
            chain.append(f"{'if' if k == 0 else 'elif'} loc == {index}:")
            chain += ["    " + line for line in lines]
        return chain
    half = len(branches) // 2
    return [f"if loc < {branches[half][0]}:", *("    " + line for line in _dispatch(branches[:half])),
            "else:", *("    " + line for line in _dispatch(branches[half:]))]


def _first_enabled(cases: list[tuple[str, list[str]]]) -> list[str]:
    """The lines of the first of ``cases`` (a condition, its lines) whose condition holds, in order: an
    ``if``/``elif`` chain; past :data:`_EDGES` cases, chains of that many, each tried only while no case
    before it held (``fired``). Python nests every ``elif`` in the one before, and a location of about 2,500
    edges (a fan-out on an ``int`` input) made a module whose import raised RecursionError."""

    def chain(part: list[tuple[str, list[str]]]) -> list[str]:
        lines: list[str] = []
        for k, (condition, inner) in enumerate(part):
            lines.append(f"{'if' if k == 0 else 'elif'} {condition}:")
            lines += ["    " + line for line in inner or ["pass"]]
        return lines

    if len(cases) <= _EDGES:
        return chain(cases)
    out = ["fired = True"]
    for start in range(0, len(cases), _EDGES):
        tried = [*chain(cases[start:start + _EDGES]), "else:", "    fired = False"]
        out += tried if start == 0 else ["if not fired:", "    fired = True", *("    " + line for line in tried)]
    return out


def _num_or_inf(value: float) -> str:
    if value == float("inf"):
        return "math.inf"
    if value == float("-inf"):
        return "-math.inf"
    return _num(value)


def _split_top(expr: str, op: str) -> list[str]:
    """``expr`` cut before each top-level (unparenthesised) ``op``; pieces after the first keep it."""
    pieces, depth, start, i = [], 0, 0, 0
    while i < len(expr):
        if expr[i] == "(":
            depth += 1
        elif expr[i] == ")":
            depth -= 1
        elif depth == 0 and expr.startswith(op, i):
            pieces.append(expr[start:i])
            start = i + 1
            i += len(op)
            continue
        i += 1
    return [*pieces, expr[start:]]


def _enclosed(text: str) -> bool:
    """``text`` starts with ``(`` whose matching ``)`` is its last character."""
    depth = 0
    for i, ch in enumerate(text):
        if ch == "(":
            depth += 1
        elif ch == ")":
            depth -= 1
            if depth == 0:
                return i == len(text) - 1
    return False


def _break(expr: str, indent: str) -> list[str]:
    """``expr`` as lines starting with ``indent``, cut before top-level operators when too long.

    Only line breaks inside parentheses are added, so the evaluation order does not change.
    """
    if len(indent) + len(expr) <= _LINE:
        return [indent + expr]
    prefix = re.match(r"(?:(?:and|or|\+|-) )?(?:not )?", expr).group(0)  # type: ignore[union-attr]
    rest = expr[len(prefix):]
    if rest.startswith("(") and _enclosed(rest):
        return [indent + prefix + "(", *_break(rest[1:-1], indent + "    "), indent + ")"]
    for op in (" or ", " and ", " + ", " - "):
        pieces = _split_top(expr, op)
        if len(pieces) > 1:
            break
    else:
        return [indent + expr]
    lines: list[str] = []
    current = ""
    for piece in pieces:
        if current and len(current) + 1 + len(piece) <= _LINE:
            current += " " + piece
            continue
        if current:
            lines.append(current)
        broken = _break(piece, indent)
        lines += broken[:-1]
        current = broken[-1]
    return [*lines, current]


def _wrap(line: str) -> list[str]:
    """Break an over-long ``if``/``elif``/assignment line inside parentheses."""
    indent = line[: len(line) - len(line.lstrip())]
    match = re.fullmatch(r"(\s*(?:if|elif) )(.*)(:)|(\s*[A-Za-z_]\w* = )(.*)()", line)
    if len(line) <= _LINE or not match:
        return [line]
    head, expr, tail = (match.group(1, 2, 3) if match.group(1) else match.group(4, 5, 6))
    return [head + "(", *_break(expr, indent + "    "), indent + ")" + tail]


def _indent(lines: list[str], width: int = 8) -> str:
    out = []
    for line in lines:
        out += _wrap(" " * width + line) if line else [""]
    return "\n".join(out)


@lru_cache(maxsize=1)
def _template() -> jinja2.Template:
    text = (resources.files("rac.targets") / "templates" / _TEMPLATE).read_text(encoding="utf-8")
    env = jinja2.Environment(trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True,
                             undefined=jinja2.StrictUndefined, autoescape=False)
    env.filters["py"] = _py
    env.filters["pytuple"] = _pytuple
    return env.from_string(text)


def generate_python(automaton: ir.Automaton, *, source_name: str = "") -> str:
    """The source of a standalone Python module running ``automaton`` (deterministic text).

    The module defines one class named after the automaton, with the API and the exact float
    semantics of :class:`rac.runtime.interpreter.RewardAutomaton`; it imports only the standard library.
    """
    check_automaton(automaton)
    gen = _Generator(automaton)
    class_name = python_class_name(automaton.name)
    zeros = {r: 0.0 for r in automaton.rewards}
    const, terms = float_linear(automaton.objective, "objective")
    initial_objective = const
    for coef, name in terms:
        initial_objective = initial_objective + coef * zeros[name]
    period = Fraction(automaton.period)
    if period.denominator == 1:
        time_expr = f"float(self._samples * {period.numerator})"
    elif period.numerator == 1:
        time_expr = f"self._samples / {period.denominator}"
    else:
        time_expr = f"self._samples * {period.numerator} / {period.denominator}"
    reward_slots = [gen.slots[r] for r in automaton.rewards]
    held_slots = [f"_h_{name}" for name in gen.held]
    source = _ascii(" ".join(source_name.split())) or "<unnamed>"
    return _template().render(
        source_name=source,
        name=automaton.name,
        class_name=class_name,
        docstring=gen.docstring(class_name),
        slots=sorted(("_loc", *reward_slots, *held_slots, "_samples", "_ended", "_terminated", "_objective",
                      "clipped")),
        inputs=tuple(i.name for i in automaton.inputs),
        reward_names=tuple(automaton.rewards),
        locations=automaton.location_names,
        period=to_float(period, "period"),
        horizon=float(automaton.horizon),
        steps=automaton.steps,
        narrow_floats=NARROW_FLOATS,
        initial=automaton.initial,
        reward_slots=reward_slots,
        held_slots=held_slots,
        initial_objective=initial_objective,
        step_body=_indent(gen.step()),
        end_body=_indent(gen.end()),
        rewards_dict=_pydict([(_py(r), f"self.{gen.slots[r]}") for r in automaton.rewards], 15),
        time_expr=time_expr,
        bounds=_pytuple([f"({_py(s.name)}, {_num_or_inf(s.low)}, {_num_or_inf(s.high)})"
                         for s in gen.specs if not s.is_bool], 52, printed=True),
    )
