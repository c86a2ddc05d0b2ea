"""P1 rate dominance, P2 no compensation (plain and strict) and the int32 range check.

The numbers for the driving automaton are worked out by hand. Its worst P2 run stays in `Normal`
(every objective grows at 1/s), enters `Unsafe` at the last sample (paying PENALTY once) and
ends there with the `at end` bonus of 100 on `pr`:

    10*(H - PENALTY) + 5*(H + 100) + H = 16*H - 10*PENALTY + 500

Any other run pays the penalty at least once and gains less, so this is the supremum.
"""

from __future__ import annotations

import itertools
import json
import math
from fractions import Fraction
from unittest import mock

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from reference import reference_max

from rac import ir
from rac.check.analysis.affine import moves
from rac.check.analysis.priority import (
    check_priorities,
    check_ranges,
    check_rate_dominance,
    exists_neg_pos_in,
    p2_target,
    replay,
)
from rac.check.analysis.worst import (
    AFTER_END,
    CONTINUE,
    Target,
    maximise,
    maximise_generic,
    maximise_translations,
)
from rac.compiler import CompileResult, compile_text
from rac.core.diagnostics import render_text
from rac.ir.inputs import InputSpace
from rac.lang.resources import stdlib_file

DRIVING = stdlib_file("driving.ra").read_text(encoding="utf-8")


def driving_text(penalty: int | str = 100, horizon: str = "30", period: str = "0.1", strict: bool = False,
                 **replace: str) -> str:
    text = DRIVING.replace("const PENALTY = 100", f"const PENALTY = {penalty}")
    text = text.replace("horizon 30 ", f"horizon {horizon} ").replace("sample every 0.1", f"sample every {period}")
    if strict:
        text = text.replace("priority sa > pr > co", "priority strict sa > pr > co")
    for old, new in replace.items():
        assert old in text
        text = text.replace(old, new)
    return text


def compiled(text: str) -> CompileResult:
    return compile_text(text, "driving.ra")


def errors(result: CompileResult, code: str):
    return [d for d in result.diagnostics if d.code == code]


def p2_worst(penalty: int, horizon: Fraction) -> Fraction:
    return 16 * horizon - 10 * penalty + 500


def objective_target(automaton: ir.Automaton) -> Target:
    weights = tuple(automaton.objective.coefficient(r) for r in automaton.rewards)
    watched = tuple(name == "Unsafe" for name in automaton.location_names)
    return Target(weights, automaton.objective.const, watched)


# ---------------------------------------------------------------- P2 on the driving automaton
def test_p2_holds_at_penalty_100_with_worst_value_minus_20() -> None:
    result = compiled(driving_text(100))
    assert result.ok, render_text(result.diagnostics, result.sources)
    assert not errors(result, "E0402")
    assert any("P2 holds for `sa` (penalised in `Unsafe`): the objective stays <= -20 " in f for f in result.proved)
    automaton = result.automaton
    assert automaton is not None
    facts: list[str] = []
    assert check_priorities(automaton, facts) == []
    space = InputSpace(automaton)
    worst = maximise(automaton, moves(automaton, space), objective_target(automaton))
    assert worst is not None and worst.value == -20 == p2_worst(100, Fraction(30))
    values, _ = replay(automaton, space, worst)
    assert values == [-70, 130, 30]  # 10*(-70) + 5*130 + 30 = -20


def test_p2_fails_at_penalty_90_with_the_expected_counterexample() -> None:
    result = compiled(driving_text(90))
    assert not result.ok
    (diag,) = errors(result, "E0402")
    assert diag.data["value"] == "80"
    assert diag.data["level"] == 0 and diag.data["reward"] == "sa"
    assert diag.data["values"] == {"sa": "-60", "pr": "130", "co": "30"}
    assert "the objective can reach 80" in diag.message
    run, end = diag.data["run"], diag.data["end"]
    assert end["clause_lines"] == [32] and Fraction(end["inputs"]["dgoal"]) < 2
    # consecutive samples alike are one entry: Normal to Normal for 299 samples, then the crash
    assert [k for s in run for k in range(s["sample"], s["last_sample"] + 1)] == list(range(1, 301))
    assert all(s["from"] == s["to"] == "Normal" and s["instant"] == CONTINUE for s in run[:-1])
    assert len(run) <= 3 and run[-1]["sample"] == run[-1]["last_sample"] == 300
    last = run[-1]
    assert (last["from"], last["to"], last["instant"]) == ("Normal", "Unsafe", AFTER_END)
    assert last["inputs"]["isClose"] is True

    text = render_text(result.diagnostics, result.sources)
    assert "error[E0402]: P2 no compensation fails: while `sa` is penalised, the objective can reach 80" in text
    assert ("samples 1-299 (t = 0.1..29.9 s): stays in `Normal`, 299 samples; "
            "inputs isClose=false, prog=true, comf=true") in text
    assert "sample 300 (t = 30 s): `Normal` -> `Unsafe` (edge at line 26)" in text
    assert "run ends at t = 30 s: `at end` (line 32)" in text
    assert "inputs dgoal in (0, 2)" in text
    assert "sa = -60, pr = 130, co = 30; the objective = 80 > 0" in text
    assert "after the `at end` updates" in text
    assert "penalise `sa` by at least 8 more (80 / weight 10)" in text



@pytest.mark.parametrize(("objective", "said"), [
    ("-10 * sa + 5 * pr + co", "the objective weighs `sa` by -10, so a penalty on `sa` raises it"),
    ("0 * sa + 5 * pr + co", "the objective leaves `sa` out (weight 0), so a penalty on `sa` does not lower it")])
def test_p2_failing_for_a_reward_weighted_zero_or_negative_hints_at_the_weight(objective: str, said: str) -> None:
    """Found by fuzzing: with `sa` weighted <= 0, E0402 had no hint at all (penalising more cannot help,
    so the usual "penalise by at least" was left out and nothing said what to do instead)."""
    result = compiled(driving_text(100, **{"objective 10 * sa + 5 * pr + co": f"objective {objective}"}))
    (diag,) = [d for d in errors(result, "E0402") if d.data["reward"] == "sa"]
    assert diag.hints == (f"{said}: give `sa` a positive weight in `objective`",)

RATE_READS_AN_INPUT = """\
automaton Rates {{
    input c : bool
    input d : real in [0, 10]
    reward sa, pr
    priority sa > pr
    objective 3 * sa + pr
    sample every 1
    horizon 5
    initial location N {{ sa' == 1; pr' == d / 5 }}
    location U          {{ sa' == -1 }}
    location F          {{ sa' == 1 }}
    edge * -> U when c do sa -= 4
    {edges}
    at end when c do pr += d
}}
"""


def test_a_counterexample_names_the_values_its_rates_and_updates_read() -> None:
    """The text run shows the input values that make its value (`d = 10`, read by a rate and by `at end`
    only), as the JSON does: without them the run could not be replayed to the value printed."""
    result = compiled(RATE_READS_AN_INPUT.format(edges=""))
    (diag,) = errors(result, "E0402")
    assert diag.data["value"] == "23"  # 3 * (5 - 4) + 5 * 2 + 10
    assert [s["inputs"]["d"] for s in diag.data["run"]][0] == "10" and diag.data["end"]["inputs"]["d"] == "10"
    text = render_text(result.diagnostics, result.sources)
    assert "samples 1-4 (t = 1..4 s): stays in `N`, 4 samples; inputs c=false, d = 10" in text
    assert "run ends at t = 5 s: `at end` (line 14); inputs c=true, d = 10" in text


SINK = """
automaton Sink {
    input isClose : bool
    reward sa, pr
    priority sa > pr
    objective 10 * sa + pr
    sample every 1
    horizon 5
    initial location Normal { sa' == 0; pr' == 0 }
    location Unsafe { sa' == -1; pr' == 30 }
    edge Normal -> Unsafe when isClose do sa = sa - 1
}
"""


def test_a_run_through_a_location_without_edges_says_no_input_is_read() -> None:
    """`Unsafe` has no edges: its samples read no input, said so, not as `inputs (no inputs)` of an automaton
    that has inputs."""
    result = compiled(SINK)
    errors(result, "E0402")
    text = render_text(result.diagnostics, result.sources)
    assert "samples 2-4 (t = 2..4 s): stays in `Unsafe`, 3 samples; no input is read" in text
    assert "(no inputs)" not in text


def test_a_counterexample_value_a_guard_excludes_is_approached() -> None:
    """`d >= 10` leaves `N`: the supremum of `pr' == d / 5` over `d < 10` is approached, not taken."""
    result = compiled(RATE_READS_AN_INPUT.format(edges="edge N -> F when !c && d >= 10"))
    (diag,) = errors(result, "E0402")
    text = render_text(result.diagnostics, result.sources)
    assert "stays in `N`, 4 samples; inputs c=false, d in (0, 10), tending to 10" in text
    # the value is a supremum, said as one (runs close enough to it violate all the same)
    assert diag.message.endswith("the objective comes arbitrarily close to 23")
    # the JSON run replays: each input is a value the run takes (d = 10 would take the edge to `F`),
    # and the value the worst run approaches is said beside it
    first = diag.data["run"][0]
    assert 0 < Fraction(first["inputs"]["d"]) < 10 and first["approached"] == {"d": "10"}
    assert first["from"] == first["to"] == "N"


def test_an_attained_value_is_the_json_input_and_nothing_is_approached() -> None:
    result = compiled(RATE_READS_AN_INPUT.format(edges=""))
    (diag,) = errors(result, "E0402")
    assert all(step["approached"] == {} for step in diag.data["run"]) and diag.data["end"]["approached"] == {}
    assert diag.message.endswith("the objective can reach 23")


@pytest.mark.parametrize(("penalty", "horizon", "period"), [
    (100, "30", "0.1"),
    (100, "31", "0.1"),     # -4: still holds
    (100, "31.2", "0.1"),   # -0.8
    (100, "31.25", "0.25"),  # exactly 0: holds (P2 asks <= 0)
    (100, "31.5", "0.25"),  # 4: fails
    (100, "32", "0.1"),     # 12: fails
    (90, "30", "0.1"),
    (90, "25", "0.5"),      # 0: holds again on a shorter horizon
    (120, "60", "1"),       # 260
    (100, "1", "0.1"),      # a short run: 16 - 1000 + 500
])
def test_p2_worst_value_grows_with_the_horizon(penalty: int, horizon: str, period: str) -> None:
    expected = p2_worst(penalty, Fraction(horizon))
    result = compiled(driving_text(penalty, horizon, period))
    found = errors(result, "E0402")
    if expected <= 0:
        assert not found
        assert any(f"the objective stays <= {_text(expected)} over every run of {horizon} s" in f
                   for f in result.proved), result.proved
    else:
        (diag,) = found
        assert Fraction(diag.data["value"]) == expected
        assert diag.data["run"][-1]["last_sample"] == int(Fraction(horizon) / Fraction(period))



@pytest.mark.parametrize("penalty, strict", [(90, False), (100, True), (63, False)])
def test_a_run_in_json_covers_every_sample_once_and_joins_only_alike_neighbours(penalty: int, strict: bool) -> None:
    """The JSON run's entries cover samples 1 .. last, in order, each once; two neighbouring entries
    differ in what they show (a run of alike samples is one entry)."""
    result = compiled(driving_text(penalty, strict=strict))
    runs = [d.data["run"] for d in result.diagnostics if d.data and "run" in d.data]
    assert runs
    shown = ("from", "to", "edge_line", "inputs", "instant")
    for run in runs:
        covered = [k for s in run for k in range(s["sample"], s["last_sample"] + 1)]
        assert covered == list(range(1, len(covered) + 1))
        assert all(s["time"] == str(s["sample"] * Fraction(1, 10)) for s in run)
        for before, after in zip(run, run[1:]):
            assert any(before[key] != after[key] for key in shown), (before, after)

def _text(value: Fraction) -> str:
    return str(value.numerator) if value.denominator == 1 else f"{float(value):g}"


def test_p2_huge_penalty_is_exact() -> None:
    """Regression: values beyond ±2^62 (object arrays) were taken for 'unreachable'."""
    penalty = 10**17
    result = compiled(driving_text(penalty))
    assert not errors(result, "E0402")
    expected = p2_worst(penalty, Fraction(30))
    assert any(f"the objective stays <= {expected} over" in f for f in result.proved), result.proved


def test_p2_with_a_non_translation_update_uses_the_generic_engine() -> None:
    # Entering Unsafe also resets comfort: the worst objective is 10*(30-100) + 5*130 + 0.
    result = compiled(driving_text(100, **{"do sa = sa - PENALTY": "do sa = sa - PENALTY, co = 0"}))
    assert result.ok
    assert any("the objective stays <= -50 " in f for f in result.proved), result.proved
    # 10 s: 10*(10 - 63) + 5*110 + 0 = 20.
    result = compiled(driving_text(63, "10", **{"do sa = sa - PENALTY": "do sa = sa - PENALTY, co = 0"}))
    (diag,) = errors(result, "E0402")
    assert diag.data["value"] == "20"
    assert diag.data["values"] == {"sa": "-53", "pr": "110", "co": "0"}
    assert diag.data["run"][-1]["instant"] == AFTER_END and diag.data["end"]


# ---------------------------------------------------------------- priority strict
def test_strict_driving_reports_the_lower_levels_only() -> None:
    result = compiled(driving_text(100, strict=True))
    found = {d.data["level"]: d for d in errors(result, "E0402")}
    assert set(found) == {1, 2}  # sa holds (-20); pr and co can be compensated
    # Level 1 (pr, penalised in Stalled): Normal 299 samples, Stalled at 300, end: 5*130 + 30.
    assert found[1].data["reward"] == "pr" and found[1].data["value"] == "680"
    assert "while `pr` is penalised, the weighted sum of `pr`, `co` can reach 680" in found[1].message
    assert found[1].data["run"][-1]["to"] == "Stalled"
    # Level 2 (co, penalised in Uncomfortable): co alone reaches 30.
    assert found[2].data["reward"] == "co" and found[2].data["value"] == "30"
    assert found[2].data["priority"] == "strict sa > pr > co"
    assert any("P2 holds for `sa` (penalised in `Unsafe`): the objective stays <= -20 " in f for f in result.proved)


def test_strict_reports_the_failing_level_when_the_top_holds() -> None:
    # Comfort never grows: level 2 holds (co <= 0 in Uncomfortable), level 1 fails with 5*130.
    variant = {"initial location Normal { sa' == 1;  pr' == 1;  co' == 1 }":
               "initial location Normal { sa' == 1;  pr' == 1;  co' == 0 }"}
    result = compiled(driving_text(100, strict=True, **variant))
    (diag,) = errors(result, "E0402")
    assert diag.data["level"] == 1 and diag.data["reward"] == "pr"
    assert diag.data["value"] == "650"
    assert diag.data["values"]["pr"] == "130"
    assert "weighted sum of `pr`, `co`" in diag.message
    text = render_text(result.diagnostics, result.sources)
    assert "`Normal` -> `Stalled`" in text
    # Without `strict` only the top level is checked, and it holds (10*(30-100) + 650 = -50).
    plain = compiled(driving_text(100, **variant))
    assert plain.ok
    assert any("the objective stays <= -50 " in f for f in plain.proved)


def test_strict_level_constant_only_counts_at_the_top() -> None:
    raw = compile_text(driving_text(100, strict=True,
                                    **{"objective 10 * sa + 5 * pr + co": "objective 10 * sa + 5 * pr + co - 1000"}),
                       analyse=False).automaton
    assert raw is not None
    diagnostics = check_priorities(raw)
    values = {d.data["level"]: d.data["value"] for d in diagnostics if d.code == "E0402"}
    assert values == {1: "680", 2: "30"}


# ---------------------------------------------------------------- P1 rate dominance
P1_TEXT = """
automaton P {
    input a : bool
    INPUTS
    reward hi, lo
    priority hi > lo
    objective 10*hi + WEIGHT*lo
    sample every 1
    horizon 2
    initial location Ok { hi' == 1; lo' == 1 }
    location Bad { hi' == HI; lo' == LO }
    edge Ok -> Bad when a do hi -= 100
    edge Bad -> Ok when !a
}
"""


def p1(hi: str, lo: str, weight: str = "1", inputs: str = "") -> list:
    text = P1_TEXT.replace("HI", hi).replace("LO", lo).replace("WEIGHT", weight).replace("INPUTS", inputs)
    result = compile_text(text, "p1.ra")
    assert not [d for d in result.diagnostics if d.is_error and d.code != "E0401"], result.diagnostics
    return errors(result, "E0401")


def test_p1_violation_where_high_decreases_and_low_increases() -> None:
    (diag,) = p1("-1", "1")
    assert diag.data == {"location": "Bad", "decreasing": "hi", "increasing": "lo"}
    assert "P1 rate dominance fails in `Bad`" in diag.message
    assert diag.span is not None and diag.span.line == 11
    # The same from the analysis entry point, on the unchecked IR.
    text = P1_TEXT.replace("HI", "-1").replace("LO", "1").replace("WEIGHT", "1").replace("INPUTS", "")
    automaton = compile_text(text, analyse=False).automaton
    assert automaton is not None
    assert [d.data for d in check_rate_dominance(automaton)] == [diag.data]


def test_p1_lower_reward_weighted_zero_or_negative_is_fine() -> None:
    assert p1("-1", "1", weight="0") == []
    assert p1("-1", "1", weight="-1") == []
    assert p1("-1", "-1", weight="-1") != []  # negative weight times a negative rate grows
    assert p1("0", "1") == []  # hi does not decrease
    assert p1("-1", "0") == []


def test_p1_with_numeric_rates_is_an_exact_minimax() -> None:
    v = "input v : real in [0, 2]"
    # hi < 0 exactly when v < 1, lo > 0 exactly when v > 1: never both, although hi can be
    # negative and lo positive (an interval check would complain).
    assert p1("v - 1", "v - 1", inputs=v) == []
    # They touch at v = 1 only, where both are 0: still fine.
    assert p1("v - 1", "(v - 1) / 2", inputs=v) == []
    # Overlap on v in [0, 1).
    assert len(p1("v - 1", "3/2 - v", inputs=v)) == 1
    assert len(p1("v - 1", "1 - v", inputs=v)) == 1
    # Overlap only on a sliver near the bound: v in (1.9, 2].
    assert len(p1("v - 2", "v - 19/10", inputs=v)) == 1
    assert p1("v - 2", "v - 2", inputs=v) == []
    # Two inputs: the signs are coupled through v - w.
    vw = "input v : real in [0, 2]\n    input w : real in [0, 2]"
    assert len(p1("v - w", "w - v", inputs=vw)) == 1
    assert p1("v - w", "v - w", inputs=vw) == []


def test_p1_two_inputs_overlap_inside_the_box() -> None:
    vw = "input v : real in [0, 2]\n    input w : real in [0, 2]"
    # hi < 0 iff v - w < 2 (almost everywhere); lo > 0 iff v - w > 1 (e.g. v = 2, w = 0.5).
    assert len(p1("v - w - 2", "v - w - 1", inputs=vw)) == 1
    # lo > 0 iff v - w > 2: impossible in the box.
    assert p1("v - w - 2", "v - w - 2", inputs=vw) == []


def test_p1_with_int_inputs_is_exact() -> None:
    """Regression: the minimax relaxation over reals reported int inputs that can never overlap."""
    n = "input n : int in [0, 2]"
    # hi < 0 iff n < 1/2 (n = 0); lo > 0 iff n > 1/4 (n >= 1): no integer does both.
    assert p1("2*n - 1", "4*n - 1", inputs=n) == []
    assert len(p1("2*n - 1", "4*n + 1", inputs=n)) == 1


class _Inputs:
    """Just enough of an automaton for ``exists_neg_pos_in``."""

    def __init__(self, items: list[ir.Input]):
        self.items = {i.name: i for i in items}

    def input(self, name: str) -> ir.Input:
        return self.items[name]


def _min_max_reference(f: ir.Linear, g: ir.Linear, inputs: list[ir.Input]) -> bool:
    """Exists x with f < 0 < g: min over the box of max(f, -g) is at a box vertex, or where an
    edge of the box crosses f = -g (h = max(f, -g) is affine on both sides of that hyperplane).
    Integer inputs are enumerated."""
    reals = [i for i in inputs if i.kind == "real"]
    ints = [i for i in inputs if i.kind == "int"]
    s = f + g
    for combo in itertools.product(*(range(int(i.low), int(i.high) + 1) for i in ints)):
        fixed = {i.name: Fraction(v) for i, v in zip(ints, combo)}
        points = []
        for corner in itertools.product(*((i.low, i.high) for i in reals)):
            points.append(dict(zip((i.name for i in reals), corner)))
            for k, item in enumerate(reals):  # the edge along reals[k] through this corner
                rest = {i.name: c for j, (i, c) in enumerate(zip(reals, corner)) if j != k}
                slope = s.coefficient(item.name)
                if slope:
                    base = s.evaluate({**fixed, **rest, item.name: Fraction(0)})
                    x = -base / slope
                    if item.low <= x <= item.high:
                        points.append({**rest, item.name: x})
        for point in points:
            values = {**fixed, **point}
            if max(f.evaluate(values), -g.evaluate(values)) < 0:
                return True
    return False


coefficients = st.builds(Fraction, st.integers(-3, 3), st.sampled_from([1, 2, 3]))


@st.composite
def rate_pairs(draw):
    inputs = []
    for name in ["u", "v", "w"][: draw(st.integers(1, 3))]:
        kind = draw(st.sampled_from(["real", "real", "int"]))
        low = draw(st.integers(-2, 1))
        high = low + draw(st.integers(0, 3))
        inputs.append(ir.Input(name, kind, Fraction(low), Fraction(high)))

    def linear() -> ir.Linear:
        terms = tuple((i.name, draw(coefficients)) for i in inputs)
        return ir.Linear(draw(coefficients), tuple(t for t in terms if t[1]))

    return linear(), linear(), inputs


@settings(max_examples=300, deadline=None, derandomize=True)
@given(rate_pairs())
def test_p1_minimax_matches_a_vertex_enumeration(case) -> None:
    f, g, inputs = case
    box = {i.name: (i.low, i.high) for i in inputs}
    assert exists_neg_pos_in(f, g, _Inputs(inputs), box) == _min_max_reference(f, g, inputs)  # type: ignore[arg-type]


@settings(max_examples=300, deadline=None, derandomize=True)
@given(rate_pairs())
def test_p1_beyond_the_enumeration_searches_the_widest_int_input_exactly(case) -> None:
    """With more joint whole values than MAX_INT_POINTS, every int input but the widest is enumerated
    and the widest searched (lowered here so that the search runs on tiny boxes): still exact."""
    f, g, inputs = case
    box = {i.name: (i.low, i.high) for i in inputs}
    sizes = sorted(int(i.high - i.low) + 1 for i in inputs if i.kind == "int")
    with mock.patch("rac.check.analysis.priority.MAX_INT_POINTS", math.prod(sizes[:-1])):
        assert exists_neg_pos_in(f, g, _Inputs(inputs), box) == _min_max_reference(f, g, inputs)  # type: ignore[arg-type]


def test_p1_with_many_int_values_is_exact() -> None:
    """Regression: beyond 4096 joint whole values the int inputs were relaxed to reals, and P1 failed
    (E0401) where no whole values make `a` fall while `b` grows: a < 0 needs n + m <= 2, b > 0 n + m >= 3."""
    ints = "input n : int in [0, 99]\n    input m : int in [0, 99]"

    def failures(hi: str, lo: str) -> list:
        text = P1_TEXT.replace("HI", hi).replace("LO", lo).replace("WEIGHT", "1").replace("INPUTS", ints)
        automaton = compile_text(text, "p1.ra", analyse=False).automaton
        assert automaton is not None
        return check_rate_dominance(automaton)

    assert failures("n + m - 5/2", "n + m - 9/4") == []
    assert len(failures("n + m - 5/2", "n + m - 7/4")) == 1  # n + m = 2 does both


ASSUMED = """automaton Assumed {{
    input u : bool
    input d : real in [0, 10]
    {assume}
    reward s, p
    priority s > p
    objective 10 * s + p
    sample every 1
    horizon 2
    initial location L {{ {rates} }}
    location M {{ }}
    {edges}
}}
"""


@pytest.mark.parametrize(("assume", "rates", "edges"), [
    ("assume d >= 5", "s' == d - 5", ""),                                  # no allowed d makes s' negative
    ("assume d >= 5", "s' == d - 5; p' == 6 - d", ""),                     # P1: s never decreases
    ("assume u imply d >= 5", "", "edge L -> M when u do s = s + d - 5"),  # the edge never lowers s
    ("assume d > 5", "s' == d - 5", ""),                                    # an open end: s' > 0
])
def test_assume_decides_where_a_reward_is_penalised(assume: str, rates: str, edges: str) -> None:
    # `assume` was ignored: rac check reported E0402 (and E0401) for penalties no allowed input makes
    result = compiled(ASSUMED.format(assume=assume, rates=rates, edges=edges))
    assert not [d for d in result.diagnostics if d.is_error], render_text(list(result.diagnostics), result.sources)
    assert "P2 holds trivially for `s`: no location penalises it" in result.proved


@pytest.mark.parametrize("updates", ["s += 5, s -= 1", "s -= 5, s += d + 5", "s = s - 2 * p, s = s + 2 * p + 1",
                                     "s -= 1, p = s, s = p + 1"])
def test_an_edge_penalises_by_what_its_updates_do_together(updates: str) -> None:
    """Regression: each update was looked at alone, so `s += 5, s -= 1` (which raises s by 4) made `M`
    penalise s, and P2 failed with E0402 at 10 * 4 > 0 in a location where s is never lowered."""
    result = compiled(ASSUMED.format(assume="", rates="", edges=f"edge L -> M when u do {updates}"))
    assert not [d for d in result.diagnostics if d.is_error], render_text(list(result.diagnostics), result.sources)
    assert "P2 holds trivially for `s`: no location penalises it" in result.proved


@pytest.mark.parametrize(("assume", "rates", "edges"), [
    ("assume d >= 4", "s' == d - 5", ""),                                   # d in [4, 5) lowers s
    ("assume u imply d >= 4", "", "edge L -> M when u do s = s + d - 5"),
    ("assume d >= 5", "s' == d - 5; p' == 6 - d", "edge L -> M when d > 9 do s = s + 5 - d"),
    ("", "", "edge L -> M when u do s += 1, s -= 5"),                      # lowers s by 4 in all
    ("", "", "edge L -> M when u do s += 5, s = s / 2"),                   # lowers s where s > 5
    ("", "", "edge L -> M when u do p = s, s = p - 1"),                    # through another reward
])
def test_an_allowed_penalty_is_still_found(assume: str, rates: str, edges: str) -> None:
    result = compiled(ASSUMED.format(assume=assume, rates=rates, edges=edges))
    assert not any("P2 holds trivially" in fact for fact in result.proved)


# ---------------------------------------------------------------- int32 range
def test_int32_range_overflows_at_one_hour() -> None:
    result = compiled(driving_text(100, horizon="3600"))
    (diag,) = errors(result, "E0501")
    # Into Unsafe at sample 1 (0.1 - 100), then a collision at each of the 35999 other samples
    # while sa' = -1: -99.9 - 100.1*35999.
    assert diag.data["reward"] == "sa"
    assert Fraction(diag.data["value"]) == Fraction("-99.9") - Fraction("100.1") * 35999 == Fraction("-3603599.8")
    assert (diag.data["base"], diag.data["exponent"]) == (10, 4)
    notes = "\n".join(n.message for n in diag.notes)
    # |sa| first exceeds 214748.3648 at sample 2146: -99.9 - 100.1*2145 = -214814.4.
    assert "first overflow on the worst run: t = 214.6 s, in `Unsafe` right after the sample (sa = -214814.4)" in notes
    assert "it can reach -3603599.8" in diag.message


def test_int32_range_holds_at_thirty_seconds() -> None:
    result = compiled(driving_text(100))
    assert not errors(result, "E0501")
    assert "int32 range holds at base 10, exponent 4: rewards stay within [-30029.8, 130]" in result.proved
    automaton = result.automaton
    assert automaton is not None
    assert check_ranges(automaton) == []
    # A coarser representation overflows already: 10^9 * 130 > 2^31.
    (diag,) = check_ranges(automaton, base=10, exponent=9)
    assert diag.code == "E0501" and diag.data["reward"] == "sa" and diag.data["value"] == "30"


def test_int32_range_boundary_is_exact() -> None:
    text = """
automaton R {
    input a : bool
    reward r
    objective r
    sample every 1
    horizon 2
    initial location L { r' == 0 }
    edge L -> L when a do r += GROWTH
}
"""
    # trunc(r * 10^4) must stay <= 2^31 - 1; two samples of growth g reach 2g.
    limit = Fraction(2**31 - 1, 10**4)
    ok = compile_text(text.replace("GROWTH", str(limit / 2)), analyse=False).automaton
    bad = compile_text(text.replace("GROWTH", str(limit / 2 + Fraction(1, 10**4) / 2)), analyse=False).automaton
    assert ok is not None and bad is not None
    # r's values fit (no E0501); the significand of limit / 2 is not whole, so the model computes
    # `(2*iR + 2147483647) / 2`, and `2*iR` does not fit (E0801)
    assert [d.code for d in check_ranges(ok)] == ["E0801"]
    (diag,) = check_ranges(bad)
    assert diag.code == "E0501"
    negative = compile_text(text.replace("GROWTH", f"-{Fraction(2**31, 10**4) / 2}"), analyse=False).automaton
    assert negative is not None and check_ranges(negative) == []  # -2^31 itself is representable


# An edge whose updates go up and back down: the edge's result stays small, the values in between
# do not. UPPAAL runs the assignments left to right and stores each in the reward's int32 mirror.
IN_BETWEEN = """\
automaton InBetween {
    input a : bool
    reward p
    objective p
    sample every 1
    horizon 3
    initial location L { p' == 1 }
    edge L -> L when a do p = p + STEP, p = p + STEP, p = p - STEP, p = p - STEP
}
"""


def test_int32_range_covers_the_values_in_between_an_edges_updates(tmp_path, capsys) -> None:
    """Regression: the range check saw only each edge's result ([0, 3] here) and passed a file whose
    UPPAAL model overflows: after the second update p is 400003, 4000030000 as a significand."""
    from rac.cli.main import main

    source = tmp_path / "in_between.ra"
    source.write_text(IN_BETWEEN.replace("STEP", "200000"), encoding="utf-8")
    assert main(["check", str(source)]) == 1
    out = capsys.readouterr().out
    assert "error[E0501]: reward `p` overflows int32 at base 10, exponent 4 in between an edge's updates: " \
           "it can reach 400003" in out
    # the caret is on the second update, the one that leaves the value
    assert f"{source}:8:43: error[E0501]" in out
    assert "an intermediate value, right after this update (update 2 of its sequence): UPPAAL runs" in out
    assert "first overflow on the worst run: t = 3 s, during the edge `L` -> `L`, right after its update 2 of 4 " \
           "(line 8): an intermediate value, which UPPAAL stores too (p = 400003)" in out
    assert "int32 range holds" not in out
    assert main(["check", "--format", "json", str(source)]) == 1
    (diag,) = [d for d in json.loads(capsys.readouterr().out)[0]["diagnostics"] if d["code"] == "E0501"]
    assert (diag["data"]["value"], diag["data"]["applied"], diag["data"]["update_line"]) == ("400003", 2, 8)


def test_int32_range_in_between_updates_at_the_representations_scale() -> None:
    """The values in between are scaled like every other: 200003 fits at exponent 4 and not at 5,
    while the edge's results ([0, 3]) would fit even at exponent 8."""
    automaton = compile_text(IN_BETWEEN.replace("STEP", "100000"), analyse=False).automaton
    assert automaton is not None
    facts: list = []
    assert check_ranges(automaton, 10, 4, facts) == []
    assert [f.message for f in facts] == ["int32 range holds at base 10, exponent 4: rewards stay within [0, 200003]"]
    (diag,) = check_ranges(automaton, 10, 5)
    assert diag.code == "E0501" and diag.data["value"] == "200003" and diag.data["applied"] == 2
    # a sequence whose values in between stay put changes nothing: the edge's results decide
    steady = compile_text(IN_BETWEEN.replace("STEP", "0"), analyse=False).automaton
    assert steady is not None and check_ranges(steady, 10, 8) == []


# Each sequence reflects p twice, so the edge leaves p where it was (a translation), but the value in
# between, OFFSET - p, is not p plus a constant.
REFLECTED = """\
automaton Reflected {
    input b : bool
    reward p
    objective p
    sample every 1
    horizon 2
    initial location L { p' == -RATE }
    edge L -> L when b do p = OFFSET - p, p = OFFSET - p
    at end when !b do p = OFFSET - p, p = OFFSET - p
}
"""


@pytest.mark.parametrize("where", ["edge", "at end"])
def test_int32_range_covers_a_reflection_in_between_updates_whose_sequence_is_a_translation(where: str) -> None:
    """Regression: a sequence of updates whose whole is a translation sent the range check to the
    translation engine, which reads only the offsets of the maps in between: it took `100000 - p` for
    `p + 100000` and proved [-300000, 0], while p = -300000 makes the value in between 400000, which
    overflows int32 at exponent 4. Either sequence alone (the other line dropped) shows it."""
    def automaton(rate: str, offset: str) -> ir.Automaton:
        text = REFLECTED.replace("RATE", rate).replace("OFFSET", offset)
        dropped = next(line for line in text.splitlines(keepends=True)
                       if line.strip().startswith("edge" if where == "at end" else "at end"))
        compiled = compile_text(text.replace(dropped, ""), analyse=False).automaton
        assert compiled is not None
        return compiled

    facts: list = []
    assert check_ranges(automaton("15", "10"), 10, 4, facts) == []
    assert [f.message for f in facts] == ["int32 range holds at base 10, exponent 4: rewards stay within [-30, 40]"]
    (diag,) = check_ranges(automaton("150000", "100000"), 10, 4)
    assert diag.code == "E0501" and diag.data["value"] == "400000" and diag.data["applied"] == 1


# An update with a fractional coefficient: UPPAAL computes `iP = 2*iP / 3`, and `2*iP` is an int32 too.
FRACTIONAL = """\
automaton Frac {
    input go : bool
    input d : real in [0, HIGH]
    reward p
    objective p
    sample every 1
    horizon 3
    initial location L { p' == RATE }
    edge L -> L when go do UPDATE
}
"""


def _fractional(rate: str, update: str, high: str = "100000") -> ir.Automaton:
    text = FRACTIONAL.replace("RATE", rate).replace("UPDATE", update).replace("HIGH", high)
    automaton = compile_text(text, analyse=False).automaton
    assert automaton is not None
    return automaton


def test_int32_range_covers_the_products_of_a_fractional_update(tmp_path, capsys) -> None:
    """Regression: `p = 2*p/3` is emitted as `iP = 2*iP / 3`; with p up to 150000 (1.5e9 as a
    significand) `2*iP` leaves int32, UPPAAL computes garbage while rac's engine is exact. The
    check passed it; now E0801 points at the update."""
    from rac.cli.main import main

    # p reaches 3 * rate: 100000 keeps 2*iP within int32 (2e9), 150000 does not (3e9), either sign
    assert check_ranges(_fractional("33333", "p = 2*p/3")) == []
    for rate in ("50000", "-50000"):
        (diag,) = check_ranges(_fractional(rate, "p = 2*p/3"))
        assert diag.code == "E0801"
        assert "`2*p` may reach " + ("3000000000" if rate[0] != "-" else "-3000000000") in diag.message
    source = tmp_path / "frac.ra"
    source.write_text(FRACTIONAL.replace("RATE", "50000").replace("UPDATE", "p = 2*p/3").replace("HIGH", "1"),
                      encoding="utf-8")
    for command in (["check"], ["compile", "--target", "uppaal"]):
        assert main([*command, str(source)]) == 1
        out = "".join(capsys.readouterr())  # compile reports on standard error
        assert f"{source}:9:28: error[E0801]: update `p = 2/3*p`: the UPPAAL model computes it as `(2*p) / 3` " \
               "over 32-bit significands, and `2*p` may reach 3000000000, beyond the 32-bit integer range" in out
        assert "`p` within [0, 150000]" in out
        assert "int32 range holds" not in out


def test_int32_range_covers_the_partial_sums_of_an_update() -> None:
    """An input's product and a partial sum before the division are int32 values too; an integer
    update's own result is the range check's (E0501), not an intermediate."""
    (diag,) = check_ranges(_fractional("1", "p = 3*d/4", high="150000"))  # 3*d up to 4.5e9, the result fits
    assert diag.code == "E0801" and "as `(3*d) / 4` over 32-bit significands, and `3*d` may reach 4500000000" \
        in diag.message
    (diag,) = check_ranges(_fractional("40000", "p = (p + d)/2"))  # p up to 150000, d up to 100000
    assert diag.code == "E0801" and "`p + d` may reach 2500000000" in diag.message
    assert check_ranges(_fractional("1", "p = (p + d)/2")) == []  # p stays below 100002: the sum fits
    # an integer coefficient is multiplied by the common denominator too: (2*iP + d) / 2
    (diag,) = check_ranges(_fractional("1", "p = p + d/2"))
    assert diag.code == "E0801" and "as `(2*p + d) / 2`" in diag.message
    assert "`2*p` may reach 3000060000" in diag.message
    assert check_ranges(_fractional("1", "p = d - 100000")) == []  # the sum is the result: it fits
    assert check_ranges(_fractional("1", "p = 2*d - 100000")) == []  # and so is the product of one term
    (diag,) = check_ranges(_fractional("1", "p = 3*d - 100000", high="100000"))  # 3*d: 3e9, the result fits
    assert diag.code == "E0801" and "as `3*d - 1000000000`" in diag.message
    # a number of the emitted sum is an int32 literal too: 100000 * 10^4 * 3 is not
    (diag,) = check_ranges(_fractional("1", "p = p/3 + 100000"))
    assert diag.code == "E0801" and "as `(p + 3000000000) / 3` over 32-bit significands, and its number " \
        "3000000000 is beyond the 32-bit integer range" in diag.message


def test_int32_range_covers_the_negation_of_an_updates_first_term() -> None:
    """Regression: `p = -p - 5` is emitted as `iP = -iP - 50000`; p reaches -214748.3648 (the significand
    -2147483648, which the range check allows), where `-iP` leaves int32 though the result fits. The
    check passed it, the UPPAAL model overflowed and rac's engine left the verdicts unknown."""
    text = """\
automaton Neg {
    input go : bool
    reward p
    objective p
    sample every 1
    horizon 4
    initial location L { p' == -53687.0912 }
    edge L -> L when go do UPDATE
}
"""
    def ranges(update: str) -> list:
        automaton = compile_text(text.replace("UPDATE", update), analyse=False).automaton
        assert automaton is not None
        return check_ranges(automaton)

    (diag,) = ranges("p = -p - 5")
    assert diag.code == "E0801" and diag.span is not None and diag.span.line == 8
    assert "as `-p - 50000` over 32-bit significands, and `-p` may reach 2147483648" in diag.message
    (diag,) = ranges("p = 5 - p")  # `-iP + 50000`: the result itself leaves int32 first, E0501's
    assert diag.code == "E0501"
    # one significand unit less per sample: p stops at -2147483644 units, whose negation fits
    text = text.replace("-53687.0912", "-53687.0911")
    assert ranges("p = -p - 5") == []


def test_int32_range_covers_a_learning_querys_discrete_observation() -> None:
    """Regression: `{p/3 + r/7}` is observed in the UPPAAL model as the integer `7*iP + 3*iR`, which
    left int32 (UPPAAL learns on garbage, rac's engine on the exact value); now E0801 at the query."""
    text = """\
automaton Obs {
    input go : bool
    reward p, r
    objective p
    sample every 1
    horizon 3
    initial location L { p' == RATE; r' == -1 }
    edge L -> L when go do p = p - 1
    query obs: strategy S = minE(p)[<=3]{OBS}->{p}: <> time >= 3
}
"""
    def ranges(rate: str, observation: str) -> list:
        automaton = compile_text(text.replace("RATE", rate).replace("OBS", observation), analyse=False).automaton
        assert automaton is not None
        return check_ranges(automaton)

    # p reaches 3 * rate: 7 * 30000 * 10^4 fits int32, 7 * 120000 * 10^4 does not
    assert ranges("10000", "p/3 + r/7") == []
    (diag,) = ranges("40000", "p/3 + r/7")
    assert diag.code == "E0801" and diag.span is not None and diag.span.line == 9
    assert "query `obs`: the discrete observation `p / 3 + r / 7` is observed in the UPPAAL model as the " \
           "integer `7*p + 3*r`" in diag.message and "`7*p` may reach 8400000000" in diag.message
    # `time` is the sample counter (period 1 s): time/7 + p is observed as 10000*count + 7*iP
    (diag,) = ranges("10300", "time/7 + p")
    assert diag.code == "E0801" and "as the integer `10000*count + 7*p`" in diag.message
    assert "`7*p` may reach 2163000000" in diag.message
    assert ranges("1", "10*p + time + Obs.location") == []  # observed as iP + 1000*count + 1000*Obs.location
    # a number of the observed sum beyond int32, whatever the ranges: `rac check` accepted these and
    # `rac compile --target uppaal` refused them (E0801: no int32 literal writes it); now rac check refuses
    for observation, number in (("4503599627370497", "4503599627370497"), ("0.5 * 8589934592", "4294967296"),
                                ("r - r + 3000000", None)):
        found = ranges("1", observation)
        if number is None:
            assert found == []
            continue
        (diag,) = found
        assert diag.code == "E0801" and diag.span is not None and diag.span.line == 9
        assert f"with the number {number}" in diag.message and "beyond the 32-bit integer range" in diag.message


def test_int32_range_covers_the_values_in_between_the_at_end_updates() -> None:
    """The enabled `at end` clauses run as one sequence on the UPPAAL model's `finish?` edge: a
    value in between them is stored too, whether the run ends at the horizon or by `episode ends when`."""
    text = """\
automaton Ends {
    input a : bool
    input stop : bool
    reward p
    objective p
    sample every 1
    horizon 3
    initial location L { p' == 1 }
    EPISODE
    at end when a do p += 150000
    at end do p -= 150000
}
"""
    for episode in ("", "episode ends when stop"):
        automaton = compile_text(text.replace("EPISODE", episode), analyse=False).automaton
        assert automaton is not None
        assert check_ranges(automaton, 10, 4) == []
        (diag,) = check_ranges(automaton, 10, 5)
        assert diag.data["value"] == "150003" and diag.data["applied"] == 1 and diag.data["update_line"] == 10
        assert "in between the `at end` updates" in diag.message
        assert "during the `at end` updates, right after its update 1 of 2 (line 10)" in \
            "\n".join(n.message for n in diag.notes)


def test_end_inputs_are_free_like_the_runtime_end_call() -> None:
    """`end(inputs)` takes inputs of its own, so the check must not tie them to the last sample's.

    Regression: with `at end when !isClose && dgoal < 2`, a run can enter Unsafe (isClose) at
    the last sample and still get the end bonus from end inputs with isClose = false.
    """
    text = driving_text(90).replace("at end when dgoal < 2", "at end when !isClose && dgoal < 2")
    (diag,) = errors(compiled(text), "E0402")
    assert diag.data["value"] == "80"
    assert diag.data["end"]["inputs"]["isClose"] is False
    assert diag.data["run"][-1]["inputs"]["isClose"] is True


# A crash ends the episode and no crash happens at the goal: `Unsafe` is entered only by a crash,
# which ends the run with the end clauses of the crash's own inputs, so the arrival bonus is never
# paid there. Regression: the worst run took the `at end` clauses with inputs of their own at an
# ending caused by `episode ends when` (the bonus with dgoal < 2 after a crash with dgoal >= 2), and
# `rac check` reported a false E0402 (330 at 30 s).
ARRIVAL = """\
automaton Arrival {
    input collide : bool
    input dgoal   : real in [0, 500]

    assume collide imply dgoal >= 2

    reward sa, pr
    priority sa > pr
    objective 10 * sa + pr

    sample every 0.1
    horizon 30

    initial location Normal { sa' == 1; pr' == 1 }
    location Unsafe         { sa' == 0; pr' == 0 }

    edge Normal -> Unsafe when collide do sa = sa - 100

    at end when dgoal < 2 do pr = pr + 1000

    episode ends when collide || dgoal < 2
}
"""


def _both_engines(automaton: ir.Automaton, target: Target) -> list[Fraction | None]:
    outs = moves(automaton, InputSpace(automaton))
    return [None if w is None else w.value
            for w in (maximise_translations(automaton, outs, target), maximise_generic(automaton, outs, target))]


def test_an_ending_by_episode_ends_when_applies_the_end_clauses_of_its_own_inputs() -> None:
    """The reproducer: P2 holds (a crash at the last sample, no bonus: 10 * (30 - 100) + 30), and
    both engines and the brute force agree on a short horizon that no run violates it."""
    result = compiled(ARRIVAL)
    assert errors(result, "E0402") == []
    (fact,) = [f for f in result.facts if f.check == "P2"]
    assert fact.data["bound"] == "-670"
    short = compile_text(ARRIVAL.replace("horizon 30", "horizon 0.3"), analyse=False).automaton
    assert short is not None
    target = p2_target(short, 0)
    expected = reference_max(short, target.weights, target.constant, target.watched)
    assert expected == 10 * (Fraction(3, 10) - 100) + Fraction(3, 10)
    assert _both_engines(short, target) == [expected, expected]


def test_an_end_that_episode_ends_when_did_not_cause_still_has_inputs_of_its_own() -> None:
    """Soundness: where the crash does not end the episode, the run can still end (at the horizon, or
    earlier by `end(inputs)`) with inputs of its own, which may pay the bonus in `Unsafe`."""
    text = ARRIVAL.replace("episode ends when collide || dgoal < 2", "episode ends when dgoal < 2")
    (diag,) = errors(compiled(text), "E0402")
    assert diag.data["value"] == "330"
    assert diag.data["run"][-1]["inputs"]["collide"] is True
    assert Fraction(diag.data["end"]["inputs"]["dgoal"]) < 2
    short = compile_text(text.replace("horizon 30", "horizon 0.3"), analyse=False).automaton
    assert short is not None
    target = p2_target(short, 0)
    expected = reference_max(short, target.weights, target.constant, target.watched)
    assert expected == 10 * (Fraction(3, 10) - 100) + Fraction(3, 10) + 1000
    assert _both_engines(short, target) == [expected, expected]


def test_a_violation_at_an_episode_ending_shows_the_end_clauses_of_the_sample_that_ended_it() -> None:
    """A bonus the crash itself pays is a real violation: the counterexample ends with the episode, and
    its end reads the crash sample's inputs."""
    text = ARRIVAL.replace("at end when dgoal < 2", "at end when collide")
    result = compiled(text)
    (diag,) = errors(result, "E0402")
    assert diag.data["value"] == "330"
    assert diag.data["end"]["inputs"] == diag.data["run"][-1]["inputs"]
    assert diag.data["run"][-1]["inputs"]["collide"] is True
    assert "the episode ends (`episode ends when` holds) at t = 30 s: `at end` (line 19)" in \
        render_text(result.diagnostics, result.sources)


def test_a_counterexample_shows_the_inputs_that_keep_the_episode_going() -> None:
    """An input only `episode ends when` reads decides whether the run goes on: the text names its value
    at every sample (`stop=false`), or replaying the run as printed could end it at the first sample."""
    ending = "    input stop : bool\n    episode ends when stop\n    horizon 30"
    text = driving_text(penalty=90).replace("    horizon 30", ending)
    result = compiled(text)
    (diag,) = errors(result, "E0402")
    (note,) = [n.message for n in diag.notes if n.message.startswith("counterexample")]
    samples = [line for line in note.splitlines()[1:] if line.lstrip().startswith("sample")]
    assert samples and all(line.endswith("stop=false") or "stop=false," in line for line in samples), note
    assert all(entry["inputs"]["stop"] is False for entry in diag.data["run"])


def test_a_violation_between_the_edge_and_the_end_of_an_episode_says_so() -> None:
    """The state right after the edge of a sample that ends the episode is an instant P2 watches, but the
    runtimes' `step` applies the `at end` updates in the same call: the note names the instant as before
    them, or a replay that reads the rewards after `step` sees another value (here p = -3, q = 0)."""
    text = """
    automaton A {
        input a : bool
        reward p, q
        priority p > q
        objective 2 * p + 3 * q
        sample every 1
        horizon 2
        initial location L0 { p' == 2; q' == 2 }
        location L2 { p' == -1 }
        edge L0 -> L2 when a do p -= 1, q -= 1
        at end do p = 0, p -= 3, q = 0
        episode ends when true
    }
    """
    result = compiled(text)
    (diag,) = errors(result, "E0402")
    assert diag.data["value"] == "5" and diag.data["run"][-1]["instant"] == "after-edge"
    assert any("in `L2` right after the sample's edge, before the `at end` updates of the episode's end): "
               "p = 1, q = 1" in note.message for note in diag.notes)


JOINT = """\
automaton Joint {
    input collide : bool
    input d       : real in [0, 10]
    reward sa, pr
    priority sa > pr
    objective 10 * sa + pr
    sample every 1
    horizon 3
    initial location Normal { sa' == 0; pr' == 1 }
    location Unsafe         { sa' == 0; pr' == 0 }
    edge Normal -> Unsafe when collide do sa = sa - 11 + d
    at end when collide do pr = pr + 50 - 20 * d
    episode ends when collide
}
"""


def test_the_end_clauses_of_an_episode_ending_read_the_same_value_as_the_edge() -> None:
    """One `d` feeds the edge and the end clauses of the sample that ends the run: the worst is one
    value of it for both (a crash at sample 3, d = 10 right after the edge: 10 * (-11 + 10) + 3 = -7),
    not the edge's worst d (10) with the end's (0), which would make the end reach 43 > 0."""
    result = compiled(JOINT)
    assert errors(result, "E0402") == []
    (fact,) = [f for f in result.facts if f.check == "P2"]
    assert fact.data["bound"] == "-7"
    automaton = compile_text(JOINT, analyse=False).automaton
    assert automaton is not None
    target = p2_target(automaton, 0)
    assert reference_max(automaton, target.weights, target.constant, target.watched) == -7
    assert _both_engines(automaton, target) == [-7, -7]


def test_a_run_may_end_before_its_first_sample() -> None:
    """An initial location that penalises the top reward is checked after an immediate `end`."""
    text = """
    automaton A {
        input b : bool
        reward hi, lo
        priority hi > lo
        objective 10*hi + lo
        sample every 1
        horizon 3
        initial location Bad { hi' == -1 }
        location Good { }
        edge Bad -> Good when b
        edge Good -> Bad when !b
        at end when b do lo = lo + 5
    }
    """
    (diag,) = errors(compiled(text), "E0402")
    assert diag.data["value"] == "5"
    assert diag.data["run"] == [] and diag.data["end"]["inputs"]["b"] is True


def test_a_long_decimal_value_is_said_as_a_decimal() -> None:
    # A value with more than 10 significant digits was said as a fraction, "-123456781001/20000".
    text = """\
automaton Driving {
    input isClose : bool
    reward sa, pr
    objective 10*sa + pr
    sample every 0.001
    horizon 1
    initial location Normal { sa' == 1;  pr' == 1 }
    location Unsafe         { sa' == -1.0001; pr' == 0 }
    edge Normal -> Unsafe when isClose  do sa = sa - 12345.6781
    edge Unsafe -> Normal when !isClose
}
"""
    result = compile_text(text, "decimal.ra")
    (overflow,) = [d for d in result.diagnostics if d.code == "E0501"]
    assert overflow.message.endswith("it can reach -6172839.05005"), overflow.message
    assert Fraction("-6172839.05005") == Fraction(overflow.data["value"])
