"""Typed, resolved expressions: what bindings and queries read, decided once by the checker.

The checker (:mod:`rac.check.queries`) lowers every binding and query expression of a file into
these nodes. Each name is resolved there — to an input, a reward, a location, a name of the
scenario model (:data:`rac.ir.vocabulary.MODEL_NAMES`) or a constant, whose value is inlined — and
each node carries its type (``"bool"`` or ``"num"``). The engine's evaluator
(:mod:`rac.engine.evaluate`), the product with the automaton and the UPPAAL printers read these nodes
only; none of them looks a name up again.

A comparison carries, besides its two sides, the linear form of ``left - right`` when both sides
are linear (constant multiples of numbers, settings folded into constants at the value the model
holds them): :class:`Compare.linear`. Every target compares such a form exactly when all its
terms are held as integers there (significands, mirrors, the sample counter), so the engine and
the emitted model agree on every comparison of the sensed state with a threshold.

Example::

    result = compile_file("examples/left_turn/model.ra")
    binding = result.automaton.model.bindings[0]     # isClose = mindist() < 3 * collision_distance
    binding.expr                                      # Compare("<", Call(mindist), Binary("*", Const(3), Ref(...)))
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from enum import Enum
from fractions import Fraction
from typing import Union

from rac.core.source import Span
from rac.ir.vocabulary import EGO_STATE, FUNCTIONS, MODEL_NAMES, TRUE_STATE, Function, Holding, ModelName

__all__ = [
    "BOOL",
    "NUM",
    "Binary",
    "Call",
    "Compare",
    "Const",
    "Expr",
    "LinearForm",
    "Prev",
    "Ref",
    "RefKind",
    "Unary",
    "call",
    "difference",
    "integer_bound",
    "linear_form",
    "model_ref",
    "prev_operands",
    "reads_automaton",
    "reads_truth",
    "refs",
    "unit_of",
    "uses_prev",
    "walk",
]

BOOL, NUM = "bool", "num"


def _span() -> Span | None:
    return field(default=None, compare=False, repr=False)


class RefKind(Enum):
    """What a resolved name refers to."""

    INPUT = "input"  # an input of the automaton (bool or num)
    REWARD = "reward"  # a reward (num)
    LOCATION = "location"  # the automaton is in this location (bool)
    LOCATION_INDEX = "location index"  # ``Automaton.location``: the current location's index (num)
    MODEL = "model"  # a name of the scenario model (:data:`MODEL_NAMES`): ego, truth, setting, time
    DEADLOCK = "deadlock"  # UPPAAL's ``deadlock`` (bool; the model never deadlocks)


@dataclass(frozen=True)
class Const:
    """A number (exact) or a truth value; constants of the automaton are inlined as these."""

    value: Fraction | bool
    span: Span | None = _span()

    @property
    def type(self) -> str:
        return BOOL if isinstance(self.value, bool) else NUM


@dataclass(frozen=True)
class Ref:
    """A resolved name.

    ``index`` is the input's, reward's or location's position in the automaton (-1 otherwise);
    ``value`` a setting's value as the model holds it (a significand setting truncated to its
    significand, e.g. 4.5555 for ``length 4.55555`` at exponent 4), None for other names.
    """

    kind: RefKind
    name: str
    type: str
    index: int = -1
    value: Fraction | None = None
    span: Span | None = _span()

    @property
    def model(self) -> ModelName:
        """The vocabulary entry of a :attr:`RefKind.MODEL` name."""
        return MODEL_NAMES[self.name]

    @property
    def is_model(self) -> bool:
        return self.kind is RefKind.MODEL


@dataclass(frozen=True)
class Call:
    """A call of a model function (``collide()``, ``mindist()`` ...) or a math function (``fabs``)."""

    function: Function
    args: tuple[Expr, ...]
    span: Span | None = _span()

    @property
    def name(self) -> str:
        return self.function.name

    @property
    def type(self) -> str:
        return self.function.result or NUM


@dataclass(frozen=True)
class Prev:
    """``prev(e)``: ``e`` at the previous sample (``e`` itself at the first)."""

    operand: Expr
    span: Span | None = _span()

    @property
    def type(self) -> str:
        return self.operand.type


@dataclass(frozen=True)
class Unary:
    """``-e`` (num) or ``!e`` (bool)."""

    op: str
    operand: Expr
    span: Span | None = _span()

    @property
    def type(self) -> str:
        return NUM if self.op == "-" else BOOL


@dataclass(frozen=True)
class Binary:
    """Arithmetic (``+ - * /``, num) or logic (``&& || imply``, bool)."""

    op: str
    left: Expr
    right: Expr
    span: Span | None = _span()

    @property
    def type(self) -> str:
        return NUM if self.op in ("+", "-", "*", "/") else BOOL


@dataclass(frozen=True)
class LinearForm:
    """``const + Σ coefficient · ref``: the value of ``left - right`` of a linear comparison.

    Terms are numeric inputs, rewards, ego and true-state names, ``time`` and ``Automaton.location``;
    settings and constants are folded into ``const``. A term's ``Ref`` appears once.
    """

    const: Fraction
    terms: tuple[tuple[Ref, Fraction], ...] = ()

    @property
    def is_constant(self) -> bool:
        return not self.terms


@dataclass(frozen=True)
class Compare:
    """``left op right`` (bool); ``linear`` is the form of ``left - right`` when both sides are linear."""

    op: str
    left: Expr
    right: Expr
    linear: LinearForm | None = None
    span: Span | None = _span()

    @property
    def type(self) -> str:
        return BOOL


Expr = Union[Const, Ref, Call, Prev, Unary, Binary, Compare]


# ---------------------------------------------------------------- constructors
def model_ref(name: str, value: Fraction | None = None) -> Ref:
    """The :class:`Ref` of a name of the scenario model (``value``: a setting's, as the model holds it)."""
    entry = MODEL_NAMES[name]
    index = EGO_STATE.index(name) if entry.kind == "ego" else TRUE_STATE.index(name) if entry.kind == "truth" else -1
    return Ref(RefKind.MODEL, name, NUM, index, value)


def call(name: str, *args: Expr) -> Call:
    """A call of a model or math function by name, e.g. ``call("goal")``."""
    return Call(FUNCTIONS[name], tuple(args))


# ---------------------------------------------------------------- linear forms
def linear_form(expr: Expr) -> LinearForm | None:
    """The linear form of a numeric expression, or None when it is not linear (a call, a product
    of two varying values, ``prev``...). Settings fold into the constant (their held value)."""
    if isinstance(expr, Const):
        return None if isinstance(expr.value, bool) else LinearForm(Fraction(expr.value))
    if isinstance(expr, Ref):
        if expr.type != NUM:
            return None
        if expr.kind is RefKind.MODEL and expr.model.kind == "setting":
            return None if expr.value is None else LinearForm(expr.value)
        return LinearForm(Fraction(0), ((expr, Fraction(1)),))
    if isinstance(expr, Unary) and expr.op == "-":
        inner = linear_form(expr.operand)
        return None if inner is None else _scaled(inner, Fraction(-1))
    if isinstance(expr, Binary) and expr.type == NUM:
        left, right = linear_form(expr.left), linear_form(expr.right)
        if left is None or right is None:
            return None
        if expr.op in ("+", "-"):
            return _added(left, right, 1 if expr.op == "+" else -1)
        if expr.op == "*":
            if left.is_constant:
                return _scaled(right, left.const)
            return _scaled(left, right.const) if right.is_constant else None
        if right.is_constant and right.const != 0:
            return _scaled(left, 1 / right.const)
    return None


def _scaled(form: LinearForm, factor: Fraction) -> LinearForm:
    if factor == 0:
        return LinearForm(Fraction(0))
    return LinearForm(form.const * factor, tuple((ref, c * factor) for ref, c in form.terms))


def _added(a: LinearForm, b: LinearForm, sign: int) -> LinearForm:
    coefficients = dict(a.terms)
    for ref, c in b.terms:
        coefficients[ref] = coefficients.get(ref, Fraction(0)) + sign * c
    return LinearForm(a.const + sign * b.const, tuple((r, c) for r, c in coefficients.items() if c != 0))


def difference(left: Expr, right: Expr) -> LinearForm | None:
    """The linear form of ``left - right`` when both are linear numbers, else None."""
    if left.type != NUM or right.type != NUM:
        return None
    a, b = linear_form(left), linear_form(right)
    return None if a is None or b is None else _added(a, b, -1)


def integer_bound(op: str, bound: Fraction) -> tuple[str, int] | bool:
    """``X op bound`` for an integer-valued ``X``, as ``X op' k`` with an integer ``k``, or a constant
    truth: the exact comparison every target makes of an integer with a rational threshold."""
    if bound.denominator == 1:
        return op, bound.numerator
    if op == "<":
        return "<", math.ceil(bound)
    if op == "<=":
        return "<=", math.floor(bound)
    if op == ">":
        return ">", math.floor(bound)
    if op == ">=":
        return ">=", math.ceil(bound)
    return op == "!="  # X == non-integer is never true, X != non-integer always


# ---------------------------------------------------------------- units
#: Math functions whose result has the unit their arguments share.
_SAME_UNIT = frozenset({"fabs", "abs", "fmin", "fmax", "floor", "ceil", "round", "trunc"})


def unit_of(expr: Expr) -> str | None:
    """The unit of a number expression, from the vocabulary: ``"m"`` for ``mindist()`` and
    ``3 * collision_distance``, ``"m/s"`` for ``prev(v)``, ``""`` for a plain number; None when it
    has none to tell: a truth value, a name of the automaton (an input or reward has no declared
    unit), or two units combined (``mindist() / v``: products and quotients are not worked out).

    A bare number added to a quantity takes its unit (``mindist() - 1.5`` is in metres).

    Example::

        unit_of(Binary("*", Const(Fraction(3)), model_ref("collision_distance")))  # "m"
    """
    if expr.type != NUM:
        return None
    if isinstance(expr, Const):
        return ""
    if isinstance(expr, Ref):
        return expr.model.unit if expr.is_model else None
    if isinstance(expr, (Prev, Unary)):
        return unit_of(expr.operand)
    if isinstance(expr, Call):
        if expr.function.kind == "model":
            return expr.function.unit
        units = {unit_of(arg) for arg in expr.args}
        if expr.name in _SAME_UNIT or units == {""}:  # sqrt of a plain number is one
            return units.pop() if len(units) == 1 else None
        return None
    if isinstance(expr, Binary):
        left, right = unit_of(expr.left), unit_of(expr.right)
        if expr.op in ("+", "-"):
            if left == right:
                return left
            return right if isinstance(expr.left, Const) else left if isinstance(expr.right, Const) else None
        if expr.op == "*":
            return right if left == "" else left if right == "" else None
        if right == "":
            return left
        return "" if left == right and left is not None else None
    return None


# ---------------------------------------------------------------- walking
def walk(expr: Expr) -> Iterator[Expr]:
    """``expr`` and every node below it, parents first."""
    yield expr
    if isinstance(expr, (Unary, Prev)):
        yield from walk(expr.operand)
    elif isinstance(expr, (Binary, Compare)):
        yield from walk(expr.left)
        yield from walk(expr.right)
    elif isinstance(expr, Call):
        for arg in expr.args:
            yield from walk(arg)


def refs(expr: Expr) -> set[Ref]:
    """Every name an expression reads (spans aside, each once)."""
    return {node for node in walk(expr) if isinstance(node, Ref)}


def reads_automaton(expr: Expr) -> bool:
    """Whether ``expr`` reads the automaton's state: an input, a reward or a location."""
    return any(r.kind in (RefKind.INPUT, RefKind.REWARD, RefKind.LOCATION, RefKind.LOCATION_INDEX)
               for r in refs(expr))


def reads_truth(expr: Expr) -> bool:
    """Whether ``expr`` reads the ground truth (``true_x`` ...), which statistical queries alone follow."""
    return any(r.is_model and r.model.holding is Holding.TRUTH for r in refs(expr))


def state_independent(expr: Expr) -> bool:
    """Whether ``expr`` has one value in every state of the model: it reads constants, the model's settings,
    math functions of them and ``deadlock`` only (no state, no time, no model function, no ``prev``)."""
    for node in walk(expr):
        if isinstance(node, Prev) or (isinstance(node, Call) and node.function.kind != "math"):
            return False
        if isinstance(node, Ref) and not (node.kind is RefKind.DEADLOCK
                                          or (node.is_model and node.model.kind == "setting")):
            return False
    return True


def uses_prev(expr: Expr) -> bool:
    return any(isinstance(node, Prev) for node in walk(expr))


def prev_operands(exprs: tuple[Expr, ...] | list[Expr]) -> list[Expr]:
    """The distinct ``e`` of every ``prev(e)`` in ``exprs``, in first-occurrence order."""
    found: list[Expr] = []
    for expr in exprs:
        for node in walk(expr):
            if isinstance(node, Prev) and node.operand not in found:
                found.append(node.operand)
    return found
