"""Checked expressions compiled once into one Python function over frames (issue 23).

:class:`rac.engine.evaluate.Evaluator` walks an expression's tree at every call: per node an
``isinstance`` chain, and per linear comparison the exact form's rationals worked out afresh.
:func:`compile_expressions` does that work once: it writes the expressions as the source of one
Python function of a :class:`~rac.engine.evaluate.Frame` — straight-line numpy calls, each shared
subexpression computed once, every constant, column index and exact comparison's integer
coefficients already in place — and compiles it with :func:`compile`. A sample then costs the numpy
operations alone.

The generated code makes *the same numpy calls on the same operands* as the evaluator, so its
values are bit for bit the evaluator's (tests/engine/test_compiled.py compares both on random expressions
and frames). The evaluator stays the reference: what depends on what a frame holds (a comparison
over inputs, rewards or the location index, decided exactly only when the frame holds their
integers), a name the frame may lack (its error is the evaluator's) and a function the engine
cannot evaluate go to :meth:`Evaluator.value <rac.engine.evaluate.Evaluator.value>` for that node,
with no change in behaviour. Model functions (``mindist()``, ``offroad()`` ...) are read through
:meth:`Evaluator.function <rac.engine.evaluate.Evaluator.function>`: once per frame, shared with
whatever else reads the frame (labels, the ``allow when`` rule, other expressions).

Example::

    compiled = compile_expressions(evaluator, [binding.expr for binding in spec.bindings])
    values = compiled(frame)              # one (n,) array per expression, as evaluator.evaluate gives
    print(compiled.source)                # the generated function
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from fractions import Fraction
from typing import Any

import numpy as np

from rac.core.numbers import INT32_BOUND
from rac.engine.evaluate import Evaluator, Frame, c_round, int_sum
from rac.ir import expr as ie
from rac.ir.vocabulary import Holding

__all__ = ["CompiledExpressions", "compile_expressions"]

#: The names the compiled code calls besides its constants (folding a constant calls the same).
_NAMES: dict[str, Any] = {"np": np, "int_sum": int_sum, "c_round": c_round}
_SAFE_INT64 = 2**62  # as int_sum: below it, no partial sum of an exact form overflows int64
_MATH_1 = {"abs": "np.abs", "fabs": "np.abs", "sqrt": "np.sqrt", "floor": "np.floor", "ceil": "np.ceil",
           "trunc": "np.trunc"}
_COMPARE = {"<": "np.less", "<=": "np.less_equal", ">": "np.greater", ">=": "np.greater_equal", "==": "np.equal",
            "!=": "np.not_equal"}
_ARITHMETIC = {"+": "np.add", "-": "np.subtract", "*": "np.multiply", "/": "np.divide"}


class CompiledExpressions:
    """``expressions`` of one evaluator compiled into one function: ``compiled(frame)`` is the list of
    their values, each what ``evaluator.evaluate(expr, frame)`` gives (a ``(n,)`` bool or float64
    array; :meth:`booleans` as ``evaluate_bool``). :attr:`source` is the generated code."""

    def __init__(self, evaluator: Evaluator, expressions: Sequence[ie.Expr]) -> None:
        self.evaluator = evaluator
        self.expressions = list(expressions)
        writer = _Writer(evaluator)
        results = [writer.node(expr, 0) for expr in self.expressions]
        self.source = writer.function(results)
        namespace: dict[str, Any] = {**_NAMES, **writer.constants}
        exec(compile(self.source, "<rac compiled expressions>", "exec"), namespace)  # noqa: S102
        self._function: Callable[[Frame, Evaluator], list[Any]] = namespace["compiled"]

    def __reduce__(self) -> tuple[Any, ...]:
        # the generated function lives in no module: a pickle (a process pool's, multiprocessing's)
        # carries what it was made from and compiles it again
        return (CompiledExpressions, (self.evaluator, self.expressions))

    def __call__(self, frame: Frame) -> list[np.ndarray]:
        n = frame.n
        return [np.broadcast_to(value, (n,)) if np.ndim(value) == 0 else value
                for value in self._function(frame, self.evaluator)]

    def booleans(self, frame: Frame) -> list[np.ndarray]:
        """:meth:`__call__` with numbers compared with 0, as ``Evaluator.evaluate_bool``."""
        return [value if value.dtype == bool else value != 0 for value in self(frame)]


def compile_expressions(evaluator: Evaluator, expressions: Sequence[ie.Expr]) -> CompiledExpressions:
    """``expressions`` (checked, of ``evaluator``'s automaton) compiled into one function of a frame."""
    return CompiledExpressions(evaluator, expressions)


class _Writer:
    """Writes the statements of the generated function, one temporary per distinct (node, frame)."""

    def __init__(self, evaluator: Evaluator) -> None:
        self.evaluator = evaluator
        self.lines: list[str] = []
        self.constants: dict[str, Any] = {}
        self.names: dict[tuple[tuple, int], str] = {}  # (node's _key, prev depth) -> its temporary
        self.depth = 0  # the deepest prev() frame used

    # ------------------------------------------------------------ plumbing
    def constant(self, value: Any) -> str:
        name = f"K{len(self.constants)}"
        self.constants[name] = value
        return name

    def emit(self, text: str, *operands: str) -> str:
        """A temporary for ``text``; when its ``operands`` are all constants, the value itself as one
        more constant (the same numpy call, made once now: folding changes no value)."""
        if operands and all(operand in self.constants for operand in operands):
            with np.errstate(divide="ignore", invalid="ignore"):
                return self.constant(eval(text, {**_NAMES, **self.constants}))  # noqa: S307
        name = f"t{len(self.lines)}"
        self.lines.append(f"{name} = {text}")
        return name

    def fallback(self, expr: ie.Expr, frame: str) -> str:
        """The evaluator's own value of ``expr`` (its errors too)."""
        return self.emit(f"ev.value({self.constant(expr)}, {frame})")

    def function(self, results: list[str]) -> str:
        head = ["def compiled(f0, ev):"]
        body = [f"f{d} = f{d - 1}.prev if f{d - 1}.prev is not None else f{d - 1}" for d in range(1, self.depth + 1)]
        # divide and invalid as the evaluator ignores them (its arithmetic and math functions); the
        # comparisons and logic it runs outside warn about neither
        body.append("with np.errstate(divide='ignore', invalid='ignore'):")
        statements = ["    " + line for line in self.lines] or ["    pass"]
        return "\n".join(head + ["    " + line for line in body + statements]
                         + [f"    return [{', '.join(results)}]", ""])

    # ------------------------------------------------------------ nodes
    def node(self, expr: ie.Expr, depth: int) -> str:
        key = (_key(expr), depth)
        if key not in self.names:
            self.names[key] = self.write(expr, depth)
        return self.names[key]

    def write(self, expr: ie.Expr, depth: int) -> str:
        frame = f"f{depth}"
        if isinstance(expr, ie.Const):
            return self.constant(np.bool_(expr.value) if isinstance(expr.value, bool)
                                 else np.float64(float(expr.value)))
        if isinstance(expr, ie.Ref):
            return self.ref(expr, frame)
        if isinstance(expr, ie.Call):
            return self.call(expr, depth)
        if isinstance(expr, ie.Prev):
            self.depth = max(self.depth, depth + 1)
            return self.node(expr.operand, depth + 1)
        if isinstance(expr, ie.Unary):
            operand = self.node(expr.operand, depth)
            return self.emit(f"np.logical_not({operand})" if expr.op == "!" else f"-{operand}", operand)
        if isinstance(expr, ie.Compare):
            return self.compare(expr, depth)
        left, right = self.node(expr.left, depth), self.node(expr.right, depth)
        if expr.op == "&&":
            return self.emit(f"np.logical_and({left}, {right})", left, right)
        if expr.op == "||":
            return self.emit(f"np.logical_or({left}, {right})", left, right)
        if expr.op == "imply":
            return self.emit(f"np.logical_or(np.logical_not({left}), {right})", left, right)
        return self.emit(f"{_ARITHMETIC[expr.op]}({left}, {right}, dtype=np.float64)", left, right)

    def ref(self, ref: ie.Ref, frame: str) -> str:
        kind = ref.kind
        if kind is ie.RefKind.INPUT:
            name = repr(ref.name)
            self.lines.append(f"if {frame}.inputs is None or {name} not in {frame}.inputs: "
                              f"ev.value({self.constant(ref)}, {frame})")
            return self.emit(f"{frame}.inputs[{name}]")
        if kind is ie.RefKind.REWARD:
            self.lines.append(f"if {frame}.rewards is None: ev.value({self.constant(ref)}, {frame})")
            return self.emit(f"{frame}.rewards[{ref.name!r}]")
        if kind in (ie.RefKind.LOCATION, ie.RefKind.LOCATION_INDEX):
            self.lines.append(f"if {frame}.location is None: ev.value({self.constant(ref)}, {frame})")
            if kind is ie.RefKind.LOCATION_INDEX:
                return self.emit(f"{frame}.location.astype(np.float64)")
            return self.emit(f"{frame}.location == {int(ref.index)}")
        if kind is ie.RefKind.DEADLOCK:
            return self.constant(np.bool_(False))
        entry = ref.model
        if entry.kind == "ego":
            return self.emit(f"{frame}.ego[:, {int(ref.index)}] / {self.constant(self.evaluator.scale_d)}")
        if entry.holding is Holding.TIME:
            return self.emit(f"{frame}.k * {self.constant(self.evaluator.period_d)}")
        if entry.holding is Holding.TRUTH:
            self.lines.append(f"if {frame}.truth is None: ev.value({self.constant(ref)}, {frame})")
            return self.emit(f"{frame}.truth[:, {int(ref.index)}]")
        assert ref.value is not None, ref
        return self.constant(np.float64(float(ref.value)))

    def call(self, call: ie.Call, depth: int) -> str:
        frame = f"f{depth}"
        name = call.name
        if call.function.kind == "model":
            return self.emit(f"ev.function({name!r}, {frame})")
        if name not in _MATH_1 and name not in ("round", "fmin", "fmax"):
            return self.fallback(call, frame)  # the evaluator's error
        args = []
        for arg in call.args:
            operand = self.node(arg, depth)
            args.append(self.emit(f"np.asarray({operand}, dtype=np.float64)", operand))
        if name in _MATH_1:
            return self.emit(f"{_MATH_1[name]}({args[0]})", *args)
        if name == "round":  # C's round, the evaluator's own function
            return self.emit(f"c_round({args[0]})", *args)
        return self.emit(f"np.{name}({args[0]}, {args[1]})", *args)

    # ------------------------------------------------------------ comparisons
    def compare(self, expr: ie.Compare, depth: int) -> str:
        frame = f"f{depth}"
        form = expr.linear
        exact = self.exact_terms(form, frame) if form is not None else None
        if exact is None:  # not decided on integers (the evaluator neither): on doubles
            left, right = self.node(expr.left, depth), self.node(expr.right, depth)
            return self.emit(f"{_COMPARE[expr.op]}({left}, {right})", left, right)
        assert form is not None
        conditions, columns = exact
        multiple = math.lcm(form.const.denominator, *(c.denominator for c, _ in columns))
        const = int(form.const * multiple)
        coefficients = [int(c * multiple) for c, _ in columns]
        compare = _COMPARE[expr.op]
        if columns and abs(const) + sum(abs(c) for c in coefficients) * INT32_BOUND < _SAFE_INT64:
            # int64 holds every partial sum exactly (int_sum's test), so the order of the sum is free
            total = " + ".join([str(const)] + [f"{c} * {column}.astype(np.int64)"
                                               for c, (_, column) in zip(coefficients, columns)])
            value = f"np.asarray({compare}({total}, 0), dtype=bool)"
        else:  # a constant, or beyond int64: by the evaluator's own int_sum
            terms = ", ".join(f"({c}, {column}.astype(np.int64))" for c, (_, column) in zip(coefficients, columns))
            value = f"np.asarray({compare}(int_sum({const}, [{terms}], {frame}.n), 0), dtype=bool)"
        if not conditions:
            return self.emit(value)
        # what the frame holds decides: exact on its integers, else the evaluator (on doubles)
        name = f"t{len(self.lines)}"
        self.lines.append(f"{name} = {value} if {' and '.join(conditions)} else "
                          f"ev.value({self.constant(expr)}, {frame})")
        return name

    def exact_terms(self, form: ie.LinearForm, frame: str) -> tuple[list[str], list[tuple[Fraction, str]]] | None:
        """The conditions on the frame under which ``form`` is decided on integers, and its columns
        (coefficient times unit, the column's code); None when it never is (a true-state term)."""
        conditions: list[str] = []
        columns: list[tuple[Fraction, str]] = []
        unit = Fraction(1, self.evaluator.data.scale)
        for ref, coefficient in form.terms:
            if ref.kind is ie.RefKind.INPUT:
                conditions.append(f"{frame}.significands is not None and {ref.name!r} in {frame}.significands")
                columns.append((coefficient * unit, f"{frame}.significands[{ref.name!r}]"))
            elif ref.kind is ie.RefKind.REWARD:
                conditions.append(f"{frame}.mirrors is not None")
                columns.append((coefficient * unit, f"{frame}.mirrors[{ref.name!r}]"))
            elif ref.kind is ie.RefKind.LOCATION_INDEX:
                conditions.append(f"{frame}.location is not None")
                columns.append((coefficient, f"{frame}.location"))
            elif ref.kind is ie.RefKind.MODEL and ref.model.kind == "ego":
                columns.append((coefficient * unit, f"{frame}.ego[:, {int(ref.index)}]"))
            elif ref.kind is ie.RefKind.MODEL and ref.model.holding is Holding.TIME:
                columns.append((coefficient * self.evaluator.period, f"{frame}.k"))
            else:
                return None
        return sorted(set(conditions), key=conditions.index), columns


def _key(expr: ie.Expr) -> tuple:
    """``expr`` as a tuple that tells ``false`` from ``0`` (the nodes compare them equal, as Python's
    ``False == 0``): equal keys, the same value."""
    if isinstance(expr, ie.Const):
        return ("const", type(expr.value).__name__, expr.value)
    if isinstance(expr, ie.Ref):
        return ("ref", expr.kind, expr.name, expr.type, expr.index, expr.value)
    if isinstance(expr, ie.Call):
        return ("call", expr.name, *(_key(arg) for arg in expr.args))
    if isinstance(expr, ie.Prev):
        return ("prev", _key(expr.operand))
    if isinstance(expr, ie.Unary):
        return ("unary", expr.op, _key(expr.operand))
    if isinstance(expr, ie.Compare):  # its linear form has no truth values: compared as it is
        return ("compare", expr.op, _key(expr.left), _key(expr.right), expr.linear)
    return ("binary", expr.op, _key(expr.left), _key(expr.right))
