"""Synthesis under `require risk <= b` (rac.check.analysis.synthesis.risk_values, the parameter stage):
the set of values it finds is exactly where `rac check` with the value written as a constant has no
E1001, on random small automata (brute force over a grid of values), and the least value on the
paper's automaton."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st

from rac.check.analysis.synthesis import risk_values
from rac.check.resolve import Resolver
from rac.compiler import compile_text
from rac.lang.parser import parse_text

ROOT = Path(__file__).resolve().parents[2]

TEMPLATE = """\
automaton Small {{
    input near : bool
    input crash : bool
    input done : bool
    assume crash imply near
    param P in [0, 40]
    reward sa, pr
    objective {w} * sa + pr
    sample every 1
    horizon {horizon}
    goal when done && !crash
    collision when crash
    require risk <= {bound}
    initial location Go {{ sa' == 1; pr' == {go} }}
    location Near {{ sa' == -1; pr' == {near} }}
    edge * -> Near when near do sa = sa - P
    edge Near -> Go when !near
    at end when done do pr = pr + {bonus}
}}
"""


def holds_at(text: str, value: Fraction) -> bool:
    """Whether `rac check` finds no E1001 with P written as a constant of that value."""
    fixed = text.replace("param P in [0, 40]", f"const P = {value.numerator} / {value.denominator}")
    result = compile_text(fixed)
    assert not any(d.is_error and d.code != "E1001" for d in result.diagnostics), fixed
    return not any(d.code == "E1001" for d in result.diagnostics)


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 10), st.integers(1, 3), st.sampled_from(["1/10", "1/4", "1/2", "9/10"]),
       st.integers(-2, 2), st.integers(-2, 2), st.integers(0, 30))
def test_the_set_is_where_the_requirement_holds(w, horizon, bound, go, near, bonus):
    text = TEMPLATE.format(w=w, horizon=horizon, bound=bound, go=go, near=near, bonus=bonus)
    node = parse_text(text).automata[0]
    parameter = Resolver(node, {"P": Fraction(0)}).run().parameters[0]
    found = risk_values(lambda value: Resolver(node, {"P": value}).run(), parameter, Fraction(bound))
    for k in range(0, 81):
        value = Fraction(k, 2)
        assert any(value in interval for interval in found) == holds_at(text, value), (value, found)
    for interval in found:  # the ends too, where an open end must fail and a closed one hold
        for end, is_open in ((interval.low, interval.low_open), (interval.high, interval.high_open)):
            assert holds_at(text, end) == (not is_open)


def test_the_least_penalty_for_a_risk_of_one_in_ten():
    # The paper's automaton, its penalty a parameter: p* <= 1/10 needs R_goal - R_crash >= 10 (R_goal -
    # R_stall) = 5000, so a crash at the last sample must cost 4020 more than at PENALTY = 98 (P2's least).
    text = (ROOT / "examples" / "tune" / "driving_risk.ra").read_text(encoding="utf-8")
    result = compile_text(text)
    assert result.ok, [str(d) for d in result.diagnostics]
    assert result.automaton is not None and result.automaton.constants
    assert dict(result.automaton.constants)["PENALTY"] == 500
    sentence = next(f.message for f in result.facts if f.check == "synthesis")
    assert "`require risk <= 0.1` holds for PENALTY in [500, " in sentence
    risk = next(f for f in result.facts if f.check == "risk")
    assert risk.data["p_star"] == "1/10"
    below = compile_text(text.replace("param PENALTY in [0, 1400]", "const PENALTY = 499"))
    assert [d.code for d in below.diagnostics if d.is_error] == ["E1001"]


def test_no_value_within_the_int32_range_reaches_a_risk_of_one_in_a_hundred():
    # p* <= 1/100 needs PENALTY >= 5000; above 1430 the rewards leave int32: E0406, and the checks at
    # the least value the other checks allow (98) show why (E1001)
    text = (ROOT / "examples" / "tune" / "driving_risk.ra").read_text(encoding="utf-8")
    result = compile_text(text.replace("require risk <= 0.1", "require risk <= 0.01"))
    assert [d.code for d in result.diagnostics if d.is_error] == ["E0406", "E1001"]
    e0406 = result.diagnostics[0]
    assert "no value of parameter `PENALTY`" in e0406.message
    assert any("`require risk <= 0.01` holds for none of them" in str(n) for n in e0406.notes)
    assert any("the checks at PENALTY = 98 follow" in str(n) for n in e0406.notes)


def test_a_parameter_of_one_value_meets_the_requirement_as_its_constant_does():
    # `param PENALTY in [1000, 1000]`: the returns on the one value combined had no piece, so `require risk`
    # "holds for none of them" (E0406) where `const PENALTY = 1000` passes it
    driving = (ROOT / "stdlib" / "driving.ra").read_text(encoding="utf-8").replace(
        "\n}", "\n    require risk <= 0.5\n}")
    constant = compile_text(driving.replace("const PENALTY = 100", "const PENALTY = 1000"), "driving.ra")
    assert constant.ok
    one = compile_text(driving.replace("const PENALTY = 100", "param PENALTY in [1000, 1000]"), "driving.ra")
    assert one.ok, [d.message for d in one.diagnostics]
    assert one.proved[1:] == constant.proved


def test_a_parameter_of_one_value_may_be_the_bound_of_the_requirement():
    # `param B in [0.5, 0.5]` with `require risk <= B`: the search takes each return's slope one unit above,
    # where the bound (1.5) is no probability and the file does not check: an internal error (AssertionError)
    driving = (ROOT / "stdlib" / "driving.ra").read_text(encoding="utf-8").replace(
        "const PENALTY = 100", "const PENALTY = 1000\n    BOUND").replace("\n}", "\n    require risk <= B\n}")
    constant = compile_text(driving.replace("BOUND", "const B = 0.5"), "driving.ra")
    one = compile_text(driving.replace("BOUND", "param B in [0.5, 0.5]"), "driving.ra")
    assert constant.ok and one.ok, [d.message for d in one.diagnostics]
    assert one.proved[1:] == constant.proved


def test_the_checks_shown_under_E0406_are_at_a_value_the_significands_hold() -> None:
    # no PENALTY meets `require risk <= 0.001`; the checks shown were at 82/3, P2's least, and added E0801 (the
    # UPPAAL update `(3*safe - 820000) / 3` leaves int32): an error of rac's choice, at no value a user could
    # write; they are shown at 27.3334, the least above it that the significands hold
    text = """\
automaton Follow {
    input headway : real in [0, 10]
    input speed   : real in [0, 40]
    input collide : bool
    assume collide imply headway < 1
    param PENALTY in [0, 2000]
    reward safe, prog, comfort
    priority safe > prog > comfort
    objective 10 * safe + 2 * prog + comfort
    sample every 0.1
    horizon 20
    initial location Following { safe' == 1; prog' == speed / 30; comfort' == 1 }
    location Close             { safe' == -1 }
    location Crashed           { safe' == -5 }
    edge * -> Close when headway < 2 && !collide do safe -= PENALTY
    edge * -> Crashed when collide do safe -= 1000
    edge Close -> Following when headway >= 2
    goal when speed > 25
    collision when collide
    require risk <= 0.001
}
"""
    result = compile_text(text)
    assert [d.code for d in result.diagnostics if d.is_error] == ["E0406", "E1001"]
    assert any("the checks at PENALTY = 27.3334 follow" in str(n) for n in result.diagnostics[0].notes)
