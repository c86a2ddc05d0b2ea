"""A brute-force reference for :func:`rac.check.analysis.worst.maximise`, for tiny automata only.

It is written from the semantics, not from ``worst.py``: enumerate every run of every length
1..steps over concrete input valuations, simulate it forward with exact ``Fraction`` arithmetic,
and take the largest ``weights·r + constant`` over the instants spent in a watched location.

Semantics followed literally (language.md, and the analysis' reading of it):

- t = 0: in the initial location, every reward 0.
- sample 1: rewards accrue over (0, t_1] at the initial location's rates, evaluated with the
  inputs read at t_1 ("before the edge" instant); the one enabled edge (if any) is taken and its
  updates applied left to right ("after the edge"); if the run ends here, every
  ``at end`` clause enabled by the END's inputs applies, in order ("after end"); otherwise rewards accrue over
  (t_1, t_2] at the new location's rates with the inputs of t_1 held ("before the next sample",
  which is also the next sample's "before the edge" instant).
- sample k >= 2: the same without the first accrual.
- A run may also end at t = 0, before any sample. The end's inputs are its own
  (``end(inputs)``), free over every valuation ``assume`` allows.
- A sample whose inputs satisfy ``episode ends when`` ends the run there (the runtimes'
  ``step``): the ``at end`` clauses enabled by THAT sample's inputs apply, reading them; no
  ``end(inputs)`` with other inputs follows (the runtimes' ``end`` then changes nothing).
- With ``intermediates`` (the int32 range check's targets): also the values in between a
  sequence of updates, after each assignment but the last of an edge's updates ("mid-edge", in
  the edge's target) and of the enabled ``at end`` clauses' updates taken as one sequence
  ("mid-end"): the UPPAAL model stores each assignment.

Input valuations (built here, not with :class:`~rac.ir.inputs.InputSpace`): both values
of every boolean input; for a real input every guard threshold and bound, and the midpoint of
each open interval between them; every value of an int input. Those decide the guards. Numeric
inputs that rates or updates read also feed the arithmetic with the interval's two ends: the
value at a watched instant is affine in the inputs, so its supremum over an interval (where the
guards do not change) lies at an end of its closure.

The forward frontier merges identical (location, reward vector) states, which is exact: what
follows a sample depends on nothing else. Exponential in the horizon otherwise.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable
from dataclasses import dataclass
from fractions import Fraction

from rac import ir

ZERO = Fraction(0)
#: Refuse automata whose frontier would make the tests slow.
MAX_FRONTIER = 200_000


@dataclass
class Valuation:
    """A concrete input valuation: ``guards`` decides guards, ``values`` feeds the arithmetic."""

    guards: dict[str, object]
    values: dict[str, object]


def arithmetic_inputs(automaton: ir.Automaton) -> list[str]:
    """Numeric inputs read by a rate or by an update's right-hand side."""
    read: set[str] = set()
    for location in automaton.locations:
        for rate in location.rates:
            read.update(rate.variables())
    for edge in automaton.all_edges():
        for update in edge.updates:
            read.update(update.value.variables())
    for clause in automaton.end_clauses:
        for update in clause.updates:
            read.update(update.value.variables())
    return [i.name for i in automaton.inputs if not i.is_bool and i.name in read]


def _thresholds(guard: ir.Guard, name: str, out: set[Fraction]) -> None:
    if isinstance(guard, ir.BAtom):
        if guard.input == name:
            out.add(guard.threshold)
    elif isinstance(guard, ir.BNot):
        _thresholds(guard.operand, name, out)
    elif isinstance(guard, (ir.BAnd, ir.BOr)):
        for g in guard.operands:
            _thresholds(g, name, out)


def _choices(automaton: ir.Automaton, item: ir.Input, arithmetic: bool,
             extra: Iterable[Fraction] = ()) -> list[tuple[Fraction, list[Fraction]]]:
    """(value deciding the guards, values tried in the arithmetic) for one numeric input; ``extra``:
    more thresholds (those a query compares the input with, which no guard of the automaton has).

    Every guard compares the input with a constant, so guards are constant between consecutive
    thresholds: try each threshold, and the midpoint of each open interval between them (with
    the interval's two ends for the arithmetic). Integer inputs try every integer.
    """
    assert item.low is not None and item.high is not None
    if item.kind == "int":
        return [(Fraction(v), [Fraction(v)]) for v in range(int(item.low), int(item.high) + 1)]
    cuts: set[Fraction] = {item.low, item.high, *extra}
    named = (automaton.episode_ends, automaton.goal, automaton.collision)
    guards = [automaton.assume, *(e.guard for e in automaton.all_edges()),
              *(c.guard for c in automaton.end_clauses), *(g for g in named if g is not None)]
    for guard in guards:
        _thresholds(guard, item.name, cuts)
    points = sorted(c for c in cuts if item.low <= c <= item.high)
    result = [(p, [p]) for p in points]
    for a, b in zip(points, points[1:]):
        middle = (a + b) / 2
        result.append((middle, [a, middle, b] if arithmetic else [middle]))
    return result


def valuations(automaton: ir.Automaton, extra: Iterable[Fraction] = ()) -> list[Valuation]:
    """Every concrete valuation the reference tries at one sample (those ``assume`` allows); ``extra``:
    thresholds of a query, tried for every numeric input besides the guards' own."""
    arithmetic = set(arithmetic_inputs(automaton))
    names, options = [], []
    for item in automaton.inputs:
        names.append(item.name)
        if item.is_bool:
            options.append([(False, [False]), (True, [True])])
        else:
            options.append(_choices(automaton, item, item.name in arithmetic, extra))
    result = []
    for combo in itertools.product(*options):
        guards = {name: choice[0] for name, choice in zip(names, combo)}
        if not ir.evaluate_guard(automaton.assume, guards):
            continue
        for values in itertools.product(*(choice[1] for choice in combo)):
            result.append(Valuation(guards, dict(zip(names, values))))
    return result


# ---------------------------------------------------------------- one sample, literally
def accrue(automaton: ir.Automaton, location: int, r: tuple[Fraction, ...],
           x: dict[str, object]) -> tuple[Fraction, ...]:
    rates = automaton.locations[location].rates
    return tuple(r[i] + automaton.period * rates[i].evaluate(x) for i in range(len(r)))  # type: ignore[arg-type]


def assign(automaton: ir.Automaton, updates: tuple[ir.Assignment, ...], r: tuple[Fraction, ...],
           x: dict[str, object], between: list[tuple[Fraction, ...]] | None = None) -> tuple[Fraction, ...]:
    """Apply updates left to right; each sees the values the previous ones left. ``between``
    collects the values after each assignment but the last."""
    env: dict[str, object] = dict(x)
    env.update(zip(automaton.rewards, r))
    for i, update in enumerate(updates, start=1):
        env[update.reward] = update.value.evaluate(env)  # type: ignore[arg-type]
        if between is not None and i < len(updates):
            between.append(tuple(env[name] for name in automaton.rewards))  # type: ignore[misc]
    return tuple(env[name] for name in automaton.rewards)  # type: ignore[misc]


def edge_for(automaton: ir.Automaton, location: int, x: dict[str, object]) -> ir.Edge | None:
    enabled = [e for e in automaton.edges[location] if ir.evaluate_guard(e.guard, x)]
    assert len(enabled) <= 1, "the reference needs a deterministic automaton"
    return enabled[0] if enabled else None


def at_end(automaton: ir.Automaton, r: tuple[Fraction, ...], v: Valuation,
           between: list[tuple[Fraction, ...]] | None = None, applied: int | None = None) -> tuple[Fraction, ...]:
    """The enabled clauses' updates in order, as one sequence (``between``: see :func:`assign`);
    ``applied``: only its first so many."""
    updates = tuple(u for clause in automaton.end_clauses if ir.evaluate_guard(clause.guard, v.guards)
                    for u in clause.updates)
    return assign(automaton, updates[:applied] if applied is not None else updates, r, v.values, between)


def sample(automaton: ir.Automaton, location: int, r: tuple[Fraction, ...], v: Valuation, first: bool,
           intermediates: bool = False):
    """One sample from "before the edge" (or from t = 0 when ``first``).

    Returns the instants it passes through, as (name, location, rewards), and the state
    at "before the next sample" (the run's continuation). ``intermediates``: also "mid-edge",
    after each assignment of the edge but the last (in the edge's target).
    """
    instants = []
    if first:
        r = accrue(automaton, location, r, v.values)
        instants.append(("before-edge", location, r))
    edge = edge_for(automaton, location, v.guards)
    if edge is not None:
        between: list[tuple[Fraction, ...]] = []
        r = assign(automaton, edge.updates, r, v.values, between)
        location = edge.target
        if intermediates:
            instants += [("mid-edge", location, values) for values in between]
    instants.append(("after-edge", location, r))
    after = accrue(automaton, location, r, v.values)
    return instants, (location, after)


def ends_episode(automaton: ir.Automaton, v: Valuation) -> bool:
    """``episode ends when`` holds at a sample with these inputs: the run ends there."""
    return automaton.episode_ends is not None and ir.evaluate_guard(automaton.episode_ends, v.guards)


# ---------------------------------------------------------------- the brute force
def reference_max(automaton: ir.Automaton, weights, constant, watched, intermediates: bool = False) -> Fraction | None:
    """Max of ``weights·r + constant`` over every watched instant of every run (None: never watched); a
    run ends at the first sample whose inputs satisfy ``episode ends when``. ``intermediates``: the
    values in between each sequence of updates count too."""
    weights = tuple(Fraction(w) for w in weights)
    constant = Fraction(constant)
    steps = automaton.steps
    xs = valuations(automaton)
    best: list[Fraction | None] = [None]

    def see(location: int, r: tuple[Fraction, ...]) -> None:
        if watched[location]:
            value = constant + sum((w * v for w, v in zip(weights, r)), ZERO)
            if best[0] is None or value > best[0]:
                best[0] = value

    def see_ending(location: int, r: tuple[Fraction, ...], v: Valuation) -> None:
        between: list[tuple[Fraction, ...]] = []
        see(location, at_end(automaton, r, v, between))
        if intermediates:
            for values in between:
                see(location, values)

    def see_end(location: int, r: tuple[Fraction, ...]) -> None:
        for end in xs:  # the end's own inputs
            see_ending(location, r, end)

    l0 = automaton.initial
    zero = tuple(ZERO for _ in automaton.rewards)
    see(l0, zero)
    see_end(l0, zero)
    frontier = {(l0, zero)}
    for k in range(1, steps + 1):
        following = set()
        for location, r in frontier:
            for v in xs:
                instants, after = sample(automaton, location, r, v, first=k == 1, intermediates=intermediates)
                for _, where, values in instants:
                    see(where, values)
                if ends_episode(automaton, v):  # the run ends here, its end clauses on these inputs
                    see_ending(instants[-1][1], instants[-1][2], v)
                    continue
                see_end(*instants[-1][1:])
                if k < steps:
                    see(*after)  # "just before the next sample"
                    following.add(after)
        if len(following) > MAX_FRONTIER:
            raise RuntimeError(f"reference frontier too large ({len(following)} states)")
        frontier = following
    return best[0]


def simulate(automaton: ir.Automaton, run: list[Valuation], instant: str,
             end: Valuation | None = None, applied: int | None = None) -> tuple[int, tuple[Fraction, ...]]:
    """Location and rewards at ``instant`` of the run's last sample (a counterexample replay).

    ``instant`` is one of before-edge (first sample only), after-edge, after-end (with the
    ``end`` inputs), before-next (or continue, the same point), and, after ``applied`` assignments
    of a sequence of updates, mid-edge (the last sample's edge's) or mid-end (the ``at end`` ones).
    """
    location, r = automaton.initial, tuple(ZERO for _ in automaton.rewards)
    if instant in ("after-end", "mid-end"):
        assert end is not None and (instant == "after-end" or applied is not None)
        if run:
            location, r = simulate(automaton, run, "after-edge")
        return location, at_end(automaton, r, end, applied=applied if instant == "mid-end" else None)
    if not run:
        return location, r
    for k, v in enumerate(run, start=1):
        if k == len(run) and instant == "mid-edge":
            assert applied is not None
            if k == 1:
                r = accrue(automaton, location, r, v.values)
            edge = edge_for(automaton, location, v.guards)
            assert edge is not None and 0 < applied < len(edge.updates)
            return edge.target, assign(automaton, edge.updates[:applied], r, v.values)
        instants, after = sample(automaton, location, r, v, first=k == 1)
        if k < len(run):
            location, r = after
            continue
        if instant in ("before-next", "continue"):
            return after
        for name, where, values in instants:
            if name == instant:
                return where, values
    raise ValueError(f"unknown instant {instant!r}")
