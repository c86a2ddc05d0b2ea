"""Expressions in UPPAAL syntax: literals, the automaton's guards and its linear forms.

Everything the UPPAAL target prints goes through this module, so its rules hold for every
label and query of the emitted model:

- doubles have digits on both sides of the point (``0.5``, ``1.0e-5``; never ``.5`` or ``5.``);
- integer literals fit ``int32`` (UPPAAL's lexer rejects anything above 2147483647 with
  ``$Overflow``): :class:`NotRepresentable` otherwise;
- logical operators are ``&&``, ``||``, ``!`` and ``imply``. In UPPAAL ``imply`` has the
  precedence of ``||`` and associates to the *left* (``.ra``'s ``imply`` associates to the
  right), so operands are parenthesised whenever a reader could hesitate;
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
from rac.core.numbers import INT32_MAX
from rac.ir.expr import integer_bound

__all__ = [
    "ADD",
    "AND",
    "ATOM",
    "CMP",
    "MUL",
    "NEG",
    "NUM",
    "OR",
    "NotRepresentable",
    "Text",
    "QueryError",
    "compare_significand",
    "double_literal",
    "imply",
    "int_literal",
    "join",
    "negate",
    "number_literal",
    "paren",
    "print_guard",
    "print_exact_sum",
    "print_int_linear",
    "print_real_linear",
    "terms_text",
]

class NotRepresentable(ValueError):
    """A number has no UPPAAL literal (an integer beyond int32, an infinite double)."""


class QueryError(ValueError):
    """A query cannot be written over the emitted model (the message says why)."""


# ---------------------------------------------------------------- literals
def int_literal(value: int | Fraction) -> str:
    """An integer literal; :class:`NotRepresentable` when it is not an integer or beyond int32."""
    if isinstance(value, Fraction):
        if value.denominator != 1:
            raise NotRepresentable(f"{value} is not an integer")
        value = value.numerator
    if abs(value) > INT32_MAX:
        raise NotRepresentable(f"{value} is beyond the 32-bit integer range (at most {INT32_MAX} in magnitude)")
    return str(value)


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


# ---------------------------------------------------------------- precedence
# 0: top level; 1: `||` and `imply` (one level in UPPAAL, left-associative); 2: `&&`;
# 3: comparisons; 4: `!` and atoms. Arithmetic: 5 `+ -`, 6 `* /`, 7 unary minus, 8 atoms.
OR, AND, CMP, ATOM = 1, 2, 3, 4
ADD, MUL, NEG, NUM = 5, 6, 7, 8

#: A printed expression and its precedence level.
Text = tuple[str, int]


def paren(text: str, level: int, need: int) -> str:
    """``text`` in parentheses when its level is below ``need``."""
    return f"({text})" if level < need else text


def join(parts: Sequence[Text], op: str) -> Text:
    """``a && b && c`` or ``a || b || c`` (left-associative, so equal levels need no parentheses)."""
    level = AND if op == "&&" else OR
    texts = []
    for i, (text, own) in enumerate(parts):
        # `a || b` may stand left of `||`; anything of `imply`'s level stands in parentheses elsewhere.
        need = level + 1 if (own == level and (i > 0 or "imply" in text.split())) else level
        texts.append(paren(text, own, need))
    return f" {op} ".join(texts), level


def imply(left: Text, right: Text) -> Text:
    """``a imply b`` (UPPAAL's ``imply``: the level of ``||``, left-associative)."""
    return f"{paren(left[0], left[1], AND)} imply {paren(right[0], right[1], AND)}", OR


def negate(operand: Text) -> Text:
    """``!a``."""
    return "!" + paren(operand[0], operand[1], ATOM), ATOM


# ---------------------------------------------------------------- significand comparisons
def compare_significand(significand: str, op: str, threshold: Fraction, scale: int) -> tuple[str, int]:
    """``x op threshold`` for an input held as the integer significand ``x * scale``, exactly."""
    result = integer_bound(op, threshold * scale)
    if isinstance(result, bool):
        return ("true" if result else "false"), ATOM
    new_op, bound = result
    return f"{significand} {new_op} {int_literal(bound)}", CMP


# ---------------------------------------------------------------- guards of the automaton
def print_guard(guard: ir.Guard, names: Mapping[str, str], scale: int) -> str:
    """A guard over the inputs; ``names`` maps each input to the UPPAAL expression holding it
    (a ``bool`` for boolean inputs, an integer significand for numeric ones)."""
    return _guard(guard, names, scale)[0]


def _guard(guard: ir.Guard, names: Mapping[str, str], scale: int) -> tuple[str, int]:
    if isinstance(guard, ir.BConst):
        return ("true" if guard.value else "false"), ATOM
    if isinstance(guard, ir.BInput):
        return names[guard.name], ATOM
    if isinstance(guard, ir.BAtom):
        return compare_significand(names[guard.input], guard.op, guard.threshold, scale)
    if isinstance(guard, ir.BNot):
        return negate(_guard(guard.operand, names, scale))
    op = "&&" if isinstance(guard, ir.BAnd) else "||"
    return join([_guard(g, names, scale) for g in guard.operands], op)  # type: ignore[union-attr]


# ---------------------------------------------------------------- linear forms
def terms_text(terms: Sequence[tuple[int, str]]) -> str:
    """``10*iSa + 5*iPr - iCo`` from integer coefficients (none zero)."""
    text = ""
    for i, (coef, name) in enumerate(terms):
        magnitude = abs(coef)
        term = name if magnitude == 1 else f"{int_literal(magnitude)}*{name}"
        if i == 0:
            text = ("-" if coef < 0 else "") + term
        else:
            text += f" {'-' if coef < 0 else '+'} {term}"
    return text


def print_int_linear(const: Fraction, terms: Sequence[tuple[Fraction, str]]) -> str:
    """``const + Σ coefficient*variable`` over integer variables, in integer arithmetic.

    With integer coefficients and constant the value is exact. Otherwise everything is put over
    the least common denominator ``q`` and divided: ``(2*iSa + iPr) / 3``. UPPAAL's integer
    division truncates towards zero, so the result is the exact value truncated — once.
    """
    terms = [(Fraction(c), n) for c, n in terms if c != 0]
    q = math.lcm(const.denominator, *(c.denominator for c, _ in terms))
    ints = [(int(c * q), n) for c, n in terms]
    k = int(const * q)
    if not ints:
        return int_literal(math.trunc(const))
    text = terms_text(ints)
    if k:
        text += f" {'-' if k < 0 else '+'} {int_literal(abs(k))}"
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
    if not parts:
        return "0"
    negative, first = parts[0]
    text = ("-" if negative else "") + first
    for negative, part in parts[1:]:
        text += f" {'-' if negative else '+'} {part}"
    return text


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
            text = name if magnitude == 1 else f"{number_literal(magnitude)}*{name}"
        else:
            text = f"{name} / {double_literal(divisor)}" if magnitude == 1 else (
                f"{double_literal(magnitude)}*{name} / {double_literal(divisor)}")
        parts.append((coef < 0, text))
    if not parts:
        return number_literal(const)
    negative, first = parts[0]
    text = ("-" if negative else "") + first
    for negative, part in parts[1:]:
        text += f" {'-' if negative else '+'} {part}"
    if const:
        text += f" {'-' if const < 0 else '+'} {number_literal(abs(const))}"
    return text
