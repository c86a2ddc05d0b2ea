"""Synthesis under the loophole requirements (rac.check.analysis.parametric.loophole_values, the
parameter stage): on random small automata, the set of values it finds for each check is exactly where
:func:`rac.check.analysis.incentives.analyse` (itself tested against brute force over every run) finds
no loophole with the value written in, on a grid and at the set's ends; and `rac check` on the shipped
example synthesises the least crash cost for which ending early never pays."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st

from rac.check.analysis.behaviour import input_space
from rac.check.analysis.incentives import Findings, analyse
from rac.check.analysis.parametric import LOOPHOLES, loophole_values, upper
from rac.check.analysis.worst import Unfinished
from rac.check.resolve import Resolver
from rac.compiler import compile_text
from rac.lang.parser import parse_text

ROOT = Path(__file__).resolve().parents[2]

TEMPLATE = """\
automaton Small {{
    input near : bool
    input crash : bool
    input done : bool
    input x : real in [0, 2]
    assume crash imply near
    param P in [-10, 30]
    reward sa, pr
    objective {weight} * sa + pr
    sample every 1
    horizon {horizon}
    goal when done && !crash
    collision when crash
    episode ends when {ends}
    initial location Go {{ sa' == 1; pr' == {go} }}
    location Near {{ sa' == -1; pr' == {near} }}
    location Wait {{ sa' == 1; pr' == {wait} }}
    edge * -> Near when near do sa = sa - {penalty}
    edge Go -> Wait when !near && !done do pr = pr + {waiting}
    edge * -> Go when !near && done do pr = pr + {back}
    at end when done do pr = pr + {bonus}
    at end when crash do sa = sa - {crash}
}}
"""

TERMS = st.sampled_from(["0", "1", "3", "P", "-P", "2 * P + 1", "5 - P", "x", "P - x"])


def holds(node, value: Fraction) -> dict[str, bool]:
    automaton = Resolver(node, {"P": value}).run()
    assert automaton is not None
    space, _ = input_space(automaton)
    assert space is not None
    found = analyse(automaton, space)
    assert isinstance(found, Findings), found
    return {check: verdict is None for check, verdict in found.verdicts.items()}


@settings(max_examples=25, deadline=None)
@given(st.sampled_from(["1", "3", "P"]), st.integers(1, 4), st.sampled_from(["crash", "done || crash", "done"]),
       st.integers(-2, 2), st.integers(-2, 2), st.integers(-2, 2), TERMS, TERMS, TERMS, TERMS, TERMS)
def test_the_sets_are_where_the_checks_hold(weight, horizon, ends, go, near, wait, penalty, waiting, back, bonus,
                                            crash):
    text = TEMPLATE.format(weight=weight, horizon=horizon, ends=ends, go=go, near=near, wait=wait, penalty=penalty,
                           waiting=waiting, back=back, bonus=bonus, crash=crash)
    if weight == "P" and "P" in "".join((penalty, waiting, back, bonus, crash)):
        return  # a weight and an update both in P: the objective is quadratic (E0407 before the search)
    node = parse_text(text).automata[0]
    parameter = Resolver(node, {"P": Fraction(0)}).run().parameters[0]
    try:
        found = loophole_values(lambda value: Resolver(node, {"P": value}).run(), parameter, LOOPHOLES)
    except Unfinished as stop:
        # only a weight multiplying the numeric input whose best value flips with it stops the search
        assert weight == "P" and "x" in "".join((penalty, waiting, back, bonus, crash)), (stop, text)
        return
    assert set(found) == set(LOOPHOLES)
    for k in range(-10, 31):  # every integer of the range; the sets' ends, often fractions, below
        value = Fraction(k)
        at = holds(node, value)
        for check, intervals in found.items():
            assert any(value in i for i in intervals) == at[check], (check, value, intervals, text)
    for check, intervals in found.items():  # the ends too: an open end fails, a closed one holds
        for interval in intervals:
            for end, is_open in ((interval.low, interval.low_open), (interval.high, interval.high_open)):
                assert holds(node, end)[check] == (not is_open), (check, end, intervals, text)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.integers(-5, 5), st.integers(-20, 20)), min_size=1, max_size=8),
       st.integers(-6, 6), st.integers(0, 8))
def test_the_envelope_is_the_maximum(lines, low, width):
    low_f, high_f = Fraction(low), Fraction(low + width)
    envelope = upper(lines, low_f, high_f)
    for k in range(0, 4 * width + 1):
        p = low_f + Fraction(k, 4)
        assert max(s * p + c for s, c in envelope) == max(s * p + c for s, c in lines)
    assert [s for s, _ in envelope] == sorted({s for s, _ in envelope})  # by increasing slope, once each


def test_the_least_crash_cost_for_which_ending_early_never_pays():
    # examples/weighted/naive.ra's loophole: ending at the first sample costs 11 against 300 for the best
    # safe run of the whole horizon, so a crash must cost at least 289 (the hint of W1002).
    text = (ROOT / "examples" / "tune" / "highway_collision.ra").read_text(encoding="utf-8")
    result = compile_text(text, ROOT / "examples" / "tune" / "highway_collision.ra")
    assert result.ok, [str(d) for d in result.diagnostics]
    assert result.automaton is not None
    assert dict(result.automaton.constants)["COLLISION"] == 289
    sentence = next(f.message for f in result.facts if f.check == "synthesis")
    assert "`require ending_early_never_pays` holds for COLLISION in [289, 1000]" in sentence
    # one less, written as a constant: the loophole is back, an error under the requirement
    below = compile_text(text.replace("param COLLISION in [0, 1000]", "const COLLISION = 288"),
                         ROOT / "examples" / "tune" / "highway_collision.ra")
    assert [d.code for d in below.diagnostics if d.is_error] == ["E1003"]


def test_no_value_that_closes_the_loophole_is_e0406():
    # the least cost that closes it is 289: a range below it holds none
    text = (ROOT / "examples" / "tune" / "highway_collision.ra").read_text(encoding="utf-8")
    result = compile_text(text.replace("param COLLISION in [0, 1000]", "param COLLISION in [0, 200]"),
                          ROOT / "examples" / "tune" / "highway_collision.ra")
    codes = [d.code for d in result.diagnostics if d.is_error]
    assert codes[0] == "E0406" and "E1003" in codes, codes
    e0406 = result.diagnostics[[d.code for d in result.diagnostics].index("E0406")]
    assert any("`require ending_early_never_pays` holds for none of them" in str(n) for n in e0406.notes)


def test_a_gain_not_affine_in_the_parameter_stops_the_search():
    # P weighs `sa`, and `sa -= x` makes the best x flip at P = 0: the search says so (E0407), no guess.
    text = TEMPLATE.format(weight="P", horizon=3, ends="crash", go=1, near=-1, wait=0, penalty="x", waiting="1",
                           back="0", bonus="3", crash="3")
    result = compile_text(text.replace("    episode ends", "    require stalling_never_pays\n    episode ends"))
    assert [(d.code, d.message) for d in result.diagnostics] == [
        ("E0407", "not yet: parameter `P` cannot be synthesised here: under `require stalling_never_pays`: a "
                  "sample's gain is not affine in the parameter (it weighs a numeric input whose best value "
                  "changes with it)")]


def test_a_midpoint_where_the_file_does_not_check_is_e0407():
    # The loophole search reads the file at the bounds' midpoint too; where it does not check there (a term
    # (COLLISION - 499.999999999) * 1e-300, about 1e-309 at 500: E0011) though it does at both bounds, `rac check`
    # ended with an internal error (AssertionError in parametric._Parametric); it is the E0407 of such a value.
    path = ROOT / "examples" / "tune" / "highway_collision.ra"
    text = path.read_text(encoding="utf-8").replace(
        "do r -= COLLISION ", "do r -= COLLISION + (COLLISION - 499.999999999) * 1e-300 ")
    result = compile_text(text, path)
    assert [(d.code, d.message) for d in result.diagnostics] == [
        ("E0407", "not yet: parameter `COLLISION` cannot be synthesised here: the file does not check at "
                  "COLLISION = 500, a value within its bounds the search tried")]
    assert [n.message for n in result.diagnostics[0].notes] == [
        "at COLLISION = 500: error[E0011]: this computes a number too small for a double (about 1.0e-309)"]


def test_a_set_of_one_value_under_a_requirement_is_written_as_an_equation():
    # COLLISION in [0, 289]: only 289 closes the loophole; the recorded inequality read `289 <= COLLISION <= 289`
    # where the same set without a `require` is written `COLLISION == 289` (Synthesis.describe)
    path = ROOT / "examples" / "tune" / "highway_collision.ra"
    text = path.read_text(encoding="utf-8").replace("param COLLISION in [0, 1000]", "param COLLISION in [0, 289]")
    result = compile_text(text, path)
    assert result.ok and result.synthesis is not None, [str(d) for d in result.diagnostics]
    assert result.synthesis.inequalities == ("COLLISION == 289",)
    assert result.synthesis.values == (("COLLISION", 289),)
    # a wider set keeps its two ends
    wide = compile_text(text.replace("[0, 289]", "[0, 1000]"), path)
    assert wide.synthesis is not None and wide.synthesis.inequalities == ("289 <= COLLISION <= 1000",)
