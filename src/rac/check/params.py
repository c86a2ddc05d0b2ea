"""The parameters of a file (`param`): synthesising their values, and where they enter non-linearly
(docs/checks.md, "Parameters").

- :func:`synthesise_parameters` gives the automaton at the synthesised values, or why there are
  none (E0406, E0407), as one :class:`ParameterOutcome`: the compiler's parameter stage.
- :func:`nonlinear_use`: the synthesis is exact only where every value that depends on a parameter
  is affine in the parameters. The walk is over the AST, before any value is computed, so the
  verdict is a proof rather than a sample: ``100 / P`` or ``P * Q`` is refused whatever values the
  bounds allow.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
from typing import get_args

from rac import ir
from rac.check.analysis import analyse_automaton
from rac.check.analysis.behaviour import input_space
from rac.check.analysis.discount import Discount
from rac.check.analysis.parametric import LOOPHOLES, loophole_values
from rac.check.analysis.piecewise import Interval, intersect
from rac.check.analysis.synthesis import Synthesised, Unfinished, Unresolved, risk_values, synthesise, unsupported
from rac.check.analysis.weights import Unsupported, synthesise_region
from rac.check.resolve import Resolver
from rac.core.diagnostics import Diagnostic, Fact, Note, error, short_number
from rac.core.numbers import exact_decimal, exact_text
from rac.core.source import Span
from rac.ir.significands import representation
from rac.lang import ast

__all__ = ["ParameterOutcome", "nonlinear_use", "synthesise_parameters"]


@dataclass(frozen=True)
class ParameterOutcome:
    """What the parameter stage found: the ``automaton`` at the synthesised values (None when there
    are none), the ``diagnostics`` saying why not, what was ``synthesised`` (the values, their set)
    and the ``facts`` stating it."""

    automaton: ir.Automaton | None
    diagnostics: tuple[Diagnostic, ...]
    synthesised: Synthesised | None
    facts: tuple[Fact, ...]


def synthesise_parameters(node: ast.Automaton, parameters: tuple[ir.Parameter, ...], *,
                          discount: Discount | None = None) -> ParameterOutcome:
    """The automaton at the synthesised values of its parameters (one: the least value; several
    weights: the lexicographically least integer point), with the diagnostics and facts that say
    what was found (:class:`ParameterOutcome`). ``discount``: the file is also checked for the return
    discounted by it (``rac check --discount``), whose P2 the synthesis searches too where the discounted
    search goes; where it does not, the facts say so instead of claiming every check over the set."""
    facts: list[Fact] = []
    claim = _Claim(discount is not None, discount)
    place = nonlinear_use(node, {p.name for p in parameters})
    at_low = Resolver(node).run()
    if place is None and at_low is not None and input_space(at_low)[0] is None:
        # Too many input classes (E0306): the searches need the classes, so there is nothing to search;
        # the analysis stage reports E0306 on the file at the low bounds, as it does without a `param`.
        return ParameterOutcome(at_low, (), None, ())
    if place is not None:
        name, span, how = place
        found: tuple[ir.Automaton | None, list[Diagnostic], Synthesised | None] = (
            None, [error("E0407", f"not yet: parameter `{name}` cannot be synthesised here: {how}", span,
                         hints=[f"write `const {name} = ...` instead"])], None)
    elif len(parameters) == 1:
        found = _synthesised(node, parameters[0], facts, claim)
    else:
        found = _synthesised_weights(node, parameters, facts, claim)
    automaton, diagnostics, synthesised = found
    return ParameterOutcome(automaton, tuple(diagnostics), synthesised, tuple(facts))


@dataclass(frozen=True)
class _Claim:
    """What a synthesised set is claimed to satisfy: every check, or, for a file checked for a discounted
    return too (``discounted``), every check but that return's P2 where the synthesis did not search it
    (``search``: the discount to search, None when it is not searched: a discounted search that does not
    go), which is then checked at the chosen value only."""

    discounted: bool
    search: Discount | None = None

    def unsearched(self) -> _Claim:
        """The claim when the discounted return's P2 is not searched after all."""
        return dataclasses.replace(self, search=None)

    @property
    def holds(self) -> str:
        return ("every check but P2 of the discounted return holds" if self.discounted and self.search is None
                else "every check holds")

    @property
    def after(self) -> str:
        """What a sentence ends with."""
        if not self.discounted:
            return ""
        if self.search is None:
            return "; P2 of the discounted return (`--discount`) is checked at that value only"
        return "; P2 of the discounted return (`--discount`) is searched too"


def _synthesised_weights(node: ast.Automaton, parameters: tuple[ir.Parameter, ...], facts: list[Fact],
                         claim: _Claim) -> tuple[ir.Automaton | None, list[Diagnostic], Synthesised | None]:
    """Several parameters, weights of the objective: the automaton at the lexicographically least integer
    point of the exact polyhedron where every check holds, or None and why there is none."""
    names = [p.name for p in parameters]
    listed = ", ".join(names)

    def resolve(point: tuple[Fraction, ...]) -> ir.Automaton | None:
        return Resolver(node, dict(zip(names, point))).run()

    low = resolve(tuple(p.low for p in parameters))
    searched = [] if low is None else [r for r in low.requirements
                                       if (r.check == "risk" and r.bound is not None) or r.check in LOOPHOLES]
    if searched:
        # The polyhedron's cuts are P1's and P2's; a requirement compares two maxima over runs (p*'s
        # ratio, a loophole's gap), so where it holds need not be convex, nor found by cutting planes:
        # claiming the region would prove what was never checked.
        required = ", ".join(f"`{_requirement_text(r)}`" for r in searched)
        return None, [error("E0407", f"not yet: parameters {listed} cannot be synthesised together under "
                            f"{required}: where it holds need not be a convex set of weights",
                            parameters[0].span, notes=[f"the parameters synthesised together: {listed}"],
                            hints=["synthesise one weight at a time (the others `const`), or write the "
                                   "values as `const`"])], None
    try:
        try:
            region = synthesise_region(resolve, parameters, claim.search)
        except Unfinished:
            if claim.search is None:
                raise
            claim = claim.unsearched()  # the discounted search does not go: as in _synthesised
            region = synthesise_region(resolve, parameters)
    except Unsupported as where:
        name = where.name
        span = next(p.span for p in parameters if p.name == name)
        return None, [error("E0407", f"not yet: parameter `{name}` cannot be synthesised here: with several "
                            f"parameters, each must be a weight of the objective only, and it appears in "
                            f"{where.where}", span,
                            notes=[f"the parameters synthesised together: {listed}"],
                            hints=[f"write `const {name} = ...`, or synthesise it alone"])], None
    except Unfinished as stop:
        return None, [error("E0407", f"not yet: parameters {listed} cannot be synthesised here: the worst-run "
                            f"search stopped: {stop.reason}", parameters[0].span,
                            hints=["write the values as `const`"])], None
    bounds = _bounds_text(parameters)
    if region.point is None:
        witness = resolve(region.witness)
        assert witness is not None
        failing = [d for d in analyse_automaton(witness, []) if d.is_error]
        at = ", ".join(f"{n} = {short_number(x)}" for n, x in zip(names, region.witness))
        return None, [error("E0406", f"no values of parameters {listed} ({bounds}) pass every check",
                            parameters[0].span, notes=[*region.cuts, f"the checks at {at} follow"],
                            hints=["widen the parameters' bounds, or change what they cannot compensate"]),
                      *failing], None
    point = region.point
    chosen = ", ".join(f"{n} = {short_number(x)}" for n, x in zip(names, point))
    first = names[region.order[0]]
    how = (f"the lexicographically least integer weights, `{first}` first" if region.integer
           else f"the lexicographically least values, `{first}` first (no integer point)")
    inequalities = tuple(region.describe())
    if inequalities:
        sentence = (f"synthesised: {claim.holds} exactly where {' and '.join(inequalities)} ({bounds}); "
                    f"checked with {chosen}, {how}{claim.after}")
    else:
        sentence = f"synthesised: {claim.holds} for all values ({bounds}); checked with {chosen}, {how}{claim.after}"
    facts.append(Fact("synthesis", sentence))
    shown = ", ".join("(" + ", ".join(_readable(x) for x in v) + ")" for v in region.vertices[:8])
    more = f" and {len(region.vertices) - 8} more" if len(region.vertices) > 8 else ""
    vertices = (f"the set of ({listed}) is one point, checked: {shown}" if len(region.vertices) == 1 else
                f"the set of ({listed}) has {len(region.vertices)} vertices, each checked: {shown}{more}")
    facts.append(Fact("synthesis", vertices))
    return resolve(point), [], Synthesised(tuple(zip(names, point)), inequalities, sentence, (vertices,))


def _synthesised(node: ast.Automaton, parameter: ir.Parameter, facts: list[Fact], claim: _Claim
                 ) -> tuple[ir.Automaton | None, list[Diagnostic], Synthesised | None]:
    """The automaton at the least value of its parameter for which every check holds (the fact saying
    so goes to ``facts``), or None and why there is none (E0406 and the checks failing at the value
    that shows it, or E0407 where the search cannot be exact)."""
    name = parameter.name

    def resolve(value: Fraction) -> ir.Automaton | None:
        return Resolver(node, {name: value}).run()

    low, high = resolve(parameter.low), resolve(parameter.high)
    if low is None or high is None:
        return None, [_fails_at(node, parameter, parameter.low if low is None else parameter.high)], None
    reason = unsupported(low, high)
    searched = [r for r in low.requirements if (r.check == "risk" and r.bound is not None) or r.check in LOOPHOLES]
    #: each searched requirement with the values where it holds (in the order the file gives them)
    holding: list[tuple[ir.Requirement, list[Interval]]] = []
    allowed: list[Interval] | None = None
    if reason is None:
        try:
            try:
                result = synthesise(resolve, parameter, claim.search)
            except Unfinished:
                if claim.search is None:
                    raise
                # the discounted search does not go (an update that scales a reward, a long horizon): the set
                # of the other checks, and the discounted P2 at its least value only, as the claim then says
                claim = claim.unsearched()
                result = synthesise(resolve, parameter)
            if searched and not result.empty:
                assert result.low is not None and result.high is not None
                allowed = [Interval(result.low.value, result.high.value, result.low.open, result.high.open)]
                loopholes = (loophole_values(resolve, parameter, [r.check for r in searched])
                             if any(r.check in LOOPHOLES for r in searched) else {})
                for requirement in searched:
                    if requirement.check == "risk":
                        assert requirement.bound is not None
                        values = risk_values(resolve, parameter, requirement.bound)
                    else:
                        values = loopholes[requirement.check]
                    holding.append((requirement, values))
                    allowed = intersect(allowed, values)
        except Unresolved as where:
            return None, [_fails_at(node, parameter, where.value)], None
        except Unfinished as stop:
            reason = (f"under {', '.join(f'`{_requirement_text(r)}`' for r in searched)}: {stop.reason}"
                      if allowed is not None else f"the worst-run search stopped: {stop.reason}")
        except ValueError as why:  # piecewise.convex: the returns are not piecewise affine with few pieces
            reason = f"under `require risk`: {why}"
    if reason is not None:
        return None, [error("E0407", f"not yet: parameter `{name}` cannot be synthesised here: {reason}",
                            parameter.span, hints=[f"write `const {name} = ...` instead"])], None
    least = result.least
    if allowed is not None:
        least = allowed[0].low if allowed and not allowed[0].low_open else None
    required_text = "; ".join(f"`{_requirement_text(r)}` holds for "
                              f"{f'{name} in {_intervals_text(values)}' if values else 'none of them'}"
                              for r, values in holding)
    if least is None:
        # the value whose checks show why: the least the requirements allow (its end is open), else
        # the synthesis' own witness
        shown = allowed[0].low if allowed else result.witness
        # a value the significands hold exactly when one is as near: the checks at 82/3 showed E0801 (its
        # denominator in the UPPAAL update), an error of rac's choice of value, not of any the user could write
        if allowed:
            shown, _ = _held_exactly(resolve, name, shown, allowed[0])
        elif not result.empty and result.low is not None and result.high is not None:
            shown, _ = _held_exactly(resolve, name, shown, Interval(result.low.value, result.high.value,
                                                                    result.low.open, result.high.open))
        witness = resolve(shown)
        assert witness is not None
        failing = [d for d in analyse_automaton(witness, []) if d.is_error]
        if allowed is not None and not result.empty:
            what = ("no value" if not allowed else
                    f"no least value (the values that pass form {_intervals_text(allowed)})")
            notes = [f"every other check holds for {name} in {result.interval()}; {required_text}",
                     f"the checks at {name} = {short_number(shown)} follow"]
        else:
            what = ("no value" if result.empty else
                    f"no least value (the values that pass form {result.interval()})")
            notes = [*result.cuts, f"the checks at {name} = {short_number(shown)} follow"]
        return None, [error("E0406", f"{what} of parameter `{name}` in [{short_number(parameter.low)}, "
                            f"{short_number(parameter.high)}] passes every check", parameter.span,
                            notes=notes,
                            hints=["widen the parameter's bounds, or change what it cannot compensate"]),
                      *failing], None
    assert result.low is not None and result.high is not None  # a least value: the set is not empty
    top = allowed[0] if allowed is not None else Interval(result.low.value, result.high.value,
                                                          high_open=result.high.open)
    least, held = _held_exactly(resolve, name, least, top)
    if allowed is not None:
        sentence = (f"synthesised: {claim.holds} for {name} in {result.interval()}, and {required_text}; "
                    f"checked with {_value_checked(name, least, held)}{claim.after}")
        inequalities = tuple(_interval_inequality(name, i) for i in allowed)
        facts.append(Fact("synthesis", sentence))
        return resolve(least), [], Synthesised(((name, least),), (" or ".join(inequalities),), sentence)
    if result.whole:
        sentence = (f"synthesised: {claim.holds} for every value of {name} in {result.interval()}; "
                    f"checked with {_value_checked(name, least, held)}{claim.after}")
    else:
        sentence = (f"synthesised: {result.describe()} ({claim.holds} for {name} in {result.interval()}); "
                    f"checked with {_value_checked(name, least, held)}{claim.after}")
    facts.append(Fact("synthesis", sentence))
    return resolve(least), [], Synthesised(((name, least),), () if result.whole else (result.describe(exact=True),),
                                           sentence)


def _fails_at(node: ast.Automaton, parameter: ir.Parameter, value: Fraction) -> Diagnostic:
    """E0407 for a parameter at one of whose bounds the file does not check (``sample every P`` with a
    horizon that is no whole number of ``P`` there, an input bound ``50 - P`` reversed there), or at a value
    between them the search reached (a coefficient too small for a double there, E0011): the errors the file
    has at that value, as notes. The search reads the automaton at both bounds and at the values it tries, so
    there is nothing to search; before this, such a file ended ``rac check`` with an internal error."""
    name = parameter.name
    resolver = Resolver(node, {name: value})
    resolver.run()
    errors = [d for d in resolver.diagnostics if d.is_error]
    which = ("the low end of its bounds" if value == parameter.low else "the high end of its bounds"
             if value == parameter.high else "a value within its bounds the search tried")
    return error("E0407", f"not yet: parameter `{name}` cannot be synthesised here: the file does not check at "
                 f"{name} = {short_number(value)}, {which}",
                 parameter.span,
                 notes=[Note(f"at {name} = {short_number(value)}: error[{d.code}]: {d.message}", d.span)
                        for d in errors[:3]],
                 hints=[f"narrow the bounds of `{name}` to values at which the file checks, "
                        f"or write `const {name} = ...`"])


def _held_exactly(resolve: Callable[[Fraction], ir.Automaton | None], name: str, least: Fraction, top: Interval
                  ) -> tuple[Fraction, str]:
    """``least``, or, when the automaton at ``least`` fails E0801 (the UPPAAL model and rac's engine compute
    an update over the value's denominator, ``(9*sa - 9500000) / 9`` for ``sa -= 950/9``, and the product
    leaves int32), the least value above it that is a whole number of significands (``1/base^exponent``),
    when ``top`` (the set's interval that holds ``least``) holds it too; and the words saying why (or "").
    The synthesised set is exact for the checks it searches, but E0801 depends on the value's denominator,
    not on its size: without this, `rac check` refuted the least value and `rac tune` wrote nothing while
    every significand above it passes."""
    automaton = resolve(least)
    assert automaton is not None, "the file resolved at its least value"
    base, exponent = representation(automaton)
    scale = base ** exponent
    if (least * scale).denominator == 1 or not any(d.code == "E0801" for d in analyse_automaton(automaton, [])):
        return least, ""
    rounded = Fraction(math.ceil(least * scale), scale)
    if rounded not in top:
        return least, ""
    return rounded, (f", the least value the significands hold exactly (1/{scale}; at "
                     f"{name} = {_readable(least)} the UPPAAL model's integer arithmetic leaves int32, E0801)")


def _value_checked(name: str, least: Fraction, held: str) -> str:
    """``NAME = value`` of the value the checks were shown at, and ``held`` (why, when it is not the set's
    least): a value the significands hold is a short decimal, written in full (``357.1558``), where
    :func:`rac.core.diagnostics.short_number` rounded it to ``357.156…``, which is not the value checked."""
    return f"{name} = {exact_decimal(least) if held else short_number(least)}{held}"


def _readable(value: Fraction) -> str:
    """``value`` exactly where that is short (``16 / 7``), else rounded and marked (``357.156…``): the ends and
    vertices a discounted search finds have gamma's powers in them, hundreds of digits."""
    text = exact_text(value)
    return text if len(text) <= 40 else short_number(value)


def _requirement_text(requirement: ir.Requirement) -> str:
    if requirement.check == "risk":
        return f"require risk <= {short_number(requirement.bound or Fraction(0))}"
    return f"require {requirement.check}"


def _intervals_text(intervals: list[Interval]) -> str:
    return " or ".join(f"{'(' if i.low_open else '['}{short_number(i.low)}, {short_number(i.high)}"
                       f"{')' if i.high_open else ']'}" for i in intervals)


def _interval_inequality(name: str, interval: Interval) -> str:
    """``a <= NAME <= b`` with exact numbers (the form `rac tune` records); ``NAME == a`` for one value, as
    :meth:`~rac.check.analysis.synthesis.Synthesis.describe` writes it without a `require`."""
    if interval.low == interval.high:  # not empty, so both ends are closed
        return f"{name} == {exact_text(interval.low)}"
    return (f"{exact_text(interval.low)} {'<' if interval.low_open else '<='} {name} "
            f"{'<' if interval.high_open else '<='} {exact_text(interval.high)}")


def _bounds_text(parameters: tuple[ir.Parameter, ...]) -> str:
    """``w1, w2 in [1, 100]; P in [0, 5]``: the declared bounds, names with the same bounds together."""
    groups: dict[tuple[Fraction, Fraction], list[str]] = {}
    for p in parameters:
        groups.setdefault((p.low, p.high), []).append(p.name)
    return "; ".join(f"{', '.join(names)} in [{short_number(low)}, {short_number(high)}]"
                     for (low, high), names in groups.items())



def nonlinear_use(node: ast.Automaton, parameters: set[str]) -> tuple[str, Span | None, str] | None:
    """The first place where a parameter enters non-linearly, as (parameter, span, why), or None.

    Constants defined from parameters carry their degree into the expressions that read them.
    """
    walk = _Walk(parameters)
    for member in node.members:
        if isinstance(member, ast.ConstDecl):
            degree = walk.degree(member.expr)
            if degree:
                walk.degrees[member.name.name] = degree
        elif not isinstance(member, ast.ParamDecl):
            for expr in _expressions(member):
                walk.degree(expr)
        if walk.found is not None:
            return walk.found
    return None


def _expressions(node: object) -> list[ast.Expr]:
    """The outermost expressions of a declaration (a walk over the frozen dataclasses' fields)."""
    if isinstance(node, get_args(ast.Expr)):
        return [node]  # type: ignore[list-item]
    if isinstance(node, (tuple, list)):
        return [e for item in node for e in _expressions(item)]
    if dataclasses.is_dataclass(node) and not isinstance(node, type):
        return [e for f in dataclasses.fields(node) for e in _expressions(getattr(node, f.name))]
    return []


class _Walk:
    """Degrees in the parameters, and the first non-affine place found."""

    def __init__(self, parameters: set[str]) -> None:
        self.parameters = parameters
        self.degrees: dict[str, int] = dict.fromkeys(parameters, 1)
        self.found: tuple[str, Span | None, str] | None = None

    def degree(self, expr: ast.Expr) -> int:
        """The degree of ``expr`` in the parameters (0 or 1 when affine)."""
        if isinstance(expr, ast.Name):
            return self.degrees.get(expr.id, 0)
        if isinstance(expr, ast.Unary):
            return self.degree(expr.operand)
        if isinstance(expr, ast.Call):
            if any([self.degree(a) for a in expr.args]):
                self.refuse(expr, f"it is an argument of `{expr.func}(...)`")
            return 0
        if isinstance(expr, ast.Binary):
            left, right = self.degree(expr.left), self.degree(expr.right)
            if expr.op == "*":
                if left and right:
                    self.refuse(expr, "two parameters (or one twice) are multiplied")
                return left + right
            if expr.op == "/":
                if right:
                    self.refuse(expr, "it divides")
                return left
            return max(left, right)
        return 0

    def refuse(self, expr: ast.Expr, why: str) -> None:
        if self.found is not None:
            return
        # The parameter itself where one is named, else the constant computed from one.
        names = sorted({n.id for n in ast.names_in(expr) if self.degrees.get(n.id)},
                       key=lambda n: (n not in self.parameters, n))
        self.found = (names[0], expr.span, f"{why} (the checks would not be linear in it)")
