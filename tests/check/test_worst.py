"""The worst-run engines against a brute-force reference, on random tiny automata.

Automata are generated as `.ra` text and compiled by the real front end. They are deterministic
by construction: every location partitions the input *cells* (a valuation of the boolean inputs,
times one side of the numeric input's threshold) among its edges, and a cell left out means
"stay". A `*` edge, when drawn, claims the same cells in every location but its target.
"""

from __future__ import annotations

import itertools
import os
from dataclasses import dataclass
from fractions import Fraction

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from reference import Valuation, ends_episode, reference_max, simulate

from rac import ir
from rac.check.analysis.affine import moves
from rac.check.analysis.priority import replay
from rac.check.analysis.worst import (
    AFTER_EDGE,
    AFTER_END,
    BEFORE_EDGE,
    BEFORE_NEXT,
    CONTINUE,
    MID_EDGE,
    MID_END,
    Target,
    Worst,
    maximise,
    maximise_generic,
    maximise_translations,
)
from rac.compiler import compile_text
from rac.ir.inputs import InputSpace

SETTINGS = settings(max_examples=int(os.environ.get("RAC_EXAMPLES", "100")), deadline=None,
                    derandomize=not os.environ.get("RAC_EXAMPLES"),
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def num(value: Fraction) -> str:
    value = Fraction(value)
    if value.denominator == 1:
        return str(value.numerator)
    return f"{value.numerator}/{value.denominator}"


small = st.builds(Fraction, st.integers(-2, 2), st.sampled_from([1, 2]))
offsets = st.builds(Fraction, st.integers(-3, 3), st.sampled_from([1, 2]))


@dataclass
class Case:
    text: str
    automaton: ir.Automaton
    target: Target

    def __repr__(self) -> str:
        return f"Case(target={self.target!r}, text=\n{self.text})"


@st.composite
def numeric_inputs(draw):
    """None, or (kind, low, high, threshold, (op, negated op), used in rates, used in updates)."""
    if not draw(st.booleans()):
        return None
    kind = draw(st.sampled_from(["real", "real", "int"]))
    low = draw(st.sampled_from([-2, 0]))
    high = draw(st.sampled_from([1, 2, 3]))
    threshold = draw(st.sampled_from(sorted({Fraction(low), Fraction(high), Fraction(1), Fraction(1, 2)})))
    ops = draw(st.sampled_from([("<", ">="), ("<=", ">"), ("==", "!=")]))
    in_rates = draw(st.booleans())
    in_updates = draw(st.booleans())
    return kind, low, high, threshold, ops, in_rates, in_updates


@st.composite
def cases(draw, general: bool = False, ending: bool = False):
    """A random tiny automaton and target; ``ending``: always with `at end` clauses and `episode ends when`.
    Half the targets also watch the values in between a sequence of updates (the int32 range check's)."""
    intermediates = draw(st.booleans())
    n_loc = draw(st.integers(2, 3))
    bools = ["a", "b"][: draw(st.integers(1, 2))]
    rewards = ["p", "q"][: draw(st.integers(1, 2))]
    numeric = draw(numeric_inputs())
    # A second numeric input that only rates read (never a guard): boxes of two inputs.
    second = numeric is not None and numeric[5] and draw(st.booleans())
    locs = [f"L{i}" for i in range(n_loc)]
    # Numeric arithmetic multiplies the reference's branching: keep those horizons short.
    arithmetic = numeric is not None and (numeric[5] or numeric[6])
    steps = draw(st.integers(1, (2 if second else 3) if arithmetic else 5))
    period = draw(st.sampled_from([Fraction(1), Fraction(1, 2)]))
    initial = draw(st.integers(0, n_loc - 1))

    # Cells: conjunctions of literals that partition the input space.
    literal_sets = [[f"{b}", f"!{b}"] for b in bools]
    if numeric is not None:
        _, _, _, threshold, (op, negated), _, _ = numeric
        literal_sets.append([f"x {op} {num(threshold)}", f"x {negated} {num(threshold)}"])
    cells = [" && ".join(combo) for combo in itertools.product(*literal_sets)]

    def guard(chosen: list[int]) -> str:
        if len(chosen) == len(cells):
            return "true"
        return " || ".join(f"({cells[i]})" for i in sorted(chosen))

    def rate() -> str:
        text = num(draw(small))
        if numeric is not None and numeric[5] and draw(st.booleans()):
            text += f" + {draw(st.sampled_from(['1', '-1', '1/2']))}*x"
        if second and draw(st.booleans()):
            text += f" + {draw(st.sampled_from(['1', '-1']))}*y"
        return text

    def update() -> str:
        r = draw(st.sampled_from(rewards))
        other = draw(st.sampled_from(rewards))
        forms = ["plus", "pluseq", "minuseq"]
        if numeric is not None and numeric[6]:
            forms.append("input")
        if general:
            forms += ["zero", "half", "other", "flip"]
        form = draw(st.sampled_from(forms))
        c = num(draw(offsets))
        if form == "plus":
            return f"{r} = {r} + {c}"
        if form == "pluseq":
            return f"{r} += {c}"
        if form == "minuseq":
            return f"{r} -= {c}"
        if form == "input":
            return f"{r} = {r} + {draw(st.sampled_from(['1', '-1']))}*x + {c}"
        if form == "zero":
            return f"{r} = 0"
        if form == "half":
            return f"{r} = {r} / 2"
        if form == "flip":
            return f"{r} = {c} - {r}"
        return f"{r} = {other} + 1"

    def updates() -> str:
        items = [update() for _ in range(draw(st.integers(0, 3 if intermediates else 2)))]
        return f" do {', '.join(items)}" if items else ""

    lines = ["automaton Random {"]
    for b in bools:
        lines.append(f"    input {b} : bool")
    if numeric is not None:
        kind, low, high = numeric[:3]
        lines.append(f"    input x : {kind} in [{low}, {high}]")
    if second:
        lines.append("    input y : real in [-1, 1]")
    if len(cells) > 1 and draw(st.booleans()):
        excluded = draw(st.lists(st.integers(0, len(cells) - 1), min_size=1, max_size=len(cells) - 1,
                                 unique=True))
        lines.append(f"    assume !({guard(excluded)})")
    lines.append(f"    reward {', '.join(rewards)}")
    lines.append(f"    priority {' > '.join(rewards)}")
    lines.append(f"    objective {' + '.join(rewards)}")
    lines.append(f"    sample every {num(period)}")
    lines.append(f"    horizon {num(steps * period)}")
    for i, name in enumerate(locs):
        flows = "; ".join(f"{r}' == {rate()}" for r in rewards)
        lines.append(f"    {'initial ' if i == initial else ''}location {name} {{ {flows} }}")
    star = None
    if draw(st.booleans()):
        star_target = draw(st.integers(0, n_loc - 1))
        star_cells = draw(st.lists(st.integers(0, len(cells) - 1), min_size=1, max_size=len(cells), unique=True))
        star = (star_target, set(star_cells))
        lines.append(f"    edge * -> {locs[star_target]} when {guard(star_cells)}{updates()}")
    for i, name in enumerate(locs):
        free = [c for c in range(len(cells)) if star is None or star[0] == i or c not in star[1]]
        # Each free cell: stay (None) or go to a target; cells with the same target share one edge.
        choice = {c: draw(st.sampled_from([None, *range(n_loc)])) for c in free}
        for target in range(n_loc):
            chosen = [c for c in free if choice[c] == target]
            if chosen:
                lines.append(f"    edge {name} -> {locs[target]} when {guard(chosen)}{updates()}")
    for _ in range(draw(st.integers(1 if ending else 0, 2))):
        chosen = draw(st.lists(st.integers(0, len(cells) - 1), min_size=1, max_size=len(cells), unique=True))
        items = [update() for _ in range(draw(st.integers(1, 2)))]
        when = "" if len(chosen) == len(cells) else f" when {guard(chosen)}"
        lines.append(f"    at end{when} do {', '.join(items)}")
    # A third of the cases (every one with `ending`): runs end where `episode ends when` holds.
    if ending or draw(st.integers(0, 2)) == 0:
        chosen = draw(st.lists(st.integers(0, len(cells) - 1), min_size=1, max_size=len(cells), unique=True))
        lines.append(f"    episode ends when {guard(chosen)}")
    lines.append("}")
    text = "\n".join(lines) + "\n"
    result = compile_text(text, "random.ra", analyse=False)
    assert result.automaton is not None, (text, result.diagnostics)
    automaton = result.automaton
    weights = tuple(draw(st.lists(small, min_size=len(rewards), max_size=len(rewards))))
    constant = draw(st.sampled_from([Fraction(0), Fraction(1), Fraction(-1), Fraction(1, 2)]))
    watched = draw(st.lists(st.booleans(), min_size=n_loc, max_size=n_loc))
    if not any(watched):  # mostly watch something (an unwatched automaton is a one-liner)
        watched[draw(st.integers(-1, n_loc - 1))] = True
    watched = tuple(watched)
    return Case(text, automaton, Target(weights, constant, watched, intermediates))


# ---------------------------------------------------------------- helpers
def value_of(worst: Worst | None) -> Fraction | None:
    return None if worst is None else worst.value


def check_counterexample(automaton: ir.Automaton, space: InputSpace, worst: Worst, target: Target) -> None:
    """The worst run is a real run that reaches exactly the reported value in a watched location."""
    def functional(values) -> Fraction:
        return target.constant + sum((w * v for w, v in zip(target.weights, values)), Fraction(0))

    values, _ = replay(automaton, space, worst)
    assert functional(values) == worst.value
    assert (worst.applied is not None) == (worst.instant in (MID_EDGE, MID_END))
    assert target.intermediates or worst.applied is None
    l0 = automaton.initial
    end = None
    if worst.instant in (AFTER_END, MID_END):
        assert worst.end is not None
        guards = space.valuation(worst.end.cls)
        end = Valuation(guards, {**guards, **worst.end_inputs})
    if not worst.steps:
        assert target.watched[l0]
        if end is None:
            assert worst.value == target.constant
        else:
            assert functional(simulate(automaton, [], worst.instant, end, worst.applied)[1]) == worst.value
        return
    here = l0
    for i, step in enumerate(worst.steps, start=1):
        assert step.sample == i
        assert step.outcome.source == here
        assert (step.instant == CONTINUE) == (i < len(worst.steps))
        here = step.outcome.target
    assert len(worst.steps) <= automaton.steps
    assert worst.instant == worst.steps[-1].instant or (
        worst.instant in (AFTER_END, MID_END) and worst.steps[-1].instant == AFTER_EDGE)
    # Replay independently: the reference simulator on the concrete inputs of each step.
    run = []
    for step in worst.steps:
        guards = space.valuation(step.outcome.cls)
        run.append(Valuation(guards, {**guards, **step.inputs}))
    # a run ends at the first sample where `episode ends when` holds: none goes on after one
    assert not any(ends_episode(automaton, v) for v in run[:-1])
    if ends_episode(automaton, run[-1]):
        assert worst.instant != BEFORE_NEXT
        if end is not None:  # the run ended at that sample: its end clauses read the sample's inputs
            assert (end.guards, end.values) == (run[-1].guards, run[-1].values)
    where, rewards = simulate(automaton, run, worst.instant, end, worst.applied)
    assert where == (l0 if worst.instant == BEFORE_EDGE else here)
    assert target.watched[where]
    assert functional(rewards) == worst.value
    assert list(rewards) == list(values)


def check_case(case: Case) -> None:
    automaton, target = case.automaton, case.target
    space = InputSpace(automaton)
    outs = moves(automaton, space)
    worst = maximise(automaton, outs, target)
    expected = reference_max(automaton, target.weights, target.constant, target.watched, target.intermediates)
    assert value_of(worst) == expected, case.text
    if worst is not None:
        check_counterexample(automaton, space, worst, target)


def is_translation_only(automaton: ir.Automaton) -> bool:
    outs = moves(automaton, InputSpace(automaton))
    return outs.translations_only


# ---------------------------------------------------------------- properties
@SETTINGS
@given(cases())
def test_translation_engine_matches_reference(case: Case) -> None:
    assert is_translation_only(case.automaton)
    check_case(case)


@SETTINGS
@given(cases(general=True))
def test_maximise_with_general_updates_matches_reference(case: Case) -> None:
    check_case(case)


@SETTINGS
@given(cases())
def test_generic_engine_agrees_with_translation_engine(case: Case) -> None:
    automaton, target = case.automaton, case.target
    space = InputSpace(automaton)
    outs = moves(automaton, space)
    fast = maximise_translations(automaton, outs, target)
    slow = maximise_generic(automaton, outs, target)
    assert value_of(fast) == value_of(slow), case.text
    for worst in (fast, slow):
        if worst is not None:
            check_counterexample(automaton, space, worst, target)


@SETTINGS
@given(cases(ending=True))
def test_end_clauses_at_an_episode_ending_match_reference(case: Case) -> None:
    """`at end` clauses with `episode ends when`: a run that the condition ends applies the clauses
    enabled by that sample's inputs, on those inputs; any other end takes inputs of its own. Both
    engines against the brute force (the fast one only where every update is a translation)."""
    automaton, target = case.automaton, case.target
    space = InputSpace(automaton)
    outs = moves(automaton, space)
    expected = reference_max(automaton, target.weights, target.constant, target.watched, target.intermediates)
    engines = [maximise_generic] + ([maximise_translations] if outs.translations_only else [])
    for engine in engines:
        worst = engine(automaton, outs, target)
        assert value_of(worst) == expected, (engine.__name__, case.text)
        if worst is not None:
            check_counterexample(automaton, space, worst, target)


@SETTINGS
@given(cases(general=True, ending=True))
def test_end_clauses_at_an_episode_ending_with_general_updates_match_reference(case: Case) -> None:
    check_case(case)


def test_reference_on_the_driving_automaton_by_hand() -> None:
    """The reference itself, on a case worked out by hand (see test_priority.py):
    Normal for 4 samples, Unsafe at the 5th, then the end bonus: 16*0.5 - 10*100 + 500."""
    from rac.lang.resources import stdlib_file

    text = stdlib_file("driving.ra").read_text(encoding="utf-8").replace("horizon 30 ", "horizon 0.5 ")
    automaton = compile_ir(text)
    weights = tuple(automaton.objective.coefficient(r) for r in automaton.rewards)
    unsafe = tuple(name == "Unsafe" for name in automaton.location_names)
    assert reference_max(automaton, weights, 0, unsafe) == -492
    # Lowest comfort: into Uncomfortable at sample 1 (co = 0.1), then -0.1 per sample.
    assert reference_max(automaton, (0, 0, -1), 0, (True,) * 4) == Fraction(3, 10)
    space = InputSpace(automaton)
    worst = maximise(automaton, moves(automaton, space), Target(weights, Fraction(0), unsafe))
    assert worst is not None and worst.value == -492


# ---------------------------------------------------------------- regressions
def compile_ir(text: str) -> ir.Automaton:
    result = compile_text(text, "case.ra", analyse=False)
    assert result.automaton is not None, result.diagnostics
    return result.automaton


HUGE = """
automaton Huge {
    input a : bool
    reward p
    objective p
    sample every 1
    horizon 3
    initial location L0 { p' == 1 }
    location L1 { p' == -1 }
    edge L0 -> L1 when a do p = p - 100000000000000000000000
    edge L1 -> L0 when !a
}
"""


@pytest.mark.parametrize("target", [
    Target((Fraction(1),), Fraction(0), (False, True)),
    Target((Fraction(-1),), Fraction(0), (True, True)),
    Target((Fraction(1),), Fraction(-10**30), (True, True)),
])
def test_huge_values_are_exact(target: Target) -> None:
    """Regression: beyond ±2^62 the translation engine took real values for 'unreachable'."""
    automaton = compile_ir(HUGE)
    space = InputSpace(automaton)
    outs = moves(automaton, space)
    expected = reference_max(automaton, target.weights, target.constant, target.watched)
    for engine in (maximise, maximise_translations, maximise_generic):
        worst = engine(automaton, outs, target)
        assert worst is not None and worst.value == expected
        check_counterexample(automaton, space, worst, target)


def test_assume_excluding_everything_leaves_only_the_start() -> None:
    """Regression: the translation engine crashed on locations without outcomes."""
    automaton = compile_ir(HUGE.replace("reward p", "assume a && !a\n    reward p"))
    outs = moves(automaton, InputSpace(automaton))
    assert not any(outs.samples)
    for engine in (maximise, maximise_translations, maximise_generic):
        assert engine(automaton, outs, Target((Fraction(1),), Fraction(3), (True, True))) == Worst(Fraction(3))
        assert engine(automaton, outs, Target((Fraction(1),), Fraction(3), (False, True))) is None
    assert reference_max(automaton, (1,), 3, (True, True)) == 3
