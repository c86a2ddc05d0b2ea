"""The proven bound on the objective's change per sample (rac.check.analysis.scale) against brute force."""

from __future__ import annotations

import dataclasses
import itertools
import random
from fractions import Fraction

import pytest
from hypothesis import given
from test_worst import SETTINGS, Case, cases

from rac import ir
from rac.check.analysis.scale import SampleChange, ScaleUnproven, sample_change_bound
from rac.compiler import compile_file, compile_text

EPSILON = Fraction(1, 10**6)  # grid points this close to a threshold stand in for an open end


def grid(automaton: ir.Automaton) -> list[dict[str, object]]:
    """Every valuation on a grid (thresholds, bounds, quarter steps, and next to each threshold) that
    ``assume`` allows."""
    axes: list[list[object]] = []
    for item in automaton.inputs:
        if item.kind == "bool":
            axes.append([False, True])
            continue
        assert item.low is not None and item.high is not None
        if item.kind == "int":
            axes.append([Fraction(v) for v in range(int(item.low), int(item.high) + 1)])
            continue
        points = {item.low + Fraction(k, 4) for k in range(int((item.high - item.low) * 4) + 1)}
        points |= {p + d for p in list(points) for d in (EPSILON, -EPSILON)}
        axes.append(sorted(p for p in points if item.low <= p <= item.high))
    names = [item.name for item in automaton.inputs]
    valuations = [dict(zip(names, combo)) for combo in itertools.product(*axes)]
    return [v for v in valuations if ir.evaluate_guard(automaton.assume, v)]


def weights(automaton: ir.Automaton) -> dict[str, Fraction]:
    return {r: automaton.objective.coefficient(r) for r in automaton.rewards}


def apply(updates: tuple[ir.Assignment, ...], r: dict[str, Fraction], x: dict[str, object]) -> None:
    for update in updates:
        r[update.reward] = update.value.evaluate({**x, **r})  # type: ignore[dict-item]


def sample(automaton: ir.Automaton, loc: int, r: dict[str, Fraction], held: dict[str, object],
           x: dict[str, object]) -> tuple[int, Fraction]:
    """One sample, exactly (the runtime semantics in Fractions): the new location and the objective's change."""
    w = weights(automaton)
    before = sum(w[k] * r[k] for k in r)
    for k, rate in zip(automaton.rewards, automaton.locations[loc].rates):
        r[k] += rate.scaled(automaton.period).evaluate(held)  # type: ignore[arg-type]
    for edge in automaton.edges[loc]:
        if ir.evaluate_guard(edge.guard, x):
            apply(edge.updates, r, x)
            loc = edge.target
            break
    return loc, sum(w[k] * r[k] for k in r) - before


def end_change(automaton: ir.Automaton, r: dict[str, Fraction], x: dict[str, object]) -> Fraction:
    w = weights(automaton)
    before = sum(w[k] * r[k] for k in r)
    for clause in automaton.end_clauses:
        if ir.evaluate_guard(clause.guard, x):
            apply(clause.updates, r, x)
    return sum(w[k] * r[k] for k in r) - before


def brute_force(automaton: ir.Automaton) -> SampleChange:
    """The largest |change| over one sample from every reachable location (the horizon aside), held
    and new inputs over the grid, rewards at 0 (translations do not read them). The accrual reads the
    held inputs only and the edge the new ones only, so the extremes of each are searched apart."""
    valuations = grid(automaton)
    zero = {k: Fraction(0) for k in automaton.rewards}
    reached, todo = {automaton.initial}, [automaton.initial]
    per_sample = Fraction(0)
    stay = dataclasses.replace(automaton, edges=tuple(() for _ in automaton.edges))
    still = dataclasses.replace(automaton, locations=tuple(
        dataclasses.replace(loc, rates=tuple(ir.Linear() for _ in loc.rates)) for loc in automaton.locations))
    while todo:
        loc = todo.pop()
        if not valuations:
            break
        accrued = [sample(stay, loc, dict(zero), held, held)[1] for held in valuations]
        moved = []
        for x in valuations:
            target, change = sample(still, loc, dict(zero), x, x)
            moved.append(change)
            if target not in reached:
                reached.add(target)
                todo.append(target)
        per_sample = max(per_sample, max(accrued) + max(moved), -(min(accrued) + min(moved)))
    at_end = max((abs(end_change(automaton, dict(zero), x)) for x in valuations), default=Fraction(0))
    return SampleChange(per_sample, at_end)


def translations_only(automaton: ir.Automaton) -> bool:
    maps = [e.updates for e in automaton.all_edges()] + [c.updates for c in automaton.end_clauses]
    return all(u.value.coefficient(u.reward) == 1 and all(n not in automaton.rewards or n == u.reward
                                                          for n in u.value.variables())
               for updates in maps for u in updates)


@SETTINGS
@given(cases())
def test_the_bound_holds_and_is_attained_without_resets(case: Case) -> None:
    automaton = case.automaton
    assert translations_only(automaton), case
    bound, brute = sample_change_bound(automaton), brute_force(automaton)
    for proven, found in ((bound.per_sample, brute.per_sample), (bound.at_end, brute.at_end)):
        assert found <= proven <= found + 8 * EPSILON, (case, bound, brute)


@SETTINGS
@given(cases(general=True))
def test_the_bound_holds_on_runs_with_resets(case: Case) -> None:
    """Resets and scalings are bounded with the proven reward ranges: every sample of random runs
    within the horizon (each ending where `episode ends when` holds) stays within the bound."""
    automaton = case.automaton
    try:
        bound = sample_change_bound(automaton)
    except ScaleUnproven:
        pytest.skip("no bound proved")
    valuations = grid(automaton)
    if not valuations:
        return
    rng = random.Random(0)
    for _ in range(30):
        loc, r, held = automaton.initial, {k: Fraction(0) for k in automaton.rewards}, None
        for _ in range(rng.randint(0, automaton.steps)):
            x = rng.choice(valuations)
            loc, change = sample(automaton, loc, r, x if held is None else held, x)
            held = x
            assert abs(change) <= bound.per_sample, (case, bound, change)
            if automaton.episode_ends is not None and ir.evaluate_guard(automaton.episode_ends, x):
                break  # the run ends at the first sample where `episode ends when` holds
        assert abs(end_change(automaton, r, rng.choice(valuations))) <= bound.at_end, (case, bound)


def test_the_driving_automaton() -> None:
    """Entering Unsafe while colliding costs 10 * (100 + 0.1): 1001; the end bonus 5 * 100."""
    bound = sample_change_bound(compile_file("stdlib/driving.ra").raise_for_errors())
    assert bound == SampleChange(Fraction(1001), Fraction(500))
    assert bound.step_bound(5) == 5 * 1001 + 500
    with pytest.raises(ValueError, match="at least one sample"):
        bound.step_bound(0)


def test_a_reset_uses_the_proven_range() -> None:
    """At the third sample r accrues to 3 (objective +2) and ``r = 0`` takes it back (-6): at most 4."""
    text = """automaton R {
    input a : bool
    reward r
    objective 2 * r
    sample every 1
    horizon 3
    initial location L { r' == 1 }
    edge L -> L when a do r = 0
}
"""
    automaton = compile_text(text, "r.ra").raise_for_errors()
    assert sample_change_bound(automaton) == SampleChange(Fraction(4), Fraction(0))
