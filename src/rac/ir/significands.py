"""E0801 for the reward rates: a rate whose growth over one sample has no whole number of significand
units, or more than an ``int32`` holds.

A real value ``v`` is held as its significand ``v * base**exponent`` in the UPPAAL model and in
rac's engine (the reward mirrors). Here, below the checker, the UPPAAL target and the engine, so
that all three report the one diagnostic: the checker when the automaton has a ``model`` block (its
base and exponent are known then), ``rac compile --target uppaal``
(:class:`rac.targets.uppaal.significands.Significands`), and the engine's product.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from fractions import Fraction
from typing import TypeVar

from rac import ir
from rac.core.diagnostics import Diagnostic, RacError, error, short_number
from rac.core.numbers import INT32_MAX, INT32_MIN, exact_decimal
from rac.core.printing import signed_sum
from rac.core.source import Span
from rac.ir import expr as ie
from rac.ir import query as iq
from rac.ir.vocabulary import DEFAULT_BASE, DEFAULT_EXPONENT, SETTINGS, Holding, held_value

__all__ = ["HINT_REPRESENTATION", "Unrepresentable", "bound_diagnostic", "common_denominator", "decimal_text",
           "emitted_sum", "input_extremes", "linear_text", "literal_problem", "observation_diagnostics", "off_grid",
           "rate_diagnostic", "rate_diagnostics", "representation", "unrepresentable", "update_diagnostics",
           "vanishing"]

_Name = TypeVar("_Name")

#: The hint of an E0801 without one of its own (``scale``: ``base**exponent``).
HINT_REPRESENTATION = ("add a `model` block with a larger `exponent`, or change the number so that it "
                       "is a whole multiple of 1/{scale}")


class Unrepresentable(RacError, ValueError):
    """A number the significands cannot hold met after the checker (an automaton checked without its
    ``model`` block's checks, or built by hand); ``diagnostic`` is its E0801."""

    diagnostic: Diagnostic


def representation(automaton: ir.Automaton) -> tuple[int, int]:
    """The automaton's ``(base, exponent)``: its ``model`` block's, else the defaults."""
    model = automaton.model
    return (model.base, model.exponent) if model is not None else (DEFAULT_BASE, DEFAULT_EXPONENT)


def vanishing(values: Mapping[str, Fraction], scale: int) -> list[str]:
    """The settings of ``values`` (the ``model`` block's, by name) that must be positive but that the
    model holds as 0 at ``scale``: a significand setting truncated to 0 (``width 0.00001`` at scale
    10,000 would be 0, not what the file says)."""
    return [name for name, setting in SETTINGS.items()
            if name in values and setting.exclusive and setting.minimum == 0 and values[name] > 0
            and held_value(name, values[name], scale) == 0]


def off_grid(action: ir.Action, scale: int | Fraction) -> Fraction | None:
    """The first of ``action``'s low end and step that is no whole number of significands at ``scale``
    (the controller chooses among significands), or None when both are."""
    return next((v for v in (action.low, action.step) if (v * scale).denominator != 1), None)


def unrepresentable(automaton: ir.Automaton, message: str, span: Span | None, notes: Iterable[str] = (),
                    hints: Iterable[str] | None = None) -> Diagnostic:
    """E0801 at ``span`` (else the automaton's name); without ``hints``, the hint to enlarge the
    exponent or round the number."""
    base, exponent = representation(automaton)
    if span is None and automaton.source is not None:
        span = automaton.source.name.span
    return error("E0801", message, span, notes=list(notes),
                 hints=list(hints) if hints is not None else [HINT_REPRESENTATION.format(scale=base ** exponent)],
                 data={"base": base, "exponent": exponent})


def rate_diagnostic(automaton: ir.Automaton, location: ir.Location, reward: str, rate: ir.Linear,
                    values: Mapping[str, Sequence[int]] | None = None,
                    extremes: Mapping[str, Sequence[int]] | None = None) -> Diagnostic | None:
    """E0801 when the mirror of ``reward`` cannot follow ``rate`` in ``location``: its gain per sample
    is beyond the ``int32`` range, or not a whole number of significand units (``values``: the
    significands each numeric input takes, where the caller knows them; None checks the constant
    part only). ``extremes``: significands an input may take (its bounds') at which only the products
    the accrual computes must stay within int32, where no value is known. None when the rate is
    representable."""
    base, exponent = representation(automaton)
    scale = base ** exponent
    period = Fraction(automaton.period)
    # runtime.semantics.mirror_accrual's numbers (the checker may not import the runtime)
    const = rate.const * period * scale
    terms = [(coef * period, name) for name, coef in rate.terms]
    bad = const.denominator != 1 or any(
        (coef * v).denominator != 1 for coef, name in terms for v in (values or {}).get(name, []))
    if not bad and max([abs(const), *(abs(coef) for coef, _ in terms)]) > INT32_MAX:
        return unrepresentable(
            automaton,
            f"reward rate `{reward}' == {linear_text(rate)}` in location `{location.name}` adds "
            f"{short_number(max([abs(const), *(abs(coef) for coef, _ in terms)]))} significand units "
            "per sample (per unit of its inputs), beyond the 32-bit integer range",
            location.span, hints=["lower the rate, or the exponent of the number representation"])
    # The emitted accrual prints a term as `p*input / q` in int32 arithmetic: the product p * significand
    # is an intermediate value UPPAAL holds in 32 bits, even where the term itself fits.
    worst = None if bad else max(((abs(coef.numerator * v), coef, name, v) for coef, name in terms
                                  for v in [*(values or {}).get(name, []), *(extremes or {}).get(name, [])]),
                                 default=None)
    if worst is not None and worst[0] > INT32_MAX:
        product, coef, name, v = worst
        divided = f" / {coef.denominator}" if coef.denominator != 1 else ""
        return unrepresentable(
            automaton,
            f"reward rate `{reward}' == {linear_text(rate)}` in location `{location.name}`: the UPPAAL model "
            f"computes {abs(coef.numerator)}*{name}{divided} per sample, and {abs(coef.numerator)} times "
            f"the significand of `{name}` = {decimal_text(Fraction(v, scale))} is {short_number(Fraction(product))}, "
            "beyond the 32-bit integer range", location.span,
            notes=[f"`{name}` is held as its significand ({v}, at base {base}, exponent {exponent}); the model "
                   "computes the product in 32-bit integers"],
            hints=["narrow the input's range, lower the exponent of the number representation, or choose a "
                   "rate and sample period whose product has a smaller numerator"])
    if not bad:
        return None
    offender = next(((coef, name, v) for coef, name in terms for v in (values or {}).get(name, [])
                     if (coef * v).denominator != 1), None)
    if offender is not None and const.denominator == 1:
        return _input_rate_diagnostic(automaton, location, reward, rate, *offender)
    if terms:
        note = (f"one sample adds ({linear_text(rate)}) * {decimal_text(period)} to `{reward}`, which is "
                "not a whole number of significand units for every value its inputs take")
    else:
        step = rate.const * period
        note = (f"one sample adds {decimal_text(rate.const)} * {decimal_text(period)} = {decimal_text(step)} to "
                f"`{reward}`, that is {decimal_text(step * scale)} significand units (1/{scale} "
                "each): not a whole number")
    beyond = _beyond_powers(const.denominator, base)
    larger = (", or add a `model` block with a larger `exponent`" if beyond == 1
              else f" (no exponent helps: {beyond} divides no power of the base {base})")
    return unrepresentable(
        automaton,
        f"reward rate `{reward}' == {linear_text(rate)}` in location `{location.name}` is not "
        f"representable in significands at exponent {exponent}", location.span,
        notes=[note],
        hints=[f"make rate * period a multiple of 1/{scale}{larger}"])


def _beyond_powers(denominator: int, base: int) -> int:
    """The factor of ``denominator`` that divides no power of ``base`` (1: a larger exponent makes a
    number of that denominator whole)."""
    while (common := math.gcd(denominator, base)) > 1:
        while denominator % common == 0:
            denominator //= common
    return denominator


def _input_rate_diagnostic(automaton: ir.Automaton, location: ir.Location, reward: str, rate: ir.Linear,
                           coef: Fraction, name: str, v: int) -> Diagnostic:
    """E0801 of a rate whose term ``coef * name`` gains no whole number of significand units at the
    significand ``v`` the model gives input ``name`` (the automaton alone: its Environment gives each
    bound, each number its guards compare with, and one value of each piece between them)."""
    base, exponent = representation(automaton)
    scale = base ** exponent
    value = Fraction(v, scale)
    item = next(i for i in automaton.inputs if i.name == name)
    # the term gains whole units exactly at the significands that are multiples of q (coef = p/q)
    q = coef.denominator
    multiple = Fraction(q, scale)
    if item.kind == "int":
        multiple = Fraction(q, math.gcd(q, scale))
    beyond = _beyond_powers(q, base)
    larger = beyond == 1
    # the term is whole for every value the input may take when coefficient * period * (the least
    # significand step of the input: the scale for an int, 1 for a real) is whole
    unit = scale if item.kind == "int" else 1
    period = Fraction(automaton.period)
    example = Fraction(round(coef * unit), unit) / period
    whole = (f"(coefficient * period) is a multiple of {decimal_text(Fraction(1, unit))}"
             + (f" (`{decimal_text(example)}*{name}`)" if example else ""))
    why = (f"no exponent of base {base} helps: {beyond} divides no power of {base}" if not larger
           else "a larger exponent of the number representation helps")
    return unrepresentable(
        automaton,
        f"reward rate `{reward}' == {linear_text(rate)}` in location `{location.name}` is not representable in "
        f"significands at exponent {exponent}: at `{name}` = {decimal_text(value)} one sample's gain is no whole "
        "number of significand units", location.span,
        notes=[f"the automaton alone's Environment gives `{name}` its bounds, the numbers its guards compare it "
               f"with, and one value between each two of them; at `{name}` = {decimal_text(value)} one sample adds "
               f"{decimal_text(coef * value)} to `{reward}`, {decimal_text(coef * v)} significand units (1/{scale} "
               "each): the mirror would drift from the reward",
               f"the gain is whole only where `{name}` is a multiple of {decimal_text(multiple)} ({why})"],
        hints=[f"give `{name}` bounds and compared numbers that are multiples of {decimal_text(multiple)}, with a "
               f"multiple between each two of them, or write a coefficient whose gain per sample {whole}"
               + (", or add a `model` block with a larger `exponent`" if larger else "")])


def rate_diagnostics(automaton: ir.Automaton) -> list[Diagnostic]:
    """E0801 for every numeric input's bound without a significand (:func:`bound_diagnostic`), and for
    every rate of ``automaton`` whose constant part has no significand, or whose product
    ``p*input`` can leave int32 over the input's declared range (the checker's check, with a ``model``
    block: the inputs' values come from the scenario, known later; the UPPAAL target's whole model
    checks the same products, :func:`input_extremes`)."""
    found = [d for d in (bound_diagnostic(automaton, item) for item in automaton.numeric_inputs) if d is not None]
    extremes = input_extremes(automaton)
    for location in automaton.locations:
        for reward, rate in zip(automaton.rewards, location.rates):
            diagnostic = rate_diagnostic(automaton, location, reward, rate, extremes=extremes)
            if diagnostic is not None:
                found.append(diagnostic)
    return found


def literal_problem(value: int | Fraction) -> str | None:
    """Why ``value`` has no UPPAAL integer literal (not an integer, beyond int32, or -2147483648, which
    is an int32 that UPPAAL writes no literal for), or None (:func:`rac.targets.uppaal.expr.int_literal`)."""
    if isinstance(value, Fraction):
        if value.denominator != 1:
            return f"{value} is not an integer"
        value = value.numerator
    if value == -INT32_MAX - 1:
        return (f"{value} is a 32-bit integer, but UPPAAL writes no literal for it: its literals reach {INT32_MAX} "
                "in magnitude")
    if abs(value) > INT32_MAX:
        return f"{short_number(Fraction(value))} is beyond the 32-bit integer range (at most {INT32_MAX} in magnitude)"
    return None


def bound_diagnostic(automaton: ir.Automaton, item: ir.Input) -> Diagnostic | None:
    """E0801 when a bound of the numeric input ``item`` has no significand the model can write (the
    automaton alone's Environment gives the input its bounds; with a ``model`` block `rac check`
    reports it too, so that the check and the target agree)."""
    base, exponent = representation(automaton)
    for bound in (item.low, item.high):
        problem = None if bound is None else literal_problem(bound * base ** exponent)
        if bound is not None and problem is not None:
            return unrepresentable(
                automaton, f"the bound {decimal_text(bound)} of input `{item.name}` is not representable as a "
                f"32-bit significand at base {base}, exponent {exponent}", item.span,
                notes=[f"its significand {problem}"],
                hints=["narrow the input's bounds, or lower the exponent of the number representation"])
    return None


def input_extremes(automaton: ir.Automaton) -> dict[str, list[int]]:
    """The significands of each bounded numeric input's bounds: where no Environment chooses the inputs
    (the whole model's Controller computes them), the accruals' products ``p*input`` must stay within
    int32 over that range (:func:`rate_diagnostic`'s ``extremes``)."""
    base, exponent = representation(automaton)
    return {item.name: [round(bound * base ** exponent) for bound in (item.low, item.high)]
            for item in automaton.numeric_inputs if item.low is not None and item.high is not None}


def decimal_text(value: Fraction) -> str:
    """A rational for messages: its exact decimal when it has a short one (``0.00001``), else rounded."""
    if abs(value) >= 10**16:
        return short_number(value)
    return exact_decimal(value, max_places=12) or short_number(value)


def linear_text(linear: ir.Linear) -> str:
    """A rate for messages: ``0.1 + 2*x``, its terms joined by ``+`` (a negative coefficient keeps its sign)."""
    parts = [decimal_text(linear.const)] if linear.const or not linear.terms else []
    for name, coefficient in linear.terms:
        parts.append(name if coefficient == 1 else f"{decimal_text(coefficient)}*{name}")
    return " + ".join(parts)


# ---------------------------------------------------------------- the mirrors' updates in int32
def common_denominator(const: Fraction, terms: Sequence[tuple[Fraction, _Name]]
                       ) -> tuple[int, int, list[tuple[int, _Name]]]:
    """A mirror update ``const + Σ coefficient*name`` as the UPPAAL model computes it:
    ``(q, k, [(k_i, name)])`` with everything over the least common denominator ``q``, the new
    mirror being ``(Σ k_i*name + k) / q`` in C's integer arithmetic (one division, truncating
    towards zero; no division when ``q`` is 1). Zero coefficients are left out."""
    kept = [(Fraction(c), n) for c, n in terms if c != 0]
    q = math.lcm(const.denominator, *(c.denominator for c, _ in kept))
    return q, int(const * q), [(int(c * q), n) for c, n in kept]


def update_diagnostics(automaton: ir.Automaton, bounds: Mapping[str, tuple[Fraction, Fraction]]
                       ) -> list[Diagnostic]:
    """E0801 for every update (of an edge, or of an ``at end`` clause) whose emitted integer arithmetic
    has an intermediate value that can leave int32: a product ``k*iP`` or a partial sum computed
    before the division by the common denominator (``p = 2*p/3`` is ``iP = 2*iP / 3``, and ``2*iP``
    leaves int32 once ``p`` can exceed half the range). ``bounds``: each reward's least and greatest
    value over every instant, in between updates too (the int32 range check's); a numeric input
    ranges over its declared bounds. The final value itself is the range check's (E0501)."""
    found = []
    clauses = [*(edge.updates for group in automaton.edges for edge in group),
               *(clause.updates for clause in automaton.end_clauses)]
    seen: set[int] = set()
    for updates in clauses:
        for assignment in updates:
            if id(assignment) in seen:
                continue
            seen.add(id(assignment))
            diagnostic = _update_diagnostic(automaton, assignment, bounds)
            if diagnostic is not None:
                found.append(diagnostic)
    return found


def _update_diagnostic(automaton: ir.Automaton, assignment: ir.Assignment,
                       bounds: Mapping[str, tuple[Fraction, Fraction]]) -> Diagnostic | None:
    base, exponent = representation(automaton)
    scale = base ** exponent
    ranges = dict(bounds)
    for item in automaton.numeric_inputs:
        if item.low is None or item.high is None:
            return None  # no bound to reason with (the UPPAAL target needs one anyway)
        ranges[item.name] = (item.low, item.high)
    # runtime.semantics.mirror_update's numbers (the checker may not import the runtime)
    q, k, ints = common_denominator(assignment.value.const * scale, [(c, n) for n, c in assignment.value.terms])
    if not ints:
        return None
    held = {name: (lo * scale, hi * scale) for name, (lo, hi) in ranges.items()}
    found = emitted_sum(k, ints, held)
    if found is None:
        return None
    text, steps = found
    if q == 1:
        steps = steps[:-1]  # the last value computed is the whole sum, the result itself: E0501's
    else:
        steps.append(("", Fraction(q), Fraction(q)))
    overflow = _first_overflow(steps)
    if overflow is not None:
        emitted = f"({text}) / {q}" if q != 1 else text
        within = _within(ranges, ints)
        return unrepresentable(
            automaton,
            f"update `{assignment.reward} = {_exact_text(assignment.value)}`: the UPPAAL model computes it as "
            f"`{emitted}` over 32-bit significands, and {overflow} beyond the 32-bit integer range",
            assignment.span,
            notes=[f"{within} (the int32 range check's bounds over every run), held as significands at base "
                   f"{base}, exponent {exponent}: UPPAAL computes every product and partial sum of an update in "
                   "32-bit integers, before it divides, where rac's engine computes exactly"],
            hints=["bound the reward's growth (a shorter horizon, a smaller rate), narrow the input's range, "
                   "or lower the exponent of the number representation"])
    return None


def observation_diagnostics(automaton: ir.Automaton, bounds: Mapping[str, tuple[Fraction, Fraction]]
                            ) -> list[Diagnostic]:
    """E0801 for every discrete observation of a learning query (``{10*sa + pr}->{...}``) whose integer
    form in the UPPAAL model (mirrors and significands over their least common denominator: ``10*iSa +
    iPr``) can leave int32 on the way. ``bounds``: each reward's least and greatest value (the int32
    range check's). An observation reading a name without a known range (the ego state) is left alone."""
    base, exponent = representation(automaton)
    scale = base ** exponent
    # each name an observation reads: the integer the model holds it in, its value per unit, its range
    held: dict[tuple[ie.RefKind, str], tuple[str, Fraction, tuple[Fraction, Fraction]]] = {}
    for reward, (low, high) in bounds.items():
        held[ie.RefKind.REWARD, reward] = (reward, Fraction(1, scale), (low * scale, high * scale))
    for item in automaton.numeric_inputs:
        if item.low is not None and item.high is not None:
            held[ie.RefKind.INPUT, item.name] = (item.name, Fraction(1, scale), (item.low * scale, item.high * scale))
    held[ie.RefKind.LOCATION_INDEX, f"{automaton.name}.location"] = (
        f"{automaton.name}.location", Fraction(1), (Fraction(0), Fraction(len(automaton.locations) - 1)))
    found = []
    for decl in automaton.queries:
        query = decl.query
        if not isinstance(query, iq.LearnStrategy):
            continue
        for index, expr in enumerate(query.discrete):
            form = ie.linear_form(expr) if expr.type == ie.NUM else None
            if form is None:
                continue
            label = query.labels[index] if index < len(query.labels) else None
            terms, ranges = [], {}
            for ref, coefficient in form.terms:
                key = (ref.kind, ref.name)
                if ref.kind is ie.RefKind.MODEL and ref.model.holding is Holding.TIME:
                    # the sample counter: `time` is count * period, count in [0, steps]
                    entry = ("count", Fraction(automaton.period), (Fraction(0), Fraction(automaton.steps)))
                elif key in held:
                    entry = held[key]
                elif ref.kind is ie.RefKind.MODEL and ref.model.kind == "ego":  # a significand, range unknown
                    name = ref.model.uppaal or ref.name
                    terms.append((coefficient * Fraction(1, scale), name))
                    continue
                else:
                    break
                name, unit, ranges[name] = entry
                terms.append((coefficient * unit, name))
            else:
                _, k, ints = common_denominator(form.const, terms)
                emitted = emitted_sum(k, ints, ranges) if ints else None
                literal = max([abs(k), *(abs(c) for c, _ in ints)])
                if emitted is None and literal > INT32_MAX:  # a constant, or a sum over names of unknown
                    # ranges (the ego state), with a number no int32 literal writes
                    found.append(unrepresentable(
                        automaton,
                        f"query `{decl.name}`: the discrete observation `{label or decimal_text(form.const)}` is "
                        "observed in the UPPAAL model as an integer (mirrors and significands, a whole multiple of "
                        f"it) with the number {short_number(Fraction(literal))}, beyond the 32-bit integer range",
                        decl.span,
                        hints=["a constant observation tells no two states apart: leave it out" if not ints else
                               "observe a smaller multiple, or lower the exponent of the number representation"]))
                    continue
                if emitted is None:
                    continue
                text, steps = emitted
                overflow = _first_overflow(steps)
                if overflow is not None:
                    within = _within(ranges, ints)
                    found.append(unrepresentable(
                        automaton,
                        f"query `{decl.name}`: the discrete observation `{label or text}` is observed in the UPPAAL "
                        f"model as the integer `{text}` (mirrors and significands, a whole multiple of it), and "
                        f"{overflow} beyond the 32-bit integer range", decl.span,
                        notes=[f"{within} as the model holds them (the int32 range check's bounds for rewards, at "
                               f"base {base}, exponent {exponent}): UPPAAL computes the observation in 32-bit "
                               "integers, where rac's engine computes exactly"],
                        hints=["observe fewer or smaller multiples (`{sa}` rather than `{10*sa + pr}`), bound the "
                               "rewards' growth, or lower the exponent of the number representation"]))
    return found


def _first_overflow(steps: Sequence[tuple[str, Fraction, Fraction]]) -> str | None:
    """What leaves int32 first among an emitted sum's ``steps`` (each a value shown, its least and its
    greatest), said for a message (`` `2*p` may reach 3e9,``), or ``None``."""
    for shown, lo, hi in steps:
        if lo < INT32_MIN or hi > INT32_MAX:
            worst = hi if hi > INT32_MAX else lo
            return f"`{shown}` may reach {short_number(worst)}," if shown else f"its number {short_number(worst)} is"
    return None


def _within(ranges: Mapping[str, tuple[Fraction, Fraction]], ints: Sequence[tuple[int, str]]) -> str:
    """The ranges of the names an emitted sum reads, for a note."""
    return ", ".join(f"`{name}` within [{decimal_text(ranges[name][0])}, {decimal_text(ranges[name][1])}]"
                     for name in dict.fromkeys(name for _, name in ints))


def emitted_sum(k: int, ints: Sequence[tuple[int, str]], ranges: Mapping[str, tuple[Fraction, Fraction]]
                ) -> tuple[str, list[tuple[str, Fraction, Fraction]]] | None:
    """The integer sum ``Σ k_i*name + k`` as the UPPAAL model prints it (``2*p + d - 5``) and every value
    C computes on the way, in its order: ``(text, [(shown, least, greatest)])``, ``shown`` being the
    partial expression, or "" for a literal (an int32 too). ``ranges``: each name's least and greatest
    value as the integer the model holds; None when a name has none."""
    steps: list[tuple[str, Fraction, Fraction]] = []
    low = high = Fraction(0)
    text = ""
    for index, (coefficient, name) in enumerate(ints):
        if name not in ranges:
            return None
        lo, hi = ranges[name]
        product = (coefficient * lo, coefficient * hi)
        term = name if abs(coefficient) == 1 else f"{short_number(Fraction(abs(coefficient)))}*{name}"
        if abs(coefficient) != 1:
            steps.append(("", Fraction(abs(coefficient)), Fraction(abs(coefficient))))
            steps.append((term, min(product), max(product)))
        if index == 0 and coefficient == -1:  # `-iP` is computed too: -(-2147483648) leaves int32
            steps.append((f"-{term}", min(product), max(product)))
        if index == 0:
            text, low, high = ("-" if coefficient < 0 else "") + term, min(product), max(product)
        else:
            text += f" {'-' if coefficient < 0 else '+'} {term}"
            low, high = low + min(product), high + max(product)
            steps.append((text, low, high))
    if k:
        steps.append(("", Fraction(abs(k)), Fraction(abs(k))))
        text += f" {'-' if k < 0 else '+'} {short_number(Fraction(abs(k)))}"
        low, high = low + k, high + k
        steps.append((text, low, high))
    return text, steps


def _exact_text(linear: ir.Linear) -> str:
    """An update's value for messages, every number exact: ``2/3*p + 1``."""
    def number(value: Fraction) -> str:
        return exact_decimal(value, max_places=12) or f"{value.numerator}/{value.denominator}"

    parts = [(coefficient < 0, name if abs(coefficient) == 1 else f"{number(abs(coefficient))}*{name}")
             for name, coefficient in linear.terms]
    if linear.const or not parts:
        parts.append((linear.const < 0, number(abs(linear.const))))
    return signed_sum(parts)
