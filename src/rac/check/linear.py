"""The automaton's own expressions typed: numbers as linear forms, conditions as guards.

The resolver (:mod:`rac.check.resolve`) reads every guard, rate, update, the objective and the
constants through an :class:`ExpressionTyper`. A number must be linear in the numeric inputs and
rewards (:class:`rac.ir.Linear`); a condition becomes a guard over the inputs (:data:`rac.ir.Guard`),
each comparison normalised to ``input op threshold``. A :class:`Context` says what the expression
may name. Errors go to the scope and raise :class:`rac.check.symbols.Unresolvable`. (Queries and
bindings are typed by :mod:`rac.check.queries`, into :mod:`rac.ir.expr` instead.)
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass
from fractions import Fraction
from typing import ClassVar, NoReturn

from rac import ir
from rac.check.queries import type_word
from rac.check.symbols import DIVISION_BY_ZERO_HINT, Scope, Unresolvable
from rac.ir.vocabulary import MODEL_FUNCTIONS, MODEL_NAMES
from rac.lang import ast
from rac.lang.parser import MAX_EXACT_DIGITS, MAX_MAGNITUDE, MIN_MAGNITUDE

__all__ = ["CONSTANT", "GUARD", "OBJECTIVE", "RATE", "UPDATE", "Bool", "Context", "ExpressionTyper", "Num", "Typed"]


@dataclass(frozen=True)
class Context:
    """What an expression may mention, and how to call it in messages."""

    what: str
    rewards: bool = False
    inputs: bool = True
    #: A condition over the inputs (a guard, an assumption, an outcome): a reward there is E0202.
    condition: bool = False


GUARD = Context("a guard", condition=True)
RATE = Context("a rate")
UPDATE = Context("an update", rewards=True)
OBJECTIVE = Context("the objective", rewards=True, inputs=False)
CONSTANT = Context("a constant expression", inputs=False)


@dataclass(frozen=True)
class Num:
    """A numeric expression of the automaton: linear in its numeric inputs and rewards."""

    value: ir.Linear
    kind: ClassVar[str] = "num"


@dataclass(frozen=True)
class Bool:
    """A condition of the automaton (a guard over its inputs)."""

    value: ir.Guard
    kind: ClassVar[str] = "bool"


#: A typed expression of the automaton, as :meth:`ExpressionTyper.expr` returns it.
Typed = Num | Bool


class ExpressionTyper:
    """Types the automaton's expressions against ``scope`` (its symbols; its diagnostics)."""

    def __init__(self, scope: Scope) -> None:
        self.scope = scope
        #: The inputs the typed expressions read (the others are reported unused).
        self.used_inputs: set[str] = set()

    def expr(self, node: ast.Expr, ctx: Context) -> Typed:
        """Type an expression: a :class:`Num` (linear) or a :class:`Bool` (a guard)."""
        if isinstance(node, ast.Number):
            return Num(ir.Linear.constant(node.value))
        if isinstance(node, ast.BoolLit):
            return Bool(ir.BConst(node.value))
        if isinstance(node, ast.Name):
            return self._name(node, ctx)
        if isinstance(node, ast.Unary):
            operand = self.expr(node.operand, ctx)
            if node.op == "-":
                return Num(self._num(operand, node.operand, "`-`").scaled(-1))
            return Bool(_not(self._bool(operand, node.operand, "`!`")))
        if isinstance(node, ast.Binary):
            return self._binary(node, ctx)
        if isinstance(node, ast.Call):
            self.scope.error("E0103", f"`{node.func}(...)` is not available in {ctx.what}", node.span,
                             hints=[_read_through_an_input(f"`{node.func}()`" if node.func in MODEL_FUNCTIONS
                                                           else f"`{node.func}(...)`")])
            raise Unresolvable
        self.scope.error("E0103", f"`{node.scope}.{node.id}` is not available in {ctx.what}", node.span,
                         hints=["qualified names are allowed in queries only"])
        raise Unresolvable

    def _num(self, typed: Typed, node: ast.Expr, where: str) -> ir.Linear:
        """The linear value of ``typed``; E0201 (and :class:`Unresolvable`) for a condition."""
        if isinstance(typed, Bool):
            self._mismatch("num", typed, node, where)
        return typed.value

    def _bool(self, typed: Typed, node: ast.Expr, where: str) -> ir.Guard:
        """The guard of ``typed``; E0201 (and :class:`Unresolvable`) for a number."""
        if isinstance(typed, Num):
            self._mismatch("bool", typed, node, where)
        return typed.value

    def _mismatch(self, want: str, got: Typed, node: ast.Expr, where: str) -> NoReturn:
        hints = []
        if want == "bool":
            shown = node.id if isinstance(node, ast.Name) else "x"
            hints.append(f"a number is not a condition: compare it, e.g. `{shown} < 2`")
        else:  # a condition where a number goes: `prog + 1`, `10 * isClose`
            hints.append("a condition is not a number: write a number here, or compare first (`x < 2`) "
                         "and combine conditions with `&&` and `||`")
        self.scope.error("E0201", f"{where} needs {type_word(want)}, found {type_word(got.kind)}", node.span,
                         hints=hints)
        raise Unresolvable

    def _name(self, node: ast.Name, ctx: Context) -> Typed:
        symbol = self.scope.symbols.get(node.id)
        if symbol is None and node.id in MODEL_NAMES:  # `time`, `v`, `max_speed`: the scenario model's
            self.scope.error("E0101", f"unknown name `{node.id}`", node.span,
                             hints=[_read_through_an_input(f"`{node.id}`")])
            raise Unresolvable
        if symbol is None:
            self.scope.unknown(node.id, node.span)
            raise Unresolvable
        if symbol.kind == "const":
            if symbol.value is None:
                raise Unresolvable
            if isinstance(symbol.value, bool):
                return Bool(ir.BConst(symbol.value))
            return Num(ir.Linear.constant(symbol.value))
        if symbol.kind == "input":
            if not ctx.inputs:
                self.scope.error("E0103", f"input `{node.id}` cannot appear in {ctx.what}", node.span,
                                 hints=[_why_no_inputs(ctx)])
                raise Unresolvable
            self.used_inputs.add(node.id)
            if symbol.type == "bool":
                return Bool(ir.BInput(node.id))
            return Num(ir.Linear.variable(node.id))
        if symbol.kind == "reward":
            if not ctx.rewards:
                code = "E0202" if ctx.condition else "E0203"
                self.scope.error(code, f"reward `{node.id}` cannot appear in {ctx.what}", node.span,
                                 hints=[_why_no_rewards(ctx)])
                raise Unresolvable
            return Num(ir.Linear.variable(node.id))
        self.scope.error("E0103", f"location `{node.id}` cannot appear in {ctx.what}", node.span,
                         hints=["location names are boolean only in queries (e.g. `A[] Unsafe imply ...`)"])
        raise Unresolvable

    def _in_range(self, value: ir.Linear, node: ast.Expr) -> Num:
        """``value`` as a number, or E0011 (and :class:`Unresolvable`) when a constant or coefficient of
        it lies beyond what a double holds (the targets compute with doubles), or needs more than
        :data:`MAX_EXACT_DIGITS` digits to hold exactly."""
        for number in (value.const, *(coefficient for _, coefficient in value.terms)):
            if max(abs(number.numerator), number.denominator) >= _EXACT_LIMIT:
                self.scope.error("E0011", f"this computes a number whose exact value needs more than "
                                 f"{MAX_EXACT_DIGITS:,} digits (about {_about(number)})", node.span,
                                 notes=["the checks compute exactly, and each product of constants may double "
                                        "the digits an exact value needs, while every target computes with "
                                        "doubles, which hold 17"],
                                 hints=["round a constant this reads to the digits the model needs"])
                raise Unresolvable
            size = abs(number)
            if size > MAX_MAGNITUDE or 0 < size < MIN_MAGNITUDE:
                which = "large" if size > MAX_MAGNITUDE else "small"
                self.scope.error("E0011", f"this computes a number too {which} for a double "
                                 f"(about {_about(number)})", node.span,
                                 notes=["the checks compute exactly, but every target computes with doubles: a "
                                        "value must be 0 or between 1e-307 and 1e308 in size"],
                                 hints=["use smaller constants or another unit"])
                raise Unresolvable
        return Num(value)

    def _binary(self, node: ast.Binary, ctx: Context) -> Typed:
        typed = self._binary_value(node, ctx)
        return self._in_range(typed.value, node) if isinstance(typed, Num) else typed

    def _operands(self, node: ast.Binary, ctx: Context) -> tuple[Typed, Typed]:
        """Both operands typed. When the left one has errors, the right one is still typed, for its
        own errors (a guard reports every mixed comparison, in source order), then it fails too."""
        try:
            left = self.expr(node.left, ctx)
        except Unresolvable:
            with contextlib.suppress(Unresolvable):
                self.expr(node.right, ctx)
            raise
        return left, self.expr(node.right, ctx)

    def _binary_value(self, node: ast.Binary, ctx: Context) -> Typed:
        lt, rt = self._operands(node, ctx)
        op = node.op
        if op in ast.ARITHMETIC_OPS:
            left, right = self._num(lt, node.left, f"`{op}`"), self._num(rt, node.right, f"`{op}`")
            if op == "+":
                return Num(left + right)
            if op == "-":
                return Num(left - right)
            if op == "*":
                if left.is_constant:
                    return Num(right.scaled(left.const))
                if right.is_constant:
                    return Num(left.scaled(right.const))
                self.scope.error("E0203", f"{ctx.what} must be linear: both sides of `*` vary", node.span,
                                 hints=["multiply by constants only (rewards and inputs evolve linearly)"])
                raise Unresolvable
            if not right.is_constant:
                self.scope.error("E0203", f"{ctx.what} must be linear: division by a varying value", node.span,
                                 hints=["divide by constants only"])
                raise Unresolvable
            if right.const == 0:
                self.scope.error("E0207", "division by zero", node.right.span, hints=[DIVISION_BY_ZERO_HINT])
                raise Unresolvable
            return Num(left.scaled(1 / right.const))
        if op in ast.COMPARISON_OPS:
            if isinstance(lt, Bool) and isinstance(rt, Bool) and op in ("==", "!="):
                lv, rv = lt.value, rt.value
                same = ir.BOr((ir.BAnd((lv, rv)), ir.BAnd((_not(lv), _not(rv)))))
                return Bool(same if op == "==" else _not(same))
            left, right = self._num(lt, node.left, f"`{op}`"), self._num(rt, node.right, f"`{op}`")
            return Bool(self._atom(node, left - right, op))
        lv, rv = self._bool(lt, node.left, f"`{op}`"), self._bool(rt, node.right, f"`{op}`")
        if op == "&&":
            return Bool(ir.BAnd((lv, rv)))
        if op == "||":
            return Bool(ir.BOr((lv, rv)))
        return Bool(ir.BOr((_not(lv), rv)))

    def _atom(self, node: ast.Binary, difference: ir.Linear, op: str) -> ir.Guard:
        """Normalise ``left op right`` (as ``left - right op 0``) to ``input op' threshold``."""
        if difference.is_constant:
            return ir.BConst(ir.compare(difference.const, op, 0))
        rewards = [n for n in difference.variables() if self.scope.symbols[n].kind == "reward"]
        if rewards:
            self.scope.error("E0202", f"reward `{rewards[0]}` cannot be compared", node.span,
                             hints=["rewards only flow and are updated; guards read inputs"])
            raise Unresolvable
        if len(difference.terms) > 1:
            names = ", ".join(f"`{n}`" for n in difference.variables())
            self.scope.error("E0208", f"comparison mixes several numeric inputs ({names})", node.span,
                             hints=["compare each numeric input with a constant; "
                                    "combine such conditions with `&&`/`||`, or add a bool input for it"])
            raise Unresolvable
        (name, coefficient), = difference.terms
        threshold = -difference.const / coefficient
        self._in_range(ir.Linear.constant(threshold), node)
        if coefficient < 0:
            op = {"<": ">", "<=": ">=", ">": "<", ">=": "<="}.get(op, op)
        return ir.BAtom(name, op, threshold)

    def guard(self, node: ast.Expr | None, ctx: Context = GUARD) -> ir.Guard:
        """A condition (``true`` when absent) as a guard over the inputs."""
        if node is None:
            return ir.TRUE
        return self._bool(self.expr(node, ctx), node, ctx.what)

    def linear(self, node: ast.Expr, ctx: Context) -> ir.Linear:
        """A number, linear in what ``ctx`` lets it read."""
        return self._num(self.expr(node, ctx), node, ctx.what)

    def constant(self, node: ast.Expr, what: str) -> Fraction:
        """The value of a constant expression (``what`` names it in messages)."""
        value = self.linear(node, Context(what, inputs=False))
        return value.const


#: The bound :data:`MAX_EXACT_DIGITS` puts on a numerator and a denominator.
_EXACT_LIMIT = 10 ** MAX_EXACT_DIGITS


def _about(value: Fraction) -> str:
    """A rational of any size as ``1.2e400`` (no float conversion, which would overflow)."""
    exponent = math.log10(abs(value.numerator)) - math.log10(value.denominator)
    whole = math.floor(exponent)
    mantissa = round(10 ** (exponent - whole), 1)
    if mantissa >= 10:  # log10's rounding put an exact power of ten below it: 1.0e-600, not 10.0e-601
        mantissa, whole = mantissa / 10, whole + 1
    return f"{'-' if value < 0 else ''}{mantissa:.1f}e{whole}"


def _read_through_an_input(what: str) -> str:
    """The hint for the scenario model's vocabulary or a function in a guard, rate or update: a newcomer
    writes `time > 3` or `mindist() < 3` there, and only queries and bindings read the model."""
    return (f"the automaton reads only its inputs: declare an input, compute it from {what} with a binding of "
            "the `model` block (`bind INPUT = ...`) or in your environment, and read the input here")


def _not(guard: ir.Guard) -> ir.Guard:
    if isinstance(guard, ir.BConst):
        return ir.BConst(not guard.value)
    if isinstance(guard, ir.BNot):
        return guard.operand
    return ir.BNot(guard)


def _why_no_rewards(ctx: Context) -> str:
    if ctx.what == "a rate":
        return "rates are constants or linear in numeric inputs; rewards grow linearly between samples"
    return "rewards behave like UPPAAL hybrid clocks: they cannot steer the automaton"


def _why_no_inputs(ctx: Context) -> str:
    if ctx.what == "the objective":
        return "the objective weighs rewards; let inputs act through guards, rates and updates"
    return "only constants are allowed here"
