"""`param` declarations: the exact set of values for which every check holds (issue 14, one parameter)."""

from __future__ import annotations

import re
from fractions import Fraction
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rac import ir
from rac.check.analysis.synthesis import Unresolved, synthesise
from rac.check.resolve import Resolver
from rac.compiler import compile_text
from rac.core.numbers import exact_text
from rac.lang.parser import parse_text

ROOT = Path(__file__).resolve().parents[2]
DRIVING = (ROOT / "stdlib" / "driving.ra").read_text(encoding="utf-8")
CONST = "const PENALTY = 100"
assert CONST in DRIVING


def driving(declaration: str) -> str:
    """stdlib/driving.ra (horizon 30 s) with its penalty declared as ``declaration``."""
    return DRIVING.replace(CONST, declaration)


def codes(result) -> list[str]:
    return [d.code for d in result.diagnostics]


def test_driving_penalty_is_synthesised_exactly():
    result = compile_text(driving("param PENALTY in [0, 1000]"), "driving.ra")
    assert result.ok, [d.message for d in result.diagnostics]
    assert result.proved[0] == ("synthesised: PENALTY >= 98 (every check holds for PENALTY in [98, 1000]); "
                               "checked with PENALTY = 98")
    # The file is checked as if it said `const PENALTY = 98`: the same proofs.
    at_98 = compile_text(driving("const PENALTY = 98"), "driving.ra")
    assert at_98.ok
    assert result.proved[1:] == at_98.proved
    assert result.automaton is not None and at_98.automaton is not None
    assert result.automaton.edges == at_98.automaton.edges
    # What the targets are compiled from carries the value too.
    assert ("PENALTY", 98) in result.automaton.constants


def test_a_set_of_one_value_is_written_as_an_equation():
    # P2 needs PENALTY >= 98, the declaration allows at most 98 (it said `PENALTY >= 98`, as if more passed)
    result = compile_text(driving("param PENALTY in [0, 98]"), "driving.ra")
    assert result.ok, [d.message for d in result.diagnostics]
    assert result.proved[0] == ("synthesised: PENALTY == 98 (every check holds for PENALTY in [98, 98]); "
                               "checked with PENALTY = 98")
    assert result.synthesis is not None and result.synthesis.inequalities == ("PENALTY == 98",)


def test_one_less_fails_p2():
    result = compile_text(driving("const PENALTY = 97"), "driving.ra")
    assert codes(result) == ["E0402"]


def test_decimal_bounds_and_an_upper_end():
    # A penalty the objective also weighs: too large a weight on `pr` lets progress compensate.
    text = SMALL.format(param="param W in [0.5, 20.5]", penalty="6", weight="W")
    result = compile_text(text, "small.ra")
    assert result.ok, [d.message for d in result.diagnostics]
    # 10 * (5 - 6) + W * 5 <= 0 at the worst instant (5 s in `Ok`, then `Bad`).
    assert result.proved[0] == ("synthesised: W <= 2 (every check holds for W in [0.5, 2]); "
                               "checked with W = 0.5")


def test_empty_set_shows_the_counterexample():
    result = compile_text(SMALL.format(param="param P in [1, 5]", penalty="P", weight="1"), "small.ra")
    assert codes(result) == ["E0406", "E0402"]
    empty = result.diagnostics[0]
    assert "no value of parameter `P` in [1, 5] passes every check" in empty.message
    assert any("needs P >= 5.5" in str(n) for n in empty.notes)
    # The counterexample is shown at the best candidate, the top of the range.
    assert "at P = 5 follow" in str(empty.notes[-1])
    assert "penalise `sa` by at least 0.5 more" in result.diagnostics[1].hints[0]


def test_reversed_bounds_unused_and_second_parameter():
    reversed_ = compile_text(SMALL.format(param="param P in [5, 1]", penalty="P", weight="1"), "small.ra")
    assert codes(reversed_) == ["E0409"]
    unused = compile_text(SMALL.format(param="param Q in [1, 5]", penalty="30", weight="1"), "small.ra")
    assert unused.ok and codes(unused) == ["W0408"]
    two = compile_text(SMALL.format(param="param P in [1, 50]\n    param Q in [1, 5]", penalty="P",
                                    weight="Q"), "small.ra")
    # A penalty and a weight together: the objective would be quadratic in them.
    assert codes(two) == ["E0407"]
    assert "`P` cannot be synthesised here: with several parameters" in two.diagnostics[0].message


def test_a_parameter_declared_twice_is_named_a_parameter():
    # E0102 called the first `param P` "a constant" (the checker's kind for it), which the file never declares
    twice = compile_text(driving("param PENALTY in [0, 500]\n    param PENALTY in [0, 900]"), "twice.ra")
    assert codes(twice) == ["E0102"]
    assert twice.diagnostics[0].message == "`PENALTY` is already declared (as a parameter)"
    constant = compile_text(driving("const PENALTY = 100\n    param PENALTY in [0, 900]"), "mixed.ra")
    assert constant.diagnostics[0].message == "`PENALTY` is already declared (as a constant)"


def test_parameter_in_a_guard_is_refused():
    text = SMALL.format(param="param P in [1, 50]", penalty="P", weight="1").replace(
        "input bad : bool", "input bad : bool\n    input d : real in [0, 100]").replace(
        "when bad", "when bad && d < P").replace("when !bad", "when !(bad && d < P)")
    result = compile_text(text, "small.ra")
    assert codes(result) == ["E0407"]
    assert "guard" in result.diagnostics[0].message


def test_a_parameter_at_whose_bound_the_file_does_not_check_is_e0407():
    # `sample every P` with P in [1, 100]: at P = 100 the horizon is no whole number of periods, and an
    # input bound `5 - P` is reversed at P = 10; both ended `rac check` with an internal error (exit 3)
    period = SMALL.format(param="param P in [1, 100]", penalty="10", weight="1").replace(
        "sample every 1", "sample every P")
    result = compile_text(period, "period.ra")
    assert codes(result) == ["E0407"]
    assert result.diagnostics[0].message.endswith("the file does not check at P = 100, the high end of its bounds")
    assert [n.message for n in result.diagnostics[0].notes] == [
        "at P = 100: error[E0206]: the horizon (5 s) is not a whole number of sample periods (100 s)"]
    bound = SMALL.format(param="param P in [0, 10]", penalty="P", weight="1").replace(
        "input bad : bool", "input bad : bool\n    input d : real in [0, 5 - P]")
    result = compile_text(bound, "bound.ra")
    assert codes(result) == ["W0303", "E0407"]  # `d` is unused: the bound is the point
    assert "error[E0205]: empty range [0, -5] for `d`" in result.diagnostics[1].notes[0].message


def test_a_parameter_whose_file_does_not_check_one_unit_above_is_searched():
    # `sa -= 1 + P * 6e307` with P in [0, 1]: a check failing at P = 1 (the int32 range) was measured one unit
    # above, where the penalty leaves what a double holds (E0011), and `rac check` ended with an internal error
    # (AssertionError in synthesis._cuts). The other end of the bounds gives the slope as well: the set is the
    # one of `sa -= 1 + Q` with Q = P * 6e307.
    scaled = compile_text(SMALL.format(param="param P in [0, 1]", penalty="(1 + P * 6e307)", weight="1"), "s.ra")
    plain = compile_text(SMALL.format(param="param Q in [0, 6e307]", penalty="(1 + Q)", weight="1"), "p.ra")
    assert scaled.ok and plain.ok, [d.message for d in (*scaled.diagnostics, *plain.diagnostics)]
    assert plain.synthesis is not None and plain.synthesis.inequalities == ("9 / 2 <= Q < 715827883 / 10000",)
    factor = 6 * Fraction(10) ** 307
    assert scaled.synthesis is not None and scaled.synthesis.inequalities == (
        f"{exact_text(Fraction(9, 2) / factor)} <= P < {exact_text(Fraction(715827883, 10000) / factor)}",)
    assert scaled.synthesis.values == (("P", Fraction(9, 2) / factor),)


def test_a_value_between_the_bounds_where_the_file_does_not_check_is_a_diagnostic():
    """Where the file does not check at a value the search tries between its bounds (a coefficient too small for
    a double there: E0011), the search stops with Unresolved, which rac check reports as E0407 (it asserted)."""
    node = parse_text(driving("param PENALTY in [0, 1000]"), "driving.ra").automata[0]
    parameter = ir.Parameter("PENALTY", Fraction(0), Fraction(1000), Fraction(0))

    def resolve(value: Fraction) -> ir.Automaton | None:  # the file checks at the bounds and one unit above them
        return Resolver(node, {"PENALTY": value}).run() if value in (0, 1, 1000, 1001) else None

    with pytest.raises(Unresolved) as stopped:
        synthesise(resolve, parameter)
    assert stopped.value.value == 98  # P2's cut at PENALTY = 0 (test_driving_penalty_is_synthesised_exactly)


def test_a_parameter_of_one_value_where_the_search_cannot_go_is_e0406():
    # `param P in [2, 2]` with `sample every P`: the file at its two bounds is one file, so nothing showed that P
    # sets the period, and where a check fails the search measures it one unit above (P = 3: 4 s is no whole
    # number of 3 s periods): `rac check` ended with an internal error (AssertionError). One value: it fails.
    text = SMALL.format(param="param P in [2, 2]", penalty="1", weight="1").replace(
        "sample every 1", "sample every P").replace("horizon 5", "horizon 4")
    result = compile_text(text, "one.ra")
    assert codes(result) == ["E0406", "E0402"]
    assert "at P = 2, P2 for `sa` fails" in [n.message for n in result.diagnostics[0].notes]
    # where every check holds, the one value passes, as before
    passing = compile_text(text.replace("sa - 1", "sa - 100"), "one.ra")
    assert passing.ok and passing.proved[0].startswith("synthesised: every check holds for every value of P in [2, 2]")


def test_a_parameter_in_a_file_with_too_many_input_classes_is_e0306():
    # The searches read the input classes: with more than the checks take (E0306), `rac check` ended with
    # an internal error (AssertionError in the synthesis) instead of E0306, which the file has without `param`
    many = "\n    ".join(f"input b{i} : bool" for i in range(21))
    text = SMALL.format(param="param P in [0, 100]", penalty="P", weight="1").replace("input bad : bool", many)
    text = text.replace("when bad", "when " + " && ".join(f"b{i}" for i in range(21))).replace(
        "when !bad", "when !(" + " && ".join(f"b{i}" for i in range(21)) + ")")
    assert codes(compile_text(text, "many.ra")) == ["E0306"]
    assert codes(compile_text(text.replace("param P in [0, 100]", "const P = 0"), "many.ra")) == ["E0306"]


SMALL = """automaton Small {{
    input bad : bool
    {param}
    reward sa, pr
    priority sa > pr
    objective 10 * sa + {weight} * pr
    sample every 1
    horizon 5
    initial location Ok {{ sa' == 1; pr' == 1 }}
    location Bad {{ sa' == 0; pr' == 1 }}
    edge * -> Bad when bad do sa = sa - {penalty}
    edge * -> Ok when !bad
}}
"""


# ---------------------------------------------------------------- against brute force
GUARDS = {2: ["a", "!a"], 3: ["a", "!a && b", "!a && !b"]}


@st.composite
def small_automata(draw) -> tuple[str, Fraction, Fraction]:
    """A deterministic automaton of 2-3 locations and a short horizon, with parameter P either in
    the penalties of `sa` or as the objective's weight of `pr`; and P's bounds."""
    n = draw(st.sampled_from([2, 3]))
    in_updates = draw(st.booleans())
    low = Fraction(draw(st.integers(1 if in_updates else 0, 4)))
    high = low + draw(st.integers(0, 8))
    rate = st.integers(-2, 2)
    lines = ["automaton S {", "    input a : bool", "    input b : bool",
             f"    param P in [{low}, {high}]", "    reward sa, pr",
             f"    priority {draw(st.sampled_from(['', 'strict ']))}sa > pr",
             f"    objective {draw(st.integers(1, 4))} * sa + {'1' if in_updates else 'P'} * pr",
             "    sample every 1", f"    horizon {draw(st.integers(2, 4))}"]
    for k in range(n):
        lines.append(f"    {'initial ' if k == 0 else ''}location L{k} {{ sa' == {draw(rate)}; "
                     f"pr' == {draw(rate)} }}")
    for k, guard in enumerate(GUARDS[n]):
        amount = draw(st.sampled_from(["P", "2 * P", "P + 1"]) if in_updates else st.integers(0, 6))
        lines.append(f"    edge * -> L{k} when {guard} do sa = sa - {amount}, pr = pr + {draw(st.integers(0, 3))}")
    if n == 2:
        lines.append("    assume a || !b")  # reads b (an unused input is only a warning, but keep it quiet)
    lines.append("}")
    return "\n".join(lines) + "\n", low, high


def brute_force(text: str, low: Fraction, high: Fraction) -> list[Fraction]:
    """The integer and half-integer values of P in [low, high] at which `const P = value` checks."""
    passing = []
    value = low
    while value <= high:
        constant = text.replace(f"param P in [{low}, {high}]", f"const P = {value.numerator}/{value.denominator}")
        if compile_text(constant, "s.ra").ok:
            passing.append(value)
        value += Fraction(1, 2)
    return passing


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(small_automata())
def test_threshold_matches_brute_force(case):
    from rac.check.analysis.synthesis import synthesise, unsupported

    text, low, high = case
    node = parse_text(text, "s.ra").automata[0]
    resolver = Resolver(node)
    automaton = resolver.run()
    assert automaton is not None, [d.message for d in resolver.diagnostics]
    parameter = automaton.parameters[0]

    def resolve(value: Fraction):
        return Resolver(node, {"P": value}).run()

    if unsupported(resolve(low), resolve(high)) is not None:
        # e.g. `sa = sa - P + 1` at P = 1 does not penalise: the set may be a union, refused for now.
        assert [d.code for d in compile_text(text, "s.ra").diagnostics if d.is_error] == ["E0407"]
        return
    result = synthesise(resolve, parameter)
    expected = brute_force(text, low, high)
    grid = [low + Fraction(k, 2) for k in range(int(2 * (high - low)) + 1)]
    if result.empty:
        assert expected == []
        return
    assert result.low is not None and result.high is not None

    def inside(v: Fraction) -> bool:
        above = v > result.low.value if result.low.open else v >= result.low.value
        below = v < result.high.value if result.high.open else v <= result.high.value
        return above and below

    assert expected == [v for v in grid if inside(v)]
    # Exactness at the end itself, whatever its denominator: the least value checks, and just below fails.
    least = result.least
    if least is not None:
        at = text.replace(f"param P in [{low}, {high}]", f"const P = {least.numerator}/{least.denominator}")
        assert compile_text(at, "s.ra").ok
        if least > low:
            below = least - Fraction(1, 1000)
            at = text.replace(f"param P in [{low}, {high}]", f"const P = {below.numerator}/{below.denominator}")
            assert not compile_text(at, "s.ra").ok


def test_compile_reports_what_synthesise_finds():
    text = SMALL.format(param="param P in [1, 50]", penalty="P", weight="1")
    result = compile_text(text, "small.ra")
    assert result.ok
    assert re.match(r"synthesised: P >= 5\.5 \(every check holds for P in \[5\.5, 50\]\); checked with P = 5\.5",
                    result.proved[0])


def test_an_episode_ending_pays_only_the_end_clauses_of_its_own_inputs():
    """A crash ends the episode and never happens at the goal, so the arrival bonus is never paid in
    `Bad`: P2 needs 10 * (30 - PENALTY) + 30 <= 0 only. Regression: the end clauses took inputs of
    their own at that ending, the bonus counted, and the set was too small (PENALTY >= 133)."""
    text = """\
automaton Arrival {
    input collide : bool
    input dgoal   : real in [0, 500]
    assume collide imply dgoal >= 2
    param PENALTY in [1, 1000]
    reward sa, pr
    priority sa > pr
    objective 10 * sa + pr
    sample every 0.1
    horizon 30
    initial location Ok { sa' == 1; pr' == 1 }
    location Bad        { sa' == 0; pr' == 0 }
    edge Ok -> Bad when collide do sa = sa - PENALTY
    at end when dgoal < 2 do pr = pr + 1000
    episode ends when collide || dgoal < 2
}
"""
    result = compile_text(text, "arrival.ra")
    assert [d.code for d in result.diagnostics if d.is_error] == []
    assert result.proved[0] == ("synthesised: PENALTY >= 33 (every check holds for PENALTY in [33, 1000]); "
                               "checked with PENALTY = 33")


def test_the_range_of_the_values_in_between_updates_bounds_a_parameter():
    """The int32 range check bounds the values in between an edge's and the `at end` clauses' updates
    (UPPAAL stores each assignment), and so does the set synthesised for a parameter there: the edge
    leaves `p` where it was, but after its first update `p` is 3 + B at most (sample 3)."""
    from rac.check.analysis.synthesis import End, synthesise

    text = """\
automaton P {
    input a : bool
    param B in [0, 300000]
    reward p
    objective p
    sample every 1
    horizon 3
    initial location L { p' == 1 }
    edge L -> L when a do p = p + B, p = p - B
    at end when a do p += B, p -= B
}
"""
    node = parse_text(text, "p.ra").automata[0]
    automaton = Resolver(node).run()
    assert automaton is not None
    result = synthesise(lambda value: Resolver(node, {"B": value}).run(), automaton.parameters[0])
    limit = Fraction(2**31, 10**4) - 3  # trunc((3 + B)·10^4) <= 2^31 - 1
    assert (result.low, result.high) == (End(Fraction(0)), End(limit, open=True))
    for value, ok in ((limit - Fraction(1, 10**4), True), (limit, False)):
        constant = text.replace("param B in [0, 300000]", f"const B = {value.numerator}/{value.denominator}")
        assert compile_text(constant, "p.ra").ok is ok


@pytest.mark.parametrize("declaration", ["const B = 2", "param B in [1, 5]"])
def test_a_constant_used_above_its_declaration_says_where_it_is(declaration: str) -> None:
    """`const A = B + 1` above `const B = 2` said "unknown name `B`" and nothing else: a newcomer who
    sees `B` declared three lines down does not learn that the order matters."""
    text = ("automaton A {\n    input d : real in [0, 10]\n    const A2 = B + 1\n    " + declaration + "\n"
            "    reward r\n    objective r\n    sample every 1\n    horizon 5\n"
            "    initial location L { r' == d / A2 }\n}\n")
    found = [d for d in compile_text(text, "t.ra").diagnostics if d.code == "E0101"]
    assert len(found) == 1 and found[0].message == "unknown name `B`", found
    assert [(n.message, n.span.line if n.span else None) for n in found[0].notes] == [("`B` is declared below", 4)]
    assert list(found[0].hints) == ["a constant may use only the constants declared above it: move this "
                                    "declaration below `B`'s"]
    # below it, the same constant is known, and an unknown name elsewhere gets no such note
    moved = text.replace("    const A2 = B + 1\n", "").replace("reward r\n", "const A2 = B + 1\n    reward r\n")
    fine = compile_text(moved, "t.ra")
    assert not [d for d in fine.diagnostics if d.code == "E0101"], fine.diagnostics
    other = compile_text(moved.replace("r' == d / A2", "r' == d / C"), "t.ra")
    assert [n.message for d in other.diagnostics if d.code == "E0101" for n in d.notes] == []


SWITCHING = """automaton Switching {
    input a : bool
    input x : real in [0, 2]
    param P in [-1, 1]
    reward s, q
    priority s > q
    objective s + q
    sample every 1
    horizon 3
    initial location A { q' == 1 }
    location B { q' == 1 }
    EDGES
}
"""


@pytest.mark.parametrize("edges", [
    # `s -= P` lowers s where P > 0, `s += P` where P < 0: B penalises s at both bounds, not at 0
    "edge A -> B when a do s -= P\n    edge B -> B when a do s += P",
    # `s += P * x - P` lowers s somewhere in x for every P but 0
    "edge A -> B when a do s = s + P * x - P\n    edge B -> A when !a",
])
def test_a_location_that_penalises_at_both_bounds_but_not_between_is_refused(edges: str) -> None:
    """P2 fails at both bounds (B penalises s and q grows there) and holds at P = 0 (B penalises
    nothing). The synthesis compared the bounds only and said E0406, no value passes."""
    text = SWITCHING.replace("EDGES", edges)

    def ok_at(value: int) -> bool:
        return compile_text(text.replace("param P in [-1, 1]", f"const P = {value}"), "s.ra").ok

    assert [ok_at(v) for v in (-1, 0, 1)] == [False, True, False]
    result = compile_text(text, "s.ra")
    (refused,) = [d for d in result.diagnostics if d.is_error]
    assert refused.code == "E0407" and "may change between its bounds" in refused.message


def test_one_edge_that_penalises_at_both_bounds_penalises_between() -> None:
    """`s -= P` lowers s wherever P > 0: with P in [1, 10] the location penalises throughout, and the
    synthesis goes on."""
    text = SWITCHING.replace("EDGES", "edge A -> B when a do s -= P\n    edge B -> A when !a").replace(
        "param P in [-1, 1]", "param P in [1, 10]")
    result = compile_text(text, "s.ra")
    assert result.ok and "every check holds for P in [3, 10]" in result.facts[0].message
