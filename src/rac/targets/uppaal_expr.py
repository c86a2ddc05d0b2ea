"""Expressions in UPPAAL syntax: literals, guards, linear forms and the ``.ra`` queries.

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

Queries (:class:`QueryPrinter`): *symbolic* queries (``A[]``, ``E<>``, ``E[]``, ``A<>``,
``-->``, ``control:``) read integers only — rewards through their integer mirrors, numeric
inputs through their significands, every constant scaled; *statistical* queries (``Pr``,
``E[..](max: ..)``, ``simulate``, learning) read the rewards' hybrid clocks directly.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from fractions import Fraction

from rac import ast, ir

__all__ = [
    "INT32_MAX",
    "NotRepresentable",
    "QueryError",
    "QueryPrinter",
    "Vocabulary",
    "compare_significand",
    "double_literal",
    "int_literal",
    "number_literal",
    "print_guard",
    "print_exact_sum",
    "print_int_linear",
    "print_real_linear",
    "reads_inputs",
]

INT32_MAX = 2_147_483_647


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
_OR, _AND, _CMP, _ATOM = 1, 2, 3, 4
_ADD, _MUL, _NEG, _NUM = 5, 6, 7, 8


def _paren(text: str, level: int, need: int) -> str:
    return f"({text})" if level < need else text


def _join(parts: Sequence[tuple[str, int]], op: str) -> tuple[str, int]:
    """``a && b && c`` or ``a || b || c`` (left-associative, so equal levels need no parentheses)."""
    level = _AND if op == "&&" else _OR
    texts = []
    for i, (text, own) in enumerate(parts):
        # `a || b` may stand left of `||`; anything of `imply`'s level stands in parentheses elsewhere.
        need = level + 1 if (own == level and (i > 0 or "imply" in text.split())) else level
        texts.append(_paren(text, own, need))
    return f" {op} ".join(texts), level


def _imply(left: tuple[str, int], right: tuple[str, int]) -> tuple[str, int]:
    return f"{_paren(left[0], left[1], _AND)} imply {_paren(right[0], right[1], _AND)}", _OR


def _not(operand: tuple[str, int]) -> tuple[str, int]:
    return "!" + _paren(operand[0], operand[1], _ATOM), _ATOM


# ---------------------------------------------------------------- significand comparisons
_FLIP = {"<": ">", "<=": ">=", ">": "<", ">=": "<=", "==": "==", "!=": "!="}


def _integer_bound(op: str, bound: Fraction) -> tuple[str, int] | bool:
    """``X op bound`` for an integer-valued ``X``, as ``X op' k`` with an integer ``k``, or a constant truth."""
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


def compare_significand(significand: str, op: str, threshold: Fraction, scale: int) -> tuple[str, int]:
    """``x op threshold`` for an input held as the integer significand ``x * scale``, exactly."""
    result = _integer_bound(op, threshold * scale)
    if isinstance(result, bool):
        return ("true" if result else "false"), _ATOM
    new_op, bound = result
    return f"{significand} {new_op} {int_literal(bound)}", _CMP


# ---------------------------------------------------------------- guards of the automaton
def print_guard(guard: ir.Guard, names: Mapping[str, str], scale: int) -> str:
    """A guard over the inputs; ``names`` maps each input to the UPPAAL expression holding it
    (a ``bool`` for boolean inputs, an integer significand for numeric ones)."""
    return _guard(guard, names, scale)[0]


def _guard(guard: ir.Guard, names: Mapping[str, str], scale: int) -> tuple[str, int]:
    if isinstance(guard, ir.BConst):
        return ("true" if guard.value else "false"), _ATOM
    if isinstance(guard, ir.BInput):
        return names[guard.name], _ATOM
    if isinstance(guard, ir.BAtom):
        return compare_significand(names[guard.input], guard.op, guard.threshold, scale)
    if isinstance(guard, ir.BNot):
        return _not(_guard(guard.operand, names, scale))
    op = "&&" if isinstance(guard, ir.BAnd) else "||"
    return _join([_guard(g, names, scale) for g in guard.operands], op)  # type: ignore[union-attr]


# ---------------------------------------------------------------- linear forms
def _terms_text(terms: Sequence[tuple[int, str]]) -> str:
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
    text = _terms_text(ints)
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


# ---------------------------------------------------------------- queries
@dataclass(frozen=True)
class Vocabulary:
    """The UPPAAL names of the automaton's vocabulary, for translating queries.

    ``mirrors`` and ``hybrids`` map each reward to its integer mirror and its hybrid clock;
    ``significands`` each numeric input to its ``int32_t`` global; ``bools`` each boolean input;
    ``locations`` each location to its UPPAAL name inside ``process``. ``time`` is the global
    clock (in time units of ``unit`` seconds); ``settled`` a global that is false exactly while
    the inputs are newer than the location (between reading them and taking the edge).
    """

    automaton: str
    process: str
    locations: Mapping[str, str]
    bools: Mapping[str, str]
    significands: Mapping[str, str]
    mirrors: Mapping[str, str]
    hybrids: Mapping[str, str]
    constants: Mapping[str, Fraction | bool]
    strategies: Mapping[str, str]
    scale: int
    unit: Fraction
    time: str
    settled: str
    model_functions: tuple[str, ...] = ()


#: A linear form of a query expression: constant plus coefficients of ("r"|"x"|"t", name).
_Var = tuple[str, str]


@dataclass
class _Lin:
    const: Fraction = Fraction(0)
    coefs: dict[_Var, Fraction] = field(default_factory=dict)

    def add(self, other: _Lin, sign: int = 1) -> _Lin:
        coefs = dict(self.coefs)
        for var, c in other.coefs.items():
            coefs[var] = coefs.get(var, Fraction(0)) + sign * c
        return _Lin(self.const + sign * other.const, {v: c for v, c in coefs.items() if c != 0})

    def scale(self, factor: Fraction) -> _Lin:
        if factor == 0:
            return _Lin()
        return _Lin(self.const * factor, {v: c * factor for v, c in self.coefs.items()})


SYMBOLIC, STATISTICAL = "symbolic", "statistical"


class QueryPrinter:
    """Translate the ``.ra`` queries into UPPAAL formulas over the emitted model.

    :meth:`formula` raises :class:`QueryError` with a message for the user when a query cannot be
    written over the model (a nonlinear comparison in a symbolic query, a scenario-model function).
    """

    def __init__(self, vocabulary: Vocabulary):
        self.v = vocabulary

    # ------------------------------------------------------------ whole queries
    def formula(self, query: ast.Query) -> str:
        """The query as one line of UPPAAL property syntax."""
        if isinstance(query, ast.PathQuery):
            box = query.quantifier in ("A[]", "E[]")
            text = f"{query.quantifier} {self._state(query.expr, SYMBOLIC, box)[0]}"
        elif isinstance(query, ast.LeadsToQuery):
            left = self._state(query.left, SYMBOLIC, False)[0]
            right = self._state(query.right, SYMBOLIC, False)[0]
            text = f"{left} --> {right}"
        elif isinstance(query, ast.ControlStrategy):
            body = self._state(query.expr, SYMBOLIC, query.goal == "A[]")[0]
            text = f"strategy {self._strategy(query.name)} = control: {query.goal} {body}"
        elif isinstance(query, ast.ProbabilityQuery):
            body = self._state(query.expr, STATISTICAL, query.path == "[]")[0]
            text = f"Pr[{self._bound(query.bound, query.runs)}]({query.path} {body})"
            if query.compare is not None:
                op, threshold = query.compare
                if op not in (">=", "<="):
                    raise QueryError(f"UPPAAL compares a probability with `>=` or `<=` only, not `{op}`")
                text += f" {op} {double_literal(self._constant(threshold, 'the probability threshold'))}"
        elif isinstance(query, ast.ExpectationQuery):
            text = (f"E[{self._bound(query.bound, query.runs)}]"
                    f"({query.aggregate}: {self._real(query.expr)[0]})")
        elif isinstance(query, ast.SimulateQuery):
            exprs = ", ".join(self._any(e) for e in query.exprs)
            text = f"simulate[{self._bound(query.bound, query.runs)}]{{{exprs}}}"
        elif isinstance(query, ast.LearnStrategy):
            discrete = ", ".join(self._discrete(e) for e in query.discrete)
            continuous = ", ".join(self._any(e) for e in query.continuous)
            body = self._state(query.expr, STATISTICAL, query.path == "[]")[0]
            text = (f"strategy {self._strategy(query.name)} = {query.optimise}({self._real(query.objective)[0]})"
                    f"[{self._bound(query.bound, None)}]{{{discrete}}}->{{{continuous}}}: {query.path} {body}")
        else:
            raise TypeError(f"not a query: {query!r}")
        under = getattr(query, "under", None)
        if under is not None:
            text += f" under {self._strategy(under)}"
        return text

    def _strategy(self, name: str) -> str:
        return self.v.strategies.get(name, name)

    def _bound(self, bound: ast.Bound, runs: ast.Expr | None) -> str:
        limit = self._constant(bound.limit, "a bound")
        if bound.kind == "time":
            units = limit / self.v.unit
            if units.denominator != 1:
                raise QueryError(f"the time bound {_short(limit)} s is not a whole number of time units "
                                 f"({_short(self.v.unit)} s)")
            text = "<=" + int_literal(units)
        else:
            if limit.denominator != 1 or limit < 0:
                raise QueryError(f"the step bound {_short(limit)} is not a whole number")
            text = "#<=" + int_literal(limit)
        if runs is not None:
            count = self._constant(runs, "the number of runs")
            if count.denominator != 1 or count <= 0:
                raise QueryError(f"the number of runs {_short(count)} is not a positive whole number")
            text += ";" + int_literal(count)
        return text

    def _constant(self, expr: ast.Expr, what: str) -> Fraction:
        lin = self._linear(expr)
        if lin is None or lin.coefs:
            raise QueryError(f"{what} must be a constant")
        return lin.const

    # ------------------------------------------------------------ state formulas
    def _state(self, expr: ast.Expr, mode: str, box: bool) -> tuple[str, int]:
        """A state formula; when it reads an input, states where the inputs are newer than the
        location (``settled`` false) are left out: ``settled imply p`` under ``[]``, else
        ``settled && p``."""
        text = self._bool(expr, mode)
        if not reads_inputs(expr, self.v):
            return text
        settled = (self.v.settled, _ATOM)
        return _imply(settled, text) if box else _join([settled, text], "&&")

    def _bool(self, expr: ast.Expr, mode: str) -> tuple[str, int]:
        v = self.v
        if isinstance(expr, ast.BoolLit):
            return ("true" if expr.value else "false"), _ATOM
        if isinstance(expr, ast.Name):
            name = expr.id
            if name in v.constants and isinstance(v.constants[name], bool):
                return ("true" if v.constants[name] else "false"), _ATOM
            if name in v.bools:
                return v.bools[name], _ATOM
            if name in v.locations:
                return f"{v.process}.{v.locations[name]}", _ATOM
            if name == "deadlock":
                return "deadlock", _ATOM
            raise QueryError(f"`{name}` is not a condition")
        if isinstance(expr, ast.Qualified):
            if expr.id == "location":
                return f"{v.process}.location", _ATOM
            if expr.id in v.locations:
                return f"{v.process}.{v.locations[expr.id]}", _ATOM
            raise QueryError(f"`{expr.scope}.{expr.id}` is not a location of `{v.automaton}`")
        if isinstance(expr, ast.Unary) and expr.op == "!":
            return _not(self._bool(expr.operand, mode))
        if isinstance(expr, ast.Binary):
            if expr.op in ("&&", "||"):
                return _join([self._bool(expr.left, mode), self._bool(expr.right, mode)], expr.op)
            if expr.op == "imply":
                return _imply(self._bool(expr.left, mode), self._bool(expr.right, mode))
            if expr.op in ast.COMPARISON_OPS:
                return self._comparison(expr, mode)
        if isinstance(expr, ast.Call):
            self._check_call(expr)
            if expr.func in ("collide", "offroad", "goal") and not expr.args:
                return f"{expr.func}()", _ATOM  # the whole model declares them (functions of integers)
        raise QueryError("this part of the query is not a condition")

    def _is_bool(self, expr: ast.Expr) -> bool:
        v = self.v
        if isinstance(expr, ast.BoolLit):
            return True
        if isinstance(expr, ast.Name):
            return (expr.id in v.bools or expr.id in v.locations or expr.id == "deadlock"
                    or isinstance(v.constants.get(expr.id), bool))
        if isinstance(expr, ast.Qualified):
            return expr.id != "location"
        if isinstance(expr, ast.Unary):
            return expr.op == "!"
        if isinstance(expr, ast.Binary):
            return expr.op in ast.LOGICAL_OPS or expr.op in ast.COMPARISON_OPS
        if isinstance(expr, ast.Call):
            return expr.func in ("collide", "offroad", "goal")
        return False

    def _comparison(self, expr: ast.Binary, mode: str) -> tuple[str, int]:
        if self._is_bool(expr.left) or self._is_bool(expr.right):
            left = _paren(*self._bool(expr.left, mode), _ATOM)
            right = _paren(*self._bool(expr.right, mode), _ATOM)
            return f"{left} {expr.op} {right}", _CMP
        left, right = self._linear(expr.left), self._linear(expr.right)
        if left is not None and right is not None:
            return self._linear_comparison(left.add(right, -1), expr.op, mode)
        if mode == SYMBOLIC:
            self._calls(expr)
            raise QueryError("a symbolic query can compare only linear expressions (sums of constant "
                             "multiples of rewards, numeric inputs or `time`)")
        return (f"{_paren(*self._real(expr.left), _ADD)} {expr.op} "
                f"{_paren(*self._real(expr.right), _ADD)}"), _CMP

    def _linear_comparison(self, diff: _Lin, op: str, mode: str) -> tuple[str, int]:
        """``diff op 0`` with integer coefficients; variables on the left, the constant on the right."""
        if not diff.coefs:
            return ("true" if ir.compare(diff.const, op, 0) else "false"), _ATOM
        kinds = {var[0] for var in diff.coefs}
        if mode == SYMBOLIC and "t" in kinds and len(kinds) > 1:
            raise QueryError("a symbolic query cannot compare `time` with rewards or inputs "
                             "(the clock would be mixed with integers)")
        scaled: list[tuple[Fraction, str]] = []
        integral = True
        for var, coef in diff.coefs.items():
            name, factor, is_int = self._variable(var, mode)
            scaled.append((coef * factor, name))
            integral = integral and is_int
        multiplier = math.lcm(*(c.denominator for c, _ in scaled))
        coefs = [(int(c * multiplier), n) for c, n in scaled]
        bound = -diff.const * multiplier
        if coefs[0][0] < 0:
            coefs = [(-c, n) for c, n in coefs]
            bound, op = -bound, _FLIP[op]
        lhs = _terms_text(coefs)
        if integral:
            result = _integer_bound(op, bound)
            if isinstance(result, bool):
                return ("true" if result else "false"), _ATOM
            op, whole = result
            return f"{lhs} {op} {int_literal(whole)}", _CMP
        if bound.denominator != 1 and mode == SYMBOLIC:
            raise QueryError(f"`time` is compared with {_short(bound / multiplier * self.v.unit)} s, "
                             "which is not a whole number of time units")
        return f"{lhs} {op} {number_literal(bound)}", _CMP

    def _variable(self, var: _Var, mode: str) -> tuple[str, Fraction, bool]:
        """(UPPAAL name, value of one unit of the name in the variable's own unit, integer-valued?)."""
        kind, name = var
        v = self.v
        if kind == "t":
            return v.time, v.unit, False
        if kind == "x":
            return v.significands[name], Fraction(1, v.scale), True
        if mode == SYMBOLIC:
            return v.mirrors[name], Fraction(1, v.scale), True
        return v.hybrids[name], Fraction(1), False

    # ------------------------------------------------------------ numbers
    def _linear(self, expr: ast.Expr) -> _Lin | None:
        """The linear form of a numeric expression, or None (nonlinear, calls, locations...)."""
        v = self.v
        if isinstance(expr, ast.Number):
            return _Lin(Fraction(expr.value))
        if isinstance(expr, ast.Name):
            name = expr.id
            if name in v.constants:
                value = v.constants[name]
                return None if isinstance(value, bool) else _Lin(Fraction(value))
            if name in v.significands:
                return _Lin(coefs={("x", name): Fraction(1)})
            if name in v.mirrors:
                return _Lin(coefs={("r", name): Fraction(1)})
            if name == "time":
                return _Lin(coefs={("t", "time"): Fraction(1)})
            if name in v.bools or name in v.locations or name == "deadlock":
                return None
            raise QueryError(f"`{name}` is not a name of the automaton `{v.automaton}` "
                             "(the automaton-alone model has no scenario-model names)")
        if isinstance(expr, ast.Unary) and expr.op == "-":
            inner = self._linear(expr.operand)
            return None if inner is None else inner.scale(Fraction(-1))
        if isinstance(expr, ast.Binary) and expr.op in ast.ARITHMETIC_OPS:
            left, right = self._linear(expr.left), self._linear(expr.right)
            if left is None or right is None:
                return None
            if expr.op in ("+", "-"):
                return left.add(right, 1 if expr.op == "+" else -1)
            if expr.op == "*":
                if not left.coefs:
                    return right.scale(left.const)
                if not right.coefs:
                    return left.scale(right.const)
                return None
            if right.coefs or right.const == 0:
                return None
            return left.scale(1 / right.const)
        return None

    def _real(self, expr: ast.Expr) -> tuple[str, int]:
        """A numeric expression as a double (statistical queries): rewards as hybrid clocks."""
        lin = self._linear(expr)
        if lin is not None:
            terms = []
            for (kind, name), coef in lin.coefs.items():
                if kind == "r":
                    terms.append((coef, self.v.hybrids[name], 1))
                elif kind == "x":
                    terms.append((coef, self.v.significands[name], self.v.scale))
                else:
                    unit = self.v.unit
                    terms.append((coef * unit.numerator, self.v.time, unit.denominator))
            text = print_real_linear(lin.const, terms)
            if len(terms) + bool(lin.const) > 1:
                return text, _ADD
            level = _NEG if text.startswith("-") else _NUM
            return text, (min(level, _MUL) if ("*" in text or "/" in text) else level)
        if isinstance(expr, ast.Unary) and expr.op == "-":
            inner = self._real(expr.operand)
            return "-" + _paren(inner[0], inner[1], _NEG), _NEG
        if isinstance(expr, ast.Binary) and expr.op in ast.ARITHMETIC_OPS:
            level = _ADD if expr.op in ("+", "-") else _MUL
            left, right = self._real(expr.left), self._real(expr.right)
            return f"{_paren(left[0], left[1], level)} {expr.op} {_paren(right[0], right[1], level + 1)}", level
        if isinstance(expr, ast.Call):
            self._check_call(expr)
            func = "fabs" if expr.func == "abs" else expr.func  # UPPAAL's abs() takes integers only
            return f"{func}({', '.join(self._real(a)[0] for a in expr.args)})", _NUM
        if isinstance(expr, ast.Qualified) and expr.id == "location":
            return f"{self.v.process}.location", _NUM
        raise QueryError("this part of the query is not a number")

    def _any(self, expr: ast.Expr) -> str:
        """A simulated or observed expression: a condition or a (double) number."""
        if self._is_bool(expr):
            return self._bool(expr, STATISTICAL)[0]
        return self._real(expr)[0]

    def _discrete(self, expr: ast.Expr) -> str:
        """A discrete observation of a learning query: an integer expression (mirrors, significands)."""
        if self._is_bool(expr):
            return self._bool(expr, SYMBOLIC)[0]
        if isinstance(expr, ast.Qualified) and expr.id == "location":
            return f"{self.v.process}.location"
        lin = self._linear(expr)
        if lin is None or any(kind == "t" for kind, _ in lin.coefs):
            raise QueryError("a discrete observation must be linear in rewards and inputs "
                             "(it is observed as integers: mirrors and significands)")
        terms = [(coef, self.v.mirrors[name] if kind == "r" else self.v.significands[name])
                 for (kind, name), coef in lin.coefs.items()]
        if any(c.denominator != 1 for c, _ in terms) or (lin.const * self.v.scale).denominator != 1:
            raise QueryError("a discrete observation needs whole coefficients")
        return print_int_linear(lin.const * self.v.scale, terms)

    # ------------------------------------------------------------ calls
    def _check_call(self, expr: ast.Call) -> None:
        if expr.func in self.v.model_functions:
            raise QueryError(f"`{expr.func}()` is a function of the scenario model, which the "
                             "automaton-alone UPPAAL model does not contain")

    def _calls(self, expr: ast.Expr) -> None:
        """Report a scenario-model function anywhere in ``expr`` before any other problem."""
        for node in _walk(expr):
            if isinstance(node, ast.Call):
                self._check_call(node)


def _walk(expr: ast.Expr):
    yield expr
    if isinstance(expr, ast.Unary):
        yield from _walk(expr.operand)
    elif isinstance(expr, ast.Binary):
        yield from _walk(expr.left)
        yield from _walk(expr.right)
    elif isinstance(expr, ast.Call):
        for arg in expr.args:
            yield from _walk(arg)


def reads_inputs(expr: ast.Expr, vocabulary: Vocabulary) -> bool:
    """Whether an expression mentions an input (boolean or numeric)."""
    return any(isinstance(node, ast.Name) and (node.id in vocabulary.bools or node.id in vocabulary.significands)
               for node in _walk(expr))


def query_exprs(query: ast.Query) -> list[ast.Expr]:
    """Every expression of a query, bounds included."""
    found: list[ast.Expr] = []
    for name in ("expr", "left", "right", "objective"):
        value = getattr(query, name, None)
        if value is not None:
            found.append(value)
    for name in ("exprs", "discrete", "continuous"):
        found.extend(getattr(query, name, ()))
    bound = getattr(query, "bound", None)
    if bound is not None:
        found.append(bound.limit)
    return found


def time_constants(query: ast.Query, linear: Callable[[ast.Expr], object]) -> list[Fraction]:
    """Durations in seconds a query needs as whole time units: its time bound, and the constant
    of every comparison of ``time`` alone (``time >= 30`` needs 30 s)."""
    found: list[Fraction] = []
    def linear_or_none(expr: ast.Expr) -> object:
        try:
            return linear(expr)
        except QueryError:  # reported when the query itself is printed
            return None

    bound = getattr(query, "bound", None)
    if bound is not None and bound.kind == "time":
        value = linear_or_none(bound.limit)
        if isinstance(value, _Lin) and not value.coefs:
            found.append(value.const)
    for expr in query_exprs(query):
        for node in _walk(expr):
            if isinstance(node, ast.Binary) and node.op in ast.COMPARISON_OPS:
                left, right = linear_or_none(node.left), linear_or_none(node.right)
                if isinstance(left, _Lin) and isinstance(right, _Lin):
                    diff = left.add(right, -1)
                    if set(diff.coefs) == {("t", "time")}:
                        found.append(-diff.const / diff.coefs[("t", "time")])
    return found


def _short(value: Fraction) -> str:
    if value.denominator == 1:
        return str(value.numerator)
    text = f"{float(value):.6g}"
    return text if Fraction(text) == value else f"{value.numerator}/{value.denominator}"

