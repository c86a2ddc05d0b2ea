"""Expressions in UPPAAL syntax: literals, the automaton's guards and its linear forms.

Everything the UPPAAL target prints goes through this module, so its rules hold for every
label and query of the emitted model:

- doubles have digits on both sides of the point (``0.5``, ``1.0e-5``; never ``.5`` or ``5.``);
- integer literals fit ``int32`` (UPPAAL's lexer rejects anything above 2147483647 with
  ``$Overflow``): :class:`NotRepresentable` otherwise;
- logical operators are ``&&``, ``||``, ``!`` and ``imply``. In UPPAAL ``imply`` has the
  precedence of ``||`` and associates to the *left* (``.ra``'s ``imply`` associates to the
  right), so operands are parenthesised whenever a reader could hesitate (the table
  :data:`UPPAAL` of :class:`UppaalSyntax`, a :class:`rac.core.printing.Printer`);
- formulas are printed on one line.

Numbers: a real value ``v`` is held in an integer as its significand ``v * SCALE``
(``SCALE = base ** exponent``). Comparisons of significands with a threshold are exact for every
integer significand: ``x < 2`` becomes ``x < 20000``, and a threshold whose scaled value is not an
integer is rounded the way that keeps the comparison's truth on integers
(``x <= 0.00015`` becomes ``x <= 1``, ``x < 0.00015`` becomes ``x < 2``).

Queries and bindings are printed by :mod:`rac.targets.uppaal.query`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from fractions import Fraction

from rac import ir
from rac.core.diagnostics import RacError
from rac.core.numbers import INT32_MAX
from rac.core.printing import C_BINARY, Associativity, Level, Operator, OperatorTable, Printed, Printer, signed_sum
from rac.ir.expr import integer_bound
from rac.ir.significands import common_denominator, literal_problem
from rac.ir.text import GuardPrinter

__all__ = [
    "UPPAAL",
    "NotRepresentable",
    "QueryError",
    "UppaalGuards",
    "UppaalSyntax",
    "compare_significand",
    "double_literal",
    "int_literal",
    "number_literal",
    "print_exact_sum",
    "print_guard",
    "print_int_linear",
    "print_real_linear",
    "terms_text",
]

class NotRepresentable(RacError, ValueError):
    """A number has no UPPAAL literal (an integer beyond int32, an infinite double)."""


class QueryError(RacError, ValueError):
    """A query cannot be written over the emitted model (the message says why)."""


# ---------------------------------------------------------------- literals
def int_literal(value: int | Fraction) -> str:
    """An integer literal; :class:`NotRepresentable` when it is not an integer or beyond int32
    (:func:`rac.ir.significands.literal_problem`, which the checker's E0801 reads too)."""
    problem = literal_problem(value)
    if problem is not None:
        raise NotRepresentable(problem)
    return str(int(value))


def double_literal(value: Fraction | float) -> str:
    """A double literal with digits on both sides of the point: ``0.5``, ``100.0``, ``1.0e-5``.

    The text is the shortest decimal that reads back as the nearest double (``repr``), so exact
    decimals such as ``0.1`` print as written.
    """
    number = float(value)
    if not math.isfinite(number):
        raise NotRepresentable(f"{value} has no double literal")
    mantissa, mark, exponent = repr(number).partition("e")
    if "." not in mantissa:
        mantissa += ".0"
    if not mark:
        return mantissa
    return f"{mantissa}e{int(exponent)}"


def number_literal(value: Fraction) -> str:
    """An integer literal when ``value`` is an integer, else a double literal."""
    if value.denominator == 1:
        return int_literal(value.numerator)
    return double_literal(value)


# ---------------------------------------------------------------- the operators
#: UPPAAL's operators: C's, and ``imply``, which UPPAAL gives the level of ``||`` and associates to
#: the left; it is printed with both operands above that level, so that no reader depends on that.
UPPAAL = OperatorTable(
    binary={**C_BINARY, "imply": Operator(" imply ", Level.OR, Associativity.NONE)},
    # `!!a`, but `-(-a)`: C would read `--a` as a decrement
    prefix={"!": Operator("!", Level.PREFIX, Associativity.RIGHT),
            "-": Operator("-", Level.PREFIX, Associativity.NONE)},
)


class UppaalSyntax(Printer):
    """Parenthesises by :data:`UPPAAL`, and more where a reader of `.ra` could hesitate."""

    table = UPPAAL

    def needs_parentheses(self, op: str, operand: Printed, need: int) -> bool:
        # `a imply b || c` is `(a imply b) || c` in UPPAAL, `a imply (b || c)` in `.ra`: in a chain of
        # `||` or `&&`, an operand of the chain's level that holds `imply` stands in parentheses even first
        if op in ("||", "&&") and operand.level == self.binary(op).level and "imply" in operand.text.split():
            return True
        return super().needs_parentheses(op, operand, need)


# ---------------------------------------------------------------- significand comparisons
def compare_significand(significand: str, op: str, threshold: Fraction, scale: int) -> Printed:
    """``x op threshold`` for an input held as the integer significand ``x * scale``, exactly."""
    result = integer_bound(op, threshold * scale)
    if isinstance(result, bool):
        return Printed(UPPAAL.true if result else UPPAAL.false, Level.ATOM)
    new_op, bound = result
    return Printed(f"{significand} {new_op} {int_literal(bound)}", Level.COMPARE)


# ---------------------------------------------------------------- guards of the automaton
class UppaalGuards(UppaalSyntax, GuardPrinter):
    """Prints the automaton's guards; a numeric input is held as its significand at ``scale``."""

    def __init__(self, names: Mapping[str, str], scale: int) -> None:
        super().__init__(names)
        self.scale = scale

    def print_BAtom(self, guard: ir.BAtom) -> Printed:
        return compare_significand(self.names[guard.input], guard.op, guard.threshold, self.scale)


def print_guard(guard: ir.Guard, names: Mapping[str, str], scale: int) -> str:
    """A guard over the inputs; ``names`` maps each input to the UPPAAL expression holding it
    (a ``bool`` for boolean inputs, an integer significand for numeric ones)."""
    return UppaalGuards(names, scale).print(guard).text


# ---------------------------------------------------------------- linear forms
def terms_text(terms: Sequence[tuple[int, str]]) -> str:
    """``10*iSa + 5*iPr - iCo`` from integer coefficients (none zero)."""
    return signed_sum(_term_parts(terms))


def _term_parts(terms: Sequence[tuple[int, str]]) -> list[tuple[bool, str]]:
    return [(coef < 0, name if abs(coef) == 1 else f"{int_literal(abs(coef))}*{name}") for coef, name in terms]


def print_int_linear(const: Fraction, terms: Sequence[tuple[Fraction, str]]) -> str:
    """``const + Σ coefficient*variable`` over integer variables, in integer arithmetic.

    With integer coefficients and constant the value is exact. Otherwise everything is put over
    the least common denominator ``q`` and divided: ``(2*iSa + iPr) / 3``. UPPAAL's integer
    division truncates towards zero, so the result is the exact value truncated — once.
    """
    q, k, ints = common_denominator(const, terms)
    if not ints:
        return int_literal(math.trunc(const))
    parts = _term_parts(ints)
    if k:
        parts.append((k < 0, int_literal(abs(k))))
    text = signed_sum(parts)
    if q == 1:
        return text
    if len(ints) == 1 and not k and ints[0][0] > 0:
        return f"{text} / {int_literal(q)}"  # `2*iSa / 3` is `(2*iSa) / 3`
    return f"({text}) / {int_literal(q)}"


def print_exact_sum(const: Fraction, terms: Sequence[tuple[Fraction, str]]) -> str:
    """``Σ coefficient*variable + const`` in integer arithmetic, one division per fractional term:
    ``iSa + dgoal / 10 + 1000``. Exact only when every ``coefficient*variable`` is an integer for
    the values the variables take (the caller checks that), and ``const`` is an integer."""
    parts: list[tuple[bool, str]] = []
    for coef, name in terms:
        if coef == 0:
            continue
        p, q = abs(coef.numerator), coef.denominator
        text = name if p == 1 else f"{int_literal(p)}*{name}"
        if q != 1:
            text += f" / {int_literal(q)}"
        parts.append((coef < 0, text))
    if const:
        parts.append((const < 0, int_literal(abs(const))))
    return signed_sum(parts) or "0"


def real_literal(value: Fraction) -> str:
    """A number in a double expression: an integer literal within int32, else a double literal
    (an integer literal beyond int32 would overflow where a double does not)."""
    if value.denominator == 1 and abs(value.numerator) <= INT32_MAX:
        return int_literal(value.numerator)
    return double_literal(value)


def print_real_linear(const: Fraction, terms: Sequence[tuple[Fraction, str, int]]) -> str:
    """``const + Σ coefficient*variable/divisor`` as a double expression.

    Each term is ``(coefficient, variable, divisor)``: a hybrid clock has divisor 1, an integer
    significand the scale (``dgoal / 10000.0``). Coefficients of integer variables print as
    doubles so that no intermediate product is an integer that could overflow.
    """
    parts: list[tuple[bool, str]] = []
    for coef, name, divisor in terms:
        if coef == 0:
            continue
        magnitude = abs(coef)
        if divisor == 1:
            # a hybrid clock less a bare clock (`r0 - r1`) is a clock difference, which UPPAAL refuses to
            # assign to a clock ($Incompatible_types); `r0 - 1.0*r1` is a double
            text = name if magnitude == 1 and coef > 0 else f"{real_literal(magnitude)}*{name}"
        else:
            text = f"{name} / {double_literal(divisor)}" if magnitude == 1 else (
                f"{double_literal(magnitude)}*{name} / {double_literal(divisor)}")
        parts.append((coef < 0, text))
    if not parts:
        return real_literal(const)
    if const:
        parts.append((const < 0, real_literal(abs(const))))
    return signed_sum(parts)
