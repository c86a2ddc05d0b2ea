"""Compositional answers: a query over the automaton's own state decided by the automaton alone.

``A[] p`` (and ``E<> p`` as ``!A[] !p``) over locations, inputs and rewards is a property of the
reward automaton for every input sequence within its ``assume``s
(:func:`rac.check.analysis.invariant.decide_invariant`). It carries over to the product of model
and automaton when every run of the model gives the automaton such a sequence and the product
computes what the analysis assumes (:func:`transfer`):

- the bindings satisfy ``assume`` at every sample: proved statically from the binding expressions
  and the model functions' documented relations (``collide()`` is ``mindist() < collision_distance``;
  under ``collision sticky``, or an earlier collision), exactly, with a margin against the model's
  double rounding; where that proof fails, checked on every state of the explored model;
- the numeric inputs stay within their declared ranges, or the automaton cannot tell a value
  beyond a bound from the bound (every threshold over the input lies strictly inside the range and
  no rate or update reads it), or the explored model shows that they do;
- the integer mirrors of the rewards are exact (whole multiples of the scale) and stay in int32.

Rewards never steer the automaton (guards read inputs only, E0202), so nothing else can differ.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from rac import ir
from rac.check.analysis.affine import arithmetic_inputs
from rac.check.analysis.invariant import PROVED, Invariant, decide_invariant, over_automaton
from rac.check.analysis.priority import check_ranges
from rac.core.diagnostics import Severity
from rac.engine.evaluate import EvaluationError
from rac.ir import expr as ie
from rac.model.sample import GraphColumn
from rac.runtime.semantics import mirror_accrual, mirror_update
from rac.verify.context import Context, UnknownVerdict

__all__ = ["Transfer", "prove_valid", "transfer"]

#: The relative margin a static proof leaves against the model's double rounding.
MARGIN = Fraction(1, 10**9)
#: The most atoms a static proof enumerates truth values of.
MAX_ATOMS = 16


@dataclass(frozen=True)
class Transfer:
    """Whether the automaton's verdicts hold in the model: ``how`` (when they do) or ``why_not``."""

    holds: bool
    how: str = ""
    why_not: str = ""


# ---------------------------------------------------------------- formulas over the model's values
# A formula is ("const", bool) | ("atom", key) | ("lin", terms, const, op) | ("not", f) | ("and", fs)
# | ("or", fs); "lin" means sum(c * x for x, c in terms) + const <op> 0 over opaque real terms.
Formula = tuple


def _affine(expr: ie.Expr) -> tuple[dict[object, Fraction], Fraction]:
    """``expr`` as coefficients of opaque terms plus a constant (calls, ``prev`` and products of
    varying values are terms of their own)."""
    if isinstance(expr, ie.Const) and not isinstance(expr.value, bool):
        return {}, Fraction(expr.value)
    if isinstance(expr, ie.Ref) and expr.kind is ie.RefKind.MODEL and expr.model.kind == "setting" \
            and expr.value is not None:
        return {}, Fraction(expr.value)
    if isinstance(expr, ie.Unary) and expr.op == "-":
        terms, const = _affine(expr.operand)
        return {k: -c for k, c in terms.items()}, -const
    if isinstance(expr, ie.Binary) and expr.op in ("+", "-", "*", "/"):
        left, right = _affine(expr.left), _affine(expr.right)
        if expr.op in ("+", "-"):
            sign = 1 if expr.op == "+" else -1
            terms = dict(left[0])
            for k, c in right[0].items():
                terms[k] = terms.get(k, Fraction(0)) + sign * c
            return {k: c for k, c in terms.items() if c}, left[1] + sign * right[1]
        if expr.op == "*" and not left[0]:
            return {k: left[1] * c for k, c in right[0].items()}, left[1] * right[1]
        if expr.op == "*" and not right[0]:
            return {k: right[1] * c for k, c in left[0].items()}, left[1] * right[1]
        if expr.op == "/" and not right[0] and right[1] != 0:
            return {k: c / right[1] for k, c in left[0].items()}, left[1] / right[1]
    return {expr: Fraction(1)}, Fraction(0)


def _formula(expr: ie.Expr, ctx: Context) -> Formula:
    """A boolean binding expression as a :data:`Formula`, the model's functions by their relations."""
    if isinstance(expr, ie.Const) and isinstance(expr.value, bool):
        return ("const", expr.value)
    if isinstance(expr, ie.Unary) and expr.op == "!":
        return ("not", _formula(expr.operand, ctx))
    if isinstance(expr, ie.Binary) and expr.op in ("&&", "||", "imply"):
        left, right = _formula(expr.left, ctx), _formula(expr.right, ctx)
        if expr.op == "&&":
            return ("and", (left, right))
        return ("or", (left, right) if expr.op == "||" else (("not", left), right))
    if isinstance(expr, ie.Call) and expr.function.kind == "model" and expr.name == "collide":
        td = Fraction(ctx.data.td, ctx.data.scale)
        close: Formula = ("lin", ((ie.call("mindist"), Fraction(1)),), -td, "<")
        # collision sticky: or at an earlier sample (the run's crashed flag, nothing else known of it)
        return ("or", (close, ("atom", "crashed"))) if ctx.data.sticky else close
    if isinstance(expr, ie.Compare) and expr.left.type == ie.NUM and expr.right.type == ie.NUM:
        left, right = _affine(expr.left), _affine(expr.right)
        terms = dict(left[0])
        for k, c in right[0].items():
            terms[k] = terms.get(k, Fraction(0)) - c
        return ("lin", tuple((k, c) for k, c in terms.items() if c), left[1] - right[1], expr.op)
    if isinstance(expr, ie.Compare) and expr.op in ("==", "!="):
        a, b = _formula(expr.left, ctx), _formula(expr.right, ctx)
        same: Formula = ("or", (("and", (a, b)), ("and", (("not", a), ("not", b)))))
        return same if expr.op == "==" else ("not", same)
    return ("atom", expr)  # goal(), offroad(), ...: a truth value nothing relates


def _substituted(guard: ir.Guard, ctx: Context) -> Formula:
    """``assume`` with every boolean input replaced by its binding; a numeric input's atom stays an
    atom over the input's value (its truncated significand, related to nothing)."""
    fold: ir.GuardFold[Formula] = ir.GuardFold(
        const=lambda value: ("const", value),
        boolean=lambda leaf: _formula(_binding(ctx, leaf.name), ctx),
        atom=lambda leaf: ("lin", ((("input", leaf.input), Fraction(1)),), -leaf.threshold, leaf.op),
        negate=lambda inner: ("not", inner),
        conjoin=lambda parts: ("and", parts),
        disjoin=lambda parts: ("or", parts))
    return fold(guard)


def _binding(ctx: Context, name: str) -> ie.Expr:
    assert ctx.automaton.model is not None
    return next(b.expr for b in ctx.automaton.model.bindings if b.input == name)


def _atoms(formula: Formula) -> Iterator[Formula]:
    if formula[0] in ("atom", "lin"):
        yield formula
    elif formula[0] == "not":
        yield from _atoms(formula[1])
    elif formula[0] in ("and", "or"):
        for part in formula[1]:
            yield from _atoms(part)


def _value(formula: Formula, truth: dict[Formula, bool]) -> bool:
    kind = formula[0]
    if kind == "const":
        return bool(formula[1])
    if kind in ("atom", "lin"):
        return truth[formula]
    if kind == "not":
        return not _value(formula[1], truth)
    parts = [_value(p, truth) for p in formula[1]]
    return all(parts) if kind == "and" else any(parts)


_NEGATED = {"<": ">=", "<=": ">", ">": "<=", ">=": "<", "==": "!=", "!=": "=="}


def _constraints(atom: Formula, true: bool) -> list[tuple[dict[object, Fraction], Fraction, bool]]:
    """``atom`` (or its negation) as constraints ``sum + const < 0`` (strict) or ``<= 0``, relaxed by
    :data:`MARGIN` so that a proof survives the model's rounding; ``!=`` constrains nothing."""
    _, terms, const, op = atom
    op = op if true else _NEGATED[op]
    coefficients = dict(terms)
    slack = MARGIN * (1 + abs(const) + sum((abs(c) for c in coefficients.values()), Fraction(0)))
    negated = {k: -c for k, c in coefficients.items()}
    if op == "<":
        return [(coefficients, const - slack, True)]
    if op == "<=":
        return [(coefficients, const - slack, False)]
    if op == ">":
        return [(negated, -const - slack, True)]
    if op == ">=":
        return [(negated, -const - slack, False)]
    if op == "==":
        return [(coefficients, const - slack, False), (negated, -const - slack, False)]
    return []


def _feasible(rows: list[tuple[dict[object, Fraction], Fraction, bool]]) -> bool:
    """Whether the constraints have a real solution (Fourier-Motzkin elimination, exact)."""
    while True:
        variables = {k for terms, _, _ in rows for k in terms}
        for terms, const, strict in rows:
            if not terms and (const > 0 or (strict and const == 0)):
                return False
        if not variables:
            return True
        x = next(iter(variables))
        upper = [r for r in rows if r[0].get(x, 0) > 0]
        lower = [r for r in rows if r[0].get(x, 0) < 0]
        rest = [r for r in rows if x not in r[0]]
        for (a, ca, sa), (b, cb, sb) in itertools.product(upper, lower):
            fa, fb = 1 / a[x], -1 / b[x]
            terms = {k: a.get(k, Fraction(0)) * fa + b.get(k, Fraction(0)) * fb for k in set(a) | set(b) if k != x}
            rest.append(({k: c for k, c in terms.items() if c}, ca * fa + cb * fb, sa or sb))
        rows = rest


def prove_valid(formula: Formula) -> tuple[bool, dict[Formula, bool] | None]:
    """Whether ``formula`` holds for every value of its atoms that the linear relations allow; else
    an assignment of its atoms that falsifies it (None: too many atoms to try)."""
    atoms = list(dict.fromkeys(_atoms(formula)))
    if len(atoms) > MAX_ATOMS:
        return False, None
    for values in itertools.product((False, True), repeat=len(atoms)):
        truth = dict(zip(atoms, values))
        if _value(formula, truth):
            continue
        rows = [row for atom, true in truth.items() if atom[0] == "lin" for row in _constraints(atom, true)]
        if _feasible(rows):
            return False, truth
    return True, None


# ---------------------------------------------------------------- the conditions
def _exact_mirrors(automaton: ir.Automaton, scale: int) -> str | None:
    """Why the reward mirrors are not exact (None: they are)."""
    for location in automaton.locations:
        for reward, rate in zip(automaton.rewards, location.rates):
            constant, terms = mirror_accrual(rate, automaton.period, scale)
            if terms or constant.denominator != 1:
                return f"`{reward}`'s rate in `{location.name}` is not a whole number of significands per sample"
    updates = [u for e in automaton.all_edges() for u in e.updates] + \
              [u for c in automaton.end_clauses for u in c.updates]
    for update in updates:
        constant, terms = mirror_update(update.value, scale)
        if constant.denominator != 1 or any(c.denominator != 1 for c, _ in terms):
            return f"an update of `{update.reward}` is truncated in the integer mirrors"
    return None


def _input_ranges(automaton: ir.Automaton, expr: ie.Expr) -> list[ir.Input]:
    """The numeric inputs whose values beyond their range the automaton or the query could tell apart
    from the bounds (the others need no range check)."""
    arithmetic = set(arithmetic_inputs(automaton))
    thresholds: dict[str, set[Fraction]] = {}
    for guard in [automaton.assume, *(e.guard for e in automaton.all_edges()),
                  *(c.guard for c in automaton.end_clauses)]:
        for leaf in ir.guard_leaves(guard):
            if isinstance(leaf, ir.BAtom):
                thresholds.setdefault(leaf.input, set()).add(leaf.threshold)
    for node in ie.walk(expr):
        if isinstance(node, ie.Compare) and node.linear is not None:
            for ref, coefficient in node.linear.terms:
                if ref.kind is ie.RefKind.INPUT:
                    if len(node.linear.terms) > 1:
                        arithmetic.add(ref.name)
                    else:
                        thresholds.setdefault(ref.name, set()).add(-node.linear.const / coefficient)
    tell: list[ir.Input] = []
    for item in automaton.numeric_inputs:
        assert item.low is not None and item.high is not None
        inside = all(item.low < t < item.high for t in thresholds.get(item.name, ()))
        if item.kind == "int" or item.name in arithmetic or not inside:
            tell.append(item)
    return tell


def transfer(ctx: Context, expr: ie.Expr) -> Transfer:
    """Whether the automaton's verdict on ``A[] expr`` within the horizon is the model's."""
    automaton = dataclasses.replace(ctx.automaton, horizon=ctx.horizon_samples * ctx.automaton.period)
    model = automaton.model
    assert model is not None
    scale = ctx.data.scale
    why = _exact_mirrors(automaton, scale)
    if why is not None:
        return Transfer(False, why_not=why)
    if any(d.severity is Severity.ERROR for d in check_ranges(automaton, model.base, model.exponent)):
        return Transfer(False, why_not="a reward's mirror can leave int32 within the horizon")
    checked: list[str] = []
    ranges = _input_ranges(automaton, expr)
    formula = _substituted(automaton.assume, ctx)
    proved, _ = prove_valid(formula)
    if automaton.assume == ir.TRUE:
        how = "nothing is assumed of the inputs"
    elif proved:
        how = "the bindings satisfy `assume` by their definitions"
    else:
        checked.append("`assume`")
        how = ""
    conditions = []
    if not proved:
        conditions.append(_assume_expr(automaton.assume, ctx))
    for item in ranges:
        assert item.low is not None and item.high is not None
        if item.kind == "int" or (item.low * scale).denominator != 1 or (item.high * scale).denominator != 1:
            return Transfer(False, why_not=f"`{item.name}`'s range is not whole significands")
        value = _binding(ctx, item.name)
        conditions.append(ie.Binary("&&", ie.Compare(">=", value, ie.Const(item.low)),
                                    ie.Compare("<=", value, ie.Const(item.high))))
        checked.append(f"`{item.name}` in [{item.low}, {item.high}]")
    if conditions:
        if any(c is None for c in conditions):
            return Transfer(False, why_not="`assume` reads a numeric input: it is not proved from the bindings")
        try:
            graph = ctx.graph(False)
            holds = np.ones(graph.n_states, dtype=bool)
            for condition in conditions:
                assert condition is not None
                holds &= ctx.label(graph, condition)
        except (UnknownVerdict, EvaluationError) as exc:
            return Transfer(False, why_not=f"{' and '.join(checked)} could not be checked on the model ({exc})")
        later = graph.states[:, GraphColumn.K] >= 1  # the inputs are read from the first sample on
        bad = int((~holds & later).sum())
        if bad:
            return Transfer(False, why_not=f"{' and '.join(checked)} fails in {bad:,} states of the model")
        how = (how + "; " if how else "") + f"{' and '.join(checked)} checked on all {graph.n_states:,} " \
                                            "states of the model"
    return Transfer(True, how=how + "; the reward mirrors are exact")


def _assume_expr(guard: ir.Guard, ctx: Context) -> ie.Expr | None:
    """``assume`` over the model's values (None when it reads a numeric input)."""
    def chain(op: str) -> Callable[[tuple[ie.Expr | None, ...]], ie.Expr | None]:
        def combine(parts: tuple[ie.Expr | None, ...]) -> ie.Expr | None:
            if any(p is None for p in parts):
                return None
            result = parts[0]
            for part in parts[1:]:
                assert result is not None and part is not None
                result = ie.Binary(op, result, part)
            return result
        return combine

    fold: ir.GuardFold[ie.Expr | None] = ir.GuardFold(
        const=ie.Const,
        boolean=lambda leaf: _binding(ctx, leaf.name),
        atom=lambda leaf: None,
        negate=lambda inner: None if inner is None else ie.Unary("!", inner),
        conjoin=chain("&&"),
        disjoin=chain("||"))
    return fold(guard)


def decide(ctx: Context, quantifier: str, expr: ie.Expr) -> tuple[bool | None, str]:
    """``A[] expr`` or ``E<> expr`` decided on the automaton alone: (holds, what it means), or
    (None, why not)."""
    if quantifier not in ("A[]", "E<>") or not over_automaton(expr):
        return None, "the query reads more than the automaton's state"
    target = expr if quantifier == "A[]" else ie.Unary("!", expr)
    invariant: Invariant = decide_invariant(ctx.automaton, target, ctx.horizon_samples)
    if invariant.status != PROVED:
        return None, invariant.reason
    carried = transfer(ctx, target)
    if not carried.holds:
        return None, f"the automaton proves it, but the proof does not carry over to the model: {carried.why_not}"
    what = "holds" if quantifier == "A[]" else "is never reached"
    return quantifier == "A[]", (f"{what} for every input sequence within the assumptions, so in this model "
                                 f"({carried.how})")
