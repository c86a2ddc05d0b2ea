"""Synthesis of one parameter (``param P in [lo, hi]``): the exact set of values for which every
check holds, by cutting planes over the exact worst-run oracle (docs/checks.md, "Parameters").

Each check c (P2 at a level, either side of a reward's int32 range) holds at a value p when
``V_c(p) = max over runs r of J_r(p)`` stays <= its bound (< for the range). Under the conditions
:func:`unsupported` checks, the runs do not depend on p and each ``J_r`` is affine in p, so ``V_c`` is
convex and the values where c holds form an interval; so does their intersection. The lower end is
found from ``lo`` upwards: the oracle's worst run at the candidate gives the affine constraint
``J_r(p) <= bound``, the next candidate is the least value satisfying every constraint so far, and the
search stops when the oracle finds no violation. The upper end is found the same way from ``hi`` down.

With a discount (``rac check --discount``), P2 of the discounted return is one more check per level: a run's
discounted value weighs each step's change by a power of gamma, fixed by the run, so it is affine in p too,
and the same oracle (:func:`~rac.check.analysis.discount.discounted_worst`) gives its cuts.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
from functools import partial

from rac import ir
from rac.check.analysis.affine import Affine, EndOutcome, Moves, from_assignments, identity, moves, then
from rac.check.analysis.behaviour import input_space
from rac.check.analysis.discount import Discount, discounted_value, discounted_worst
from rac.check.analysis.incentives import Incentives, analyse
from rac.check.analysis.incentives import Unchecked as IncentivesUnchecked
from rac.check.analysis.piecewise import Interval, convex, intersect
from rac.check.analysis.priority import (
    p2_levels,
    p2_target,
    range_limit,
    range_target,
    rate_conflicts,
    replay,
)
from rac.check.analysis.worst import Target, Unfinished, Worst, maximise
from rac.core.diagnostics import RacError, short_number
from rac.core.numbers import exact_text
from rac.ir.inputs import InputSpace
from rac.ir.vocabulary import DEFAULT_BASE, DEFAULT_EXPONENT

#: The automaton resolved with the parameter at a value (None when it does not resolve).
Resolve = Callable[[Fraction], "ir.Automaton | None"]


@dataclass(frozen=True)
class Synthesised:
    """What ``rac check`` synthesised for a file's parameters: the values it checked the file with
    (declaration order), the set of passing values as inequalities beyond the declared bounds
    (empty when every declared value passes), the ``synthesised:`` sentence it printed and any further
    facts about the set (the vertices of several weights' polyhedron)."""

    values: tuple[tuple[str, Fraction], ...]
    inequalities: tuple[str, ...]
    sentence: str
    details: tuple[str, ...] = ()

    @property
    def facts(self) -> tuple[str, ...]:
        """Every fact the synthesis added to ``rac check``'s output."""
        return (self.sentence, *self.details)

    def value(self, name: str) -> Fraction:
        """The value the file was checked with for parameter ``name``."""
        return dict(self.values)[name]


@dataclass(frozen=True)
class Check:
    """One check as a maximisation: it holds while the worst value is <= ``bound`` (< when ``strict``)."""

    what: str
    target: Callable[[ir.Automaton], Target]
    bound: Fraction
    strict: bool
    #: The learner's discount of a check of the discounted return (its worst value weighs each step's change).
    discount: Discount | None = None

    def worst(self, automaton: ir.Automaton, outs: Moves, target: Target) -> Worst | None:
        """The run of the largest value of ``target``, or one past the bound."""
        if self.discount is not None:
            return discounted_worst(automaton, outs, target, self.discount)
        return maximise(automaton, outs, target, run=self.violated)

    def value(self, automaton: ir.Automaton, space: InputSpace, worst: Worst, target: Target) -> Fraction:
        """The value of ``target`` at the instant the run ``worst`` ends, replayed exactly."""
        if self.discount is not None:
            return discounted_value(automaton, space, worst, target, self.discount)
        return _value(automaton, space, worst, target)

    def violated(self, value: Fraction) -> bool:
        return value >= self.bound if self.strict else value > self.bound


@dataclass(frozen=True)
class End:
    """One end of the set: ``value``, excluded when ``open``."""

    value: Fraction
    open: bool = False


@dataclass(frozen=True)
class Synthesis:
    """The values of the parameter for which every check holds: ``[low, high]`` (ends may be open),
    or empty (``low``/``high`` None) with ``witness`` the value whose checks show why."""

    parameter: ir.Parameter
    low: End | None
    high: End | None
    witness: Fraction
    #: Each cut, as a sentence ("at P = 90, P2 for `sa` needs P >= 98").
    cuts: tuple[str, ...] = ()

    @property
    def empty(self) -> bool:
        return self.low is None or self.high is None

    @property
    def whole(self) -> bool:
        """Whether every value of the declared range passes."""
        p = self.parameter
        return (self.low, self.high) == (End(p.low), End(p.high))

    @property
    def least(self) -> Fraction | None:
        """The least value of the set (None when it is empty or its lower end is open)."""
        return None if self.low is None or self.low.open else self.low.value

    def describe(self, exact: bool = False) -> str:
        """The set as the inequalities the checks add to the declared range: ``P >= 98``, ``2 <= P < 7``,
        ``P == 98`` for one value (numbers rounded for reading, or ``exact``: ``P < 1431 / 2``)."""
        p = self.parameter
        assert self.low is not None and self.high is not None
        number = exact_text if exact else short_number
        if self.low.value == self.high.value:  # both ends closed: the set is not empty
            return f"{p.name} == {number(self.low.value)}"
        low = None if self.low == End(p.low) else self.low
        high = None if self.high == End(p.high) else self.high
        if high is None:
            assert low is not None, "the whole range: see whole"
            return f"{p.name} {'>' if low.open else '>='} {number(low.value)}"
        if low is None:
            return f"{p.name} {'<' if high.open else '<='} {number(high.value)}"
        return (f"{number(low.value)} {'<' if low.open else '<='} {p.name} "
                f"{'<' if high.open else '<='} {number(high.value)}")

    def interval(self) -> str:
        assert self.low is not None and self.high is not None
        return (f"{'(' if self.low.open else '['}{_num(self.low.value)}, "
                f"{_num(self.high.value)}{')' if self.high.open else ']'}")


def checks(automaton: ir.Automaton, discount: Discount | None = None) -> list[Check]:
    """Every check whose outcome depends on the values of rewards: P2 per level (and of the return discounted
    by ``discount``, when given) and the int32 range."""
    result = [Check(f"P2 for `{automaton.priority[level]}`", partial(p2_target, level=level),
                    Fraction(0), False) for level in p2_levels(automaton)]
    if discount is not None:
        result += [Check(f"P2 of the discounted return for `{automaton.priority[level]}`",
                         partial(p2_target, level=level), Fraction(0), False, discount)
                   for level in p2_levels(automaton)]
    base, exponent = ((automaton.model.base, automaton.model.exponent) if automaton.model is not None
                      else (DEFAULT_BASE, DEFAULT_EXPONENT))
    factor = Fraction(base) ** exponent
    for k, reward in enumerate(automaton.rewards):
        for sign in (1, -1):
            side = "upper" if sign > 0 else "lower"
            result.append(Check(f"the int32 range of `{reward}` (its {side} end)",
                                partial(range_target, k=k, sign=sign),
                                Fraction(range_limit(sign)) / factor, True))
    return result


def unsupported(low: ir.Automaton, high: ir.Automaton) -> str | None:
    """Why the parameter's place keeps the search from being exact (None when it is supported).

    ``low`` and ``high`` are the automaton at the two declared bounds; what is affine in the parameter
    differs between them only through the parameter.
    """
    if low.locations != high.locations:
        return "it appears in a rate (not yet: P1 would depend on it beyond a weight's sign)"
    if (low.inputs, low.assumptions, low.period, low.horizon, low.model) != \
            (high.inputs, high.assumptions, high.period, high.horizon, high.model):
        return "it sets an input bound, an assumption, the sample period, the horizon or the model"
    if [[(e.guard, e.target) for e in es] for es in low.edges] != [[(e.guard, e.target) for e in es]
                                                                   for es in high.edges] \
            or [c.guard for c in low.end_clauses] != [c.guard for c in high.end_clauses] \
            or (low.episode_ends, low.goal, low.collision) != (high.episode_ends, high.goal, high.collision):
        return "it appears in a guard (the runs would depend on it)"
    if low.requirements != high.requirements:
        return "it sets the bound of a `require` (the requirement would move with it)"
    if any(_maps(low, e).matrix != _maps(high, f).matrix for es, fs in zip(low.edges, high.edges)
           for e, f in zip(es, fs)) or \
            any(_end_map(low, c.updates).matrix != _end_map(high, d.updates).matrix
                for c, d in zip(low.end_clauses, high.end_clauses)):
        return "it scales a reward in an update (the rewards would not be affine in it)"
    rewards_move = (low.locations != high.locations or low.edges != high.edges
                    or low.end_clauses != high.end_clauses)
    if rewards_move and low.objective != high.objective:
        return "it is both an objective weight and in a rate or an update (the objective would be quadratic in it)"
    for level in p2_levels(low):
        watched = p2_target(low, level).watched
        if watched != p2_target(high, level).watched:
            return (f"whether a location penalises `{low.priority[level]}` changes between its bounds: "
                    "narrow them to one side of that change")
        # Watched at both bounds only through edges whose change of the reward moves with the parameter
        # (`s -= P` and `s += P` into one location, or `s -= P * x`): each of them penalises outside an
        # interval of values, so in between the location may penalise nothing, and the set of values
        # where the checks hold need not be an interval. Unwatched at both bounds stays unwatched in
        # between (each edge's least change is concave in the parameter).
        reward = low.priority[level]
        fixed = p2_target(_without_moving(low, high, reward), level).watched
        if any(w and not f and not _one_edge_penalises(low, high, reward, level, here)
               for here, (w, f) in enumerate(zip(watched, fixed))):
            return (f"whether a location penalises `{low.priority[level]}` may change between its bounds "
                    "(edges that lower it for some values of the parameter and not for others): narrow them "
                    "to values on one side of each change")
    return None


def _moving(low: ir.Automaton, high: ir.Automaton, e: ir.Edge, f: ir.Edge, reward: str) -> bool:
    """Whether the edge (``e`` at the low bound, ``f`` at the high one) changes ``reward`` by an amount
    that depends on the parameter."""
    k = low.rewards.index(reward)
    a, b = _maps(low, e), _maps(high, f)
    return a.is_translation and b.is_translation and a.offset[k] != b.offset[k]


def _without_moving(low: ir.Automaton, high: ir.Automaton, reward: str, keep: ir.Edge | None = None
                    ) -> ir.Automaton:
    """``low`` without the updates of the edges whose change of ``reward`` depends on the parameter,
    except ``keep``."""
    return dataclasses.replace(low, edges=tuple(
        tuple(dataclasses.replace(e, updates=()) if e is not keep and _moving(low, high, e, f, reward) else e
              for e, f in zip(es, fs)) for es, fs in zip(low.edges, high.edges)))


def _one_edge_penalises(low: ir.Automaton, high: ir.Automaton, reward: str, level: int, here: int) -> bool:
    """Whether one edge into location ``here`` lowers ``reward`` at both bounds by an amount whose part in
    the parameter reads no input (``s -= P``): it then lowers it at every value in between too (where it
    lowers it is a half-line), so the location penalises throughout."""
    k = low.rewards.index(reward)
    for es, fs in zip(low.edges, high.edges):
        for e, f in zip(es, fs):
            if e.target != here or not _moving(low, high, e, f, reward):
                continue
            if (_maps(high, f).offset[k] - _maps(low, e).offset[k]).variables():
                continue  # the parameter multiplies an input: where it lowers the reward need not be a half-line
            at_low = p2_target(_without_moving(low, high, reward, e), level).watched[here]
            at_high = p2_target(_without_moving(high, low, reward, f), level).watched[here]
            if at_low and at_high:
                return True
    return False


def p1_cuts(low: ir.Automaton, high: ir.Automaton, parameter: ir.Parameter, sentences: list[str]) -> list[_Cut]:
    """P1 as constraints on the parameter, which can only be a weight of the objective (rates do not
    depend on it): a pair high > low fails in a location for a positive weight of ``low`` when ``high``
    can decrease while ``low`` increases, and for a negative weight when both can decrease."""
    found: list[_Cut] = []
    name, span = parameter.name, parameter.high - parameter.low
    for location in low.locations:
        for a, first in enumerate(low.priority):
            for second in low.priority[a + 1:]:
                w0, w1 = low.objective.coefficient(second), high.objective.coefficient(second)
                slope = (w1 - w0) / span if span else Fraction(0)
                plus, minus = rate_conflicts(low, location, first, second)
                for conflict, sign in ((plus, 1), (minus, -1)):
                    if not conflict:
                        continue
                    # The weight must stay on the side of 0 where the conflict does no harm:
                    # sign·(w0 + slope·(p - low)) <= 0.
                    what = f"P1 in `{location.name}` ({first} > {second})"
                    if slope == 0:
                        if sign * w0 > 0:
                            found.append((True, None, False))
                            sentences.append(f"{what} fails whatever {name} is")
                        continue
                    root = parameter.low - w0 / slope
                    lower = sign * slope < 0
                    found.append((lower, root, False))
                    sentences.append(f"{what} needs {name} {'>=' if lower else '<='} {_num(root)}")
    return found


def synthesise(resolve: Resolve, parameter: ir.Parameter, discount: Discount | None = None) -> Synthesis:
    """The exact set of values of ``parameter`` in its bounds for which every check holds (P2 of the return
    discounted by ``discount`` too, when given).

    Raises :class:`Unfinished` when the worst-run search stops at its limit (or the discounted one does not go).
    """
    cuts: list[str] = []
    low, high = End(parameter.low), End(parameter.high)
    at_low, at_high = resolve(parameter.low), resolve(parameter.high)
    assert at_low is not None and at_high is not None
    low, high = _tighten(low, high, p1_cuts(at_low, at_high, parameter, cuts))
    if _is_empty(low, high):
        return Synthesis(parameter, None, None, parameter.low, tuple(cuts))
    # The lower end first (the least value satisfying every cut so far, until no check fails there),
    # then the upper end from the top down: the set is an interval, so every value between holds.
    for upwards in (True, False):
        while True:
            found = _cuts(resolve, parameter, low.value if upwards else high.value, cuts, discount)
            if not found:
                break
            new_low, new_high = _tighten(low, high, found)
            if _is_empty(new_low, new_high):
                # Show the checks at the best candidate: the value of the range nearest to what the cuts ask.
                best = high.value if new_low != low else low.value
                return Synthesis(parameter, None, None, best, tuple(cuts))
            if (new_low, new_high) == (low, high):
                break  # an open end that every failing check reaches exactly: see _tighten
            low, high = new_low, new_high
    return Synthesis(parameter, low, high, low.value, tuple(cuts))


def _is_empty(low: End, high: End) -> bool:
    return low.value > high.value or (low.value == high.value and (low.open or high.open))


#: A cut: the check holds only where ``p >= value`` (``lower``) or ``p <= value``, strictly when ``open``;
#: None for the value: the check fails at every value.
_Cut = tuple[bool, Fraction | None, bool]


def _tighten(low: End, high: End, found: list[_Cut]) -> tuple[End, End]:
    """The ends after the cuts. A cut that leaves an end where it is (a strict check reaching its bound
    exactly at an open end) proves that end: the check's convex worst value is below the bound inside."""
    for lower, value, is_open in found:
        if value is None:
            return End(high.value + 1), high
        end = End(value, is_open)
        if lower and (value, is_open) > (low.value, low.open):
            low = end
        elif not lower and (value, not is_open) < (high.value, not high.open):
            high = end
    return low, high


class Unresolved(RacError):
    """The file does not check at ``value`` of the parameter, a value within its bounds the search reached
    (a coefficient there beyond what a double holds, E0011): nothing to search there."""

    def __init__(self, value: Fraction) -> None:
        super().__init__(f"the file does not check at the value {value}")
        self.value = value


def _cuts(resolve: Resolve, parameter: ir.Parameter, value: Fraction, sentences: list[str],
          discount: Discount | None = None) -> list[_Cut]:
    """The oracle at ``value``: a cut from the worst run of every check that fails there."""
    automaton = resolve(value)
    if automaton is None:  # the bounds resolved; a value between them need not (E0011 of a tiny coefficient)
        raise Unresolved(value)
    space, _ = input_space(automaton)
    assert space is not None
    outs = moves(automaton, space)
    other: ir.Automaton | None = None
    found: list[_Cut] = []
    for check in checks(automaton, discount):
        worst = check.worst(automaton, outs, check.target(automaton))
        if worst is None or not check.violated(worst.value):
            continue
        if other is None:
            other, step = _second(resolve, parameter, value)
        if other is None and parameter.low == parameter.high:
            # `param P in [2, 2]` where the file does not check one unit above (P sets the period there): one
            # value, so no slope is needed: the check fails, and with it the only value
            found.append((True, None, False))
            sentences.append(f"at {parameter.name} = {_num(value)}, {check.what} fails")
            continue
        assert other is not None, "the other end of the bounds resolves"
        # The same run at a second value: its value is affine in the parameter, so two values fix it.
        here = check.value(automaton, space, worst, check.target(automaton))
        there = check.value(other, space, _transplant(worst, automaton, other), check.target(other))
        slope = (there - here) / step
        name = parameter.name
        if slope == 0:
            found.append((True, None, False))
            sentences.append(f"at {name} = {_num(value)}, {check.what} fails whatever {name} is")
            continue
        root = value + (check.bound - worst.value) / slope
        lower = slope < 0
        found.append((lower, root, check.strict))
        sign = (">" if lower else "<") + ("" if check.strict else "=")
        sentences.append(f"at {name} = {_num(value)}, {check.what} needs {name} {sign} {_num(root)}")
    return found


def _second(resolve: Resolve, parameter: ir.Parameter, value: Fraction) -> tuple[ir.Automaton | None, Fraction]:
    """The automaton at a second value, whose difference from ``value`` (the step, also returned) gives a run's
    slope: one unit above, or, where the file does not check there (``sa -= P * 1e308`` leaves what a double
    holds, E0011), the other end of the bounds, where it does (the callers resolved both). None only for a
    parameter of one value."""
    other = resolve(value + 1)
    if other is not None or parameter.low == parameter.high:
        return other, Fraction(1)
    step = (parameter.low if value == parameter.high else parameter.high) - value
    return resolve(value + step), step


def _value(automaton: ir.Automaton, space, worst: Worst, target: Target) -> Fraction:
    values, _ = replay(automaton, space, worst)
    return sum((w * v for w, v in zip(target.weights, values)), target.constant)


def _maps(automaton: ir.Automaton, edge: ir.Edge) -> Affine:
    return from_assignments(edge.updates, automaton.rewards)


def _end_map(automaton: ir.Automaton, updates: tuple[ir.Assignment, ...]) -> Affine:
    return from_assignments(updates, automaton.rewards)


def _transplant(worst: Worst, source: ir.Automaton, target: ir.Automaton) -> Worst:
    """The run ``worst`` of ``source`` as a run of ``target`` (the same automaton at another value of
    the parameter: the same edges and input classes, other update values)."""
    maps: dict[int, tuple[ir.Edge, Affine]] = {}
    steps = []
    for step in worst.steps:
        o = step.outcome
        if o.edge is not None:
            moved = maps.get(id(o.edge))
            if moved is None:
                index = next(i for i, e in enumerate(source.edges[o.source]) if e is o.edge)
                edge = target.edges[o.source][index]
                moved = maps[id(o.edge)] = (edge, _maps(target, edge))
            o = dataclasses.replace(o, edge=moved[0], edge_map=moved[1])
        if o.ending is not None:  # the end clauses of a sample that ends the run
            o = dataclasses.replace(o, ending=_transplant_end(o.ending, target))
        steps.append(dataclasses.replace(step, outcome=o))
    end = worst.end
    if end is not None:
        end = _transplant_end(end, target)
    return dataclasses.replace(worst, steps=steps, end=end)


def _transplant_end(end: EndOutcome, target: ir.Automaton) -> EndOutcome:
    """The same end clauses of ``target`` (the automaton at another value of the parameter)."""
    end_map = identity(len(target.rewards))
    for i in end.ends:
        end_map = then(end_map, _end_map(target, target.end_clauses[i].updates))
    return dataclasses.replace(end, end_map=end_map)


def risk_values(resolve: Resolve, parameter: ir.Parameter, bound: Fraction) -> list[Interval]:
    """The values of ``parameter`` in its bounds where ``require risk <= bound`` holds, exactly.

    R_goal, R_stall and R_crash (:mod:`~rac.check.analysis.incentives`) are each the best return over a
    set of runs that does not depend on the parameter (:func:`unsupported`), each run's return affine
    in it: convex and piecewise affine, recovered by :func:`~rac.check.analysis.piecewise.convex` from
    the witness runs (a run's slope: its return one unit further, :func:`_transplant`). The requirement
    holds where ``R_goal > R_crash``, ``R_stall > R_crash`` (p* < 1) and
    ``(R_goal - R_stall) <= bound * (R_goal - R_crash)``, as ``rac check`` decides it at one value.
    """
    low, high = parameter.low, parameter.high

    def incentives(value: Fraction) -> tuple[ir.Automaton, InputSpace, Incentives]:
        automaton = resolve(value)
        if automaton is None:  # the bounds resolved; a value between them need not (see _cuts)
            raise Unresolved(value)
        space, _ = input_space(automaton)
        assert space is not None
        result = analyse(automaton, space)
        if isinstance(result, IncentivesUnchecked):
            raise Unfinished(result.reason)
        assert result.incentives is not None, "`require risk` needs `goal when` (E1009)"
        return automaton, space, result.incentives

    def oracle(which: str) -> Callable[[Fraction], tuple[Fraction, Fraction]]:
        def at(value: Fraction) -> tuple[Fraction, Fraction]:
            automaton, space, here = incentives(value)
            run = getattr(here, which)
            assert run is not None
            other, step = _second(resolve, parameter, value)
            if other is None and low == high:
                # one value (`param P in [2, 2]`), where the file need not check one unit above (P sets the
                # bound of the requirement there): a function on one point needs no slope
                return run.value, Fraction(0)
            assert other is not None, "the other end of the bounds resolves"
            other_space, _ = input_space(other)
            assert other_space is not None
            now = _return(automaton, space, run.worst)
            later = _return(other, other_space, _transplant(run.worst, automaton, other))
            return run.value, (later - now) / step
        return at

    _, _, at_low = incentives(low)
    whole = [Interval(low, high)]
    if at_low.goal is None:
        return []
    if at_low.crash is None:
        return whole
    goal = convex(oracle("goal"), low, high)
    crash = convex(oracle("crash"), low, high)
    above = goal.combine(crash, Fraction(1), Fraction(-1)).where(True)  # R_goal > R_crash
    if at_low.stall is None:
        return above
    stall = convex(oracle("stall"), low, high)
    below_one = stall.combine(crash, Fraction(1), Fraction(-1)).where(True)  # p* < 1
    # (1 - bound) R_goal - R_stall + bound R_crash <= 0
    within = goal.combine(stall, 1 - bound, Fraction(-1)).combine(crash, Fraction(1), bound).where(False)
    return intersect(intersect(above, below_one), within)


def _return(automaton: ir.Automaton, space: InputSpace, worst: Worst) -> Fraction:
    """The objective at the end of the run ``worst`` (its return but for the objective's constant)."""
    values, _ = replay(automaton, space, worst)
    return sum((automaton.objective.coefficient(r) * v for r, v in zip(automaton.rewards, values)), Fraction(0))


def _num(value: Fraction) -> str:
    return short_number(value)


__all__ = ["Check", "End", "Synthesised", "Synthesis", "Unfinished", "Unresolved", "checks", "risk_values",
           "synthesise", "unsupported"]
