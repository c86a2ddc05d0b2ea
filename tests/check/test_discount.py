"""P2 of the discounted return (`rac check --discount`): the search against a brute force written from
the semantics, against P2 itself at gamma = 1, against the runtime's own rewards, and through the CLI."""

from __future__ import annotations

import dataclasses
import json
from fractions import Fraction
from pathlib import Path

import pytest
from highway_like import SCALING
from hypothesis import given
from hypothesis import strategies as st
from reference import MAX_FRONTIER, Valuation, at_end, ends_episode, sample, simulate, valuations
from test_worst import SETTINGS, Case, cases

import rac
from rac import ir
from rac.check.analysis.affine import moves
from rac.check.analysis.discount import (
    DISCOUNTED_P2,
    Discount,
    check_discounted,
    discounted_value,
    discounted_worst,
)
from rac.check.analysis.worst import AFTER_END, BEFORE_EDGE, CONTINUE, Target, maximise
from rac.check.resolve import Resolver
from rac.cli.main import main
from rac.compiler import compile_source, compile_text
from rac.core.diagnostics import UNFINISHED
from rac.core.source import SourceFile
from rac.ir.inputs import InputSpace
from rac.lang.parser import parse_text

ROOT = Path(__file__).resolve().parents[2]
DRIVING = ROOT / "stdlib" / "driving.ra"
ZERO = Fraction(0)


def reference_discounted(automaton: ir.Automaton, target: Target, discount: Discount) -> Fraction | None:
    """The largest ``constant + sum of discount.weight(k) * (w·r's change at sample k)`` over every watched
    instant of every run: every run enumerated forward, each sample's changes weighed by its step's
    discount, the accrual between two samples by the later one's (it is part of that step's reward)."""
    w, c = target.weights, target.constant

    def f(r: tuple[Fraction, ...]) -> Fraction:
        return sum((wi * ri for wi, ri in zip(w, r)), ZERO)

    xs = valuations(automaton)
    best: list[Fraction | None] = [None]

    def see(location: int, value: Fraction) -> None:
        if target.watched[location] and (best[0] is None or value > best[0]):
            best[0] = value

    def ending(location: int, r: tuple[Fraction, ...], value: Fraction, weight: Fraction, v: Valuation) -> None:
        see(location, value + weight * (f(at_end(automaton, r, v)) - f(r)))

    gains: dict[tuple[Fraction, ...], Fraction] = {}

    def any_end(location: int, r: tuple[Fraction, ...], value: Fraction, weight: Fraction) -> None:
        """A run that ends here on inputs of its own: only the best of them can be the largest value."""
        if r not in gains:
            gains[r] = max(f(at_end(automaton, r, end)) - f(r) for end in xs)
        see(location, value + weight * gains[r])

    l0 = automaton.initial
    zero = tuple(ZERO for _ in automaton.rewards)
    see(l0, c)
    any_end(l0, zero, c, discount.weight(1))
    # per (location, rewards) the largest value so far: what follows adds the same whatever the value was
    frontier = {(l0, zero): c}
    steps = automaton.steps
    for k in range(1, steps + 1):
        here, after_next = discount.weight(k), discount.weight(k + 1)
        following: dict[tuple[int, tuple[Fraction, ...]], Fraction] = {}
        for (location, r), value in frontier.items():
            for v in xs:
                instants, (next_location, next_r) = sample(automaton, location, r, v, first=k == 1)
                previous, now = r, value
                for _, where, values in instants:
                    now += here * (f(values) - f(previous))
                    previous = values
                    see(where, now)
                last_location, last_r = instants[-1][1], instants[-1][2]
                if ends_episode(automaton, v):
                    ending(last_location, last_r, now, here, v)
                    continue
                any_end(last_location, last_r, now, here)
                if k < steps:
                    later = now + after_next * (f(next_r) - f(last_r))
                    see(next_location, later)
                    key = (next_location, next_r)
                    if key not in following or later > following[key]:
                        following[key] = later
        assert len(following) <= MAX_FRONTIER
        frontier = following
    return best[0]


discounts = st.builds(Discount, st.sampled_from([Fraction(1), Fraction(1, 2), Fraction(3, 4), Fraction(9, 10)]),
                      st.integers(1, 3))


def plain(case: Case) -> Case:
    """The case's target without the values inside a sequence of updates (P2 does not watch those)."""
    return dataclasses.replace(case, target=dataclasses.replace(case.target, intermediates=False))


def check_run(automaton: ir.Automaton, space: InputSpace, worst, target: Target, discount: Discount) -> None:
    """The run is a run of the automaton, ends in a watched location, and replays to the value found."""
    assert discounted_value(automaton, space, worst, target, discount) == worst.value
    here = automaton.initial
    for i, step in enumerate(worst.steps, start=1):
        assert step.sample == i and step.outcome.source == here
        assert (step.instant == CONTINUE) == (i < len(worst.steps))
        here = step.outcome.target
    if worst.steps:
        run = [Valuation(space.valuation(s.outcome.cls), {**space.valuation(s.outcome.cls), **s.inputs})
               for s in worst.steps]
        end = None
        if worst.instant == AFTER_END:
            guards = space.valuation(worst.end.cls)
            end = Valuation(guards, {**guards, **worst.end_inputs})
        where, _ = simulate(automaton, run, worst.instant, end)
        assert where == (automaton.initial if worst.instant == BEFORE_EDGE else here)
        assert target.watched[where]


@SETTINGS
@given(cases(), discounts)
def test_the_discounted_search_matches_the_brute_force(case: Case, discount: Discount) -> None:
    case = plain(case)
    automaton, target = case.automaton, case.target
    space = InputSpace(automaton)
    worst = discounted_worst(automaton, moves(automaton, space), target, discount)
    expected = reference_discounted(automaton, target, discount)
    assert (None if worst is None else worst.value) == expected, (discount, case.text)
    if worst is not None:
        check_run(automaton, space, worst, target, discount)


@SETTINGS
@given(cases(ending=True), discounts)
def test_the_discounted_search_matches_the_brute_force_where_episodes_end(case: Case, discount: Discount) -> None:
    case = plain(case)
    automaton, target = case.automaton, case.target
    space = InputSpace(automaton)
    worst = discounted_worst(automaton, moves(automaton, space), target, discount)
    assert (None if worst is None else worst.value) == reference_discounted(automaton, target, discount), case.text
    if worst is not None:
        check_run(automaton, space, worst, target, discount)


@SETTINGS
@given(cases())
def test_without_a_discount_it_is_p2(case: Case) -> None:
    """gamma = 1 weighs every sample alike: the value is P2's worst value, to the last digit."""
    case = plain(case)
    automaton, target = case.automaton, case.target
    outs = moves(automaton, InputSpace(automaton))
    discounted = discounted_worst(automaton, outs, target, Discount(Fraction(1), 2))
    undiscounted = maximise(automaton, outs, target, run=False)
    assert (None if discounted is None else discounted.value) == (None if undiscounted is None else undiscounted.value)


def test_the_drivings_discounted_counterexample_is_what_the_runtime_pays() -> None:
    """stdlib/driving.ra: P2 holds for its return (-20 at worst while unsafe) but not for the return
    discounted by 0.99 per sample. The run the check prints, fed to the runtime (rac.load) sample by
    sample, earns rewards whose discounted sum is the value the check found."""
    automaton = rac.compile_file(DRIVING).raise_for_errors()
    found = check_discounted(automaton, Discount(Fraction(99, 100)))
    assert [d.code for d in found] == [DISCOUNTED_P2]
    data = found[0].data
    assert Fraction(data["undiscounted"]) <= 0 < Fraction(data["value"])
    assert "with gamma = 0.9999 it holds" in found[0].hints[0]
    ra = rac.load(DRIVING)
    total = 0.0
    for part in data["run"]:
        values = {name: (float(Fraction(v)) if isinstance(v, str) else v) for name, v in part["inputs"].items()}
        for k in range(part["sample"], part["last_sample"] + 1):
            reward = ra.step(values)
            if k == part["last_sample"] and data["end"] is not None and part is data["run"][-1]:
                end = {name: (float(Fraction(v)) if isinstance(v, str) else v)
                       for name, v in data["end"]["inputs"].items()}
                reward += ra.end(end)
            total += 0.99 ** (k - 1) * reward
    assert total + float(automaton.objective.const) == pytest.approx(float(Fraction(data["value"])), rel=1e-9)
    assert ra.objective == pytest.approx(float(Fraction(data["undiscounted"])))
    # nearer 1 it holds, and says how far the discounted value stays below 0
    facts: list = []
    assert check_discounted(automaton, Discount(Fraction(9999, 10000)), facts) == []
    assert any(f.check == "P2-discounted" and Fraction(f.data["bound"]) <= 0 for f in facts)


def test_updates_that_scale_a_reward_are_not_checked_and_say_so() -> None:
    automaton = compile_text(SCALING, "doubling.ra").raise_for_errors()
    found = check_discounted(automaton, Discount(Fraction(9, 10)))
    assert [d.code for d in found] == [UNFINISHED]
    assert "scales a reward" in found[0].message and "0.9" in found[0].message


def test_rac_check_discount_from_the_command_line(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["check", "--discount", "0.99", str(DRIVING)]) == 1
    out = capsys.readouterr().out
    assert f"error[{DISCOUNTED_P2}]" in out and "the objective is -20 undiscounted" in out
    assert "proved: P2 holds for `sa` (penalised in `Unsafe`)" in out  # the plain P2 still proved
    assert main(["check", "--discount", "0.9999", str(DRIVING)]) == 0
    said = capsys.readouterr().out
    assert "proved: P2 holds for `sa` under the discount (gamma = 0.9999 per step of 1 sample)" in said
    assert main(["check", "--discount", "0.99", "--format", "json", str(DRIVING)]) == 1
    report = json.loads(capsys.readouterr().out)
    assert report[0]["diagnostics"][-1]["code"] == DISCOUNTED_P2
    assert report[0]["diagnostics"][-1]["data"]["gamma"] == "99/100"
    scaling = tmp_path / "doubling.ra"
    scaling.write_text(SCALING)
    assert main(["check", "--discount", "0.9", str(scaling)]) == 4  # not checked: undecided, never ok
    # not made because an update scales a reward: the summary does not call that a limit it stopped at
    assert "a check stopped at its limit or outside what it covers" in capsys.readouterr().out
    # in JSON, named as E0410 and the fact name it (it said "property": "P2", E0402's, and "discount")
    assert main(["check", "--format", "json", "--discount", "0.9", "--samples-per-step", "2", str(scaling)]) == 4
    unfinished = json.loads(capsys.readouterr().out)[0]["diagnostics"][-1]
    assert unfinished["code"] == UNFINISHED
    assert unfinished["data"] == {"property": "P2-discounted", "reward": "sa", "gamma": "9/10", "samples_per_step": 2}
    assert main(["check", "--samples-per-step", "5", str(DRIVING)]) == 2
    assert "needs --discount" in capsys.readouterr().err
    assert main(["check", "--discount", "1.5", str(DRIVING)]) == 2
    assert "(0, 1]" in capsys.readouterr().err


def test_a_step_of_several_samples_discounts_less() -> None:
    """A step that spans 5 samples discounts by gamma once per 5: stdlib/driving.ra's return holds at
    0.99 per decision of 5 samples where it fails at 0.99 per sample (gamma**60 against gamma**300)."""
    automaton = rac.compile_file(DRIVING).raise_for_errors()
    outs = moves(automaton, InputSpace(automaton))
    target = dataclasses.replace(check_target(automaton))
    per_sample = discounted_worst(automaton, outs, target, Discount(Fraction(99, 100), 1))
    per_decision = discounted_worst(automaton, outs, target, Discount(Fraction(99, 100), 5))
    assert per_sample is not None and per_decision is not None
    assert per_decision.value < per_sample.value


def check_target(automaton: ir.Automaton) -> Target:
    from rac.check.analysis.priority import p2_target

    return p2_target(automaton, 0)


KEEP = """automaton Keep {
    input isClose : bool
    reward sa, pr
    priority sa > pr
    objective 10 * sa + pr
    sample every 0.1
    horizon 300
    initial location Normal { sa' == 1;  pr' == 1 }
    location Close          { sa' == -1; pr' == 0 }
    edge Normal -> Close when isClose do sa = sa - 400
}
"""


def test_a_long_horizons_values_reach_json(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """3,000 samples at 0.99: the discounted value's denominator has 6,000 digits, more than Python
    writes out as text, and the JSON report was an internal error (exit 3). Now rounded, and marked."""
    path = tmp_path / "keep.ra"
    path.write_text(KEEP)
    assert main(["check", "--format", "json", "--discount", "0.99", str(path)]) == 1
    found = json.loads(capsys.readouterr().out)[0]["diagnostics"][-1]
    assert found["code"] == DISCOUNTED_P2
    assert found["data"]["value"].endswith("…") and 100 < float(found["data"]["value"][:-1]) < 120
    assert found["data"]["undiscounted"] == "-700"  # 10 * (300 - 400) + 300


def test_the_hints_command_checks_steps_of_as_many_samples(capsys: pytest.CaptureFixture[str]) -> None:
    """stdlib/driving.ra at 0.9 per step of 5 samples holds at 0.999 per step of 5, not per sample: the
    hint's command said `rac check --discount 0.999`, which checks steps of 1 sample and fails (E0410)."""
    assert main(["check", "-q", "--discount", "0.9", "--samples-per-step", "5", str(DRIVING)]) == 1
    hint = next(line for line in capsys.readouterr().out.splitlines() if "hint: with gamma" in line)
    assert "(rac check --discount 0.999 --samples-per-step 5)" in hint
    assert main(["check", "-q", "--discount", "0.999", "--samples-per-step", "5", str(DRIVING)]) == 0
    assert main(["check", "-q", "--discount", "0.999", str(DRIVING)]) == 1  # what the hint said before


ACCRUING = """automaton Accruing {
    input isClose : bool
    reward sa, pr
    priority sa > pr
    objective 10 * sa + pr
    sample every 1
    horizon 4
    initial location Normal { sa' == 0; pr' == 1 }
    location Close          { sa' == 0; pr' == 3 }
    edge Normal -> Close when isClose do sa = sa - 0.35
}
"""


def test_an_instant_before_the_next_sample_is_in_that_samples_step() -> None:
    """At 0.9 the worst instant is t = 4 s just before the next sample: the accrual since sample 3 is
    step 4's reward (weighed 0.9**3 = 0.729), and the note named step 3 and its weight 0.81."""
    automaton = compile_text(ACCRUING, "accruing.ra", analyse=False).automaton
    assert automaton is not None
    found = check_discounted(automaton, Discount(Fraction(9, 10)))
    assert [d.code for d in found] == [DISCOUNTED_P2]
    assert "just before the next sample" in found[0].notes[1].message
    assert "in the learner's step 4:" in found[0].notes[1].message, found[0].notes[1].message
    assert "(here 0.729 at that step)" in found[0].notes[2].message
    # the value is what the learner's steps 1-4 earn, the fourth of them the accrual alone
    rewards = [1 - Fraction(35, 10), 3, 3, 3]  # step 1: Normal accrues pr, the edge costs 10 * 0.35; then Close
    assert Fraction(found[0].data["value"]) == sum(Fraction(9, 10) ** j * r for j, r in enumerate(rewards))


def test_a_gamma_of_many_digits_over_a_long_horizon_is_not_searched() -> None:
    """gamma = 1 - 1/300 as a float (0.9966666666666667, 16 digits) over 20,000 samples: its powers
    carry 320,000 digits and the search took 19 s at the start of learn(); it is W0405 now, saying
    why, while 0.997 over the same horizon is searched."""
    long_keep = KEEP.replace("horizon 300", "horizon 2000").replace("sa - 400", "sa - 4000")
    automaton = compile_text(long_keep, "keep.ra").raise_for_errors()
    found = check_discounted(automaton, Discount(Fraction("0.9966666666666667")))
    assert [d.code for d in found] == [UNFINISHED]
    assert "denominator has 17 digits" in found[0].message and "would carry 319,984 digits" in found[0].message
    assert [d.code for d in check_discounted(automaton, Discount(Fraction("0.997")))] == [DISCOUNTED_P2]


TWO_LEVELS = """automaton Two {
    input close : bool
    input stall : bool
    assume !(close && stall)
    reward sa, pr
    priority strict sa > pr
    objective 10 * sa + pr
    sample every 0.1
    horizon 30
    initial location Normal { sa' == 1; pr' == 1 }
    location Unsafe { sa' == -1; pr' == 0 }
    location Stalled { sa' == 0; pr' == -1 }
    edge * -> Unsafe when close do sa = sa - 200
    edge * -> Stalled when stall && !close do pr = pr - 30
    edge * -> Normal when !close && !stall
}
"""


def test_a_hints_gamma_holds_at_every_level() -> None:
    """Under `priority strict`, `sa`'s E0410 at 0.9 named 0.995, at which `sa`'s level holds but `pr`'s
    fails (30 s of progress, then a stall's -30, discounted: the penalty counts less than the gains at any
    gamma below 1): rac check --discount 0.995 then failed again. A hint's gamma holds at every level."""
    automaton = compile_text(TWO_LEVELS, "two.ra").raise_for_errors()
    found = check_discounted(automaton, Discount(Fraction(9, 10)))
    assert [d.data["reward"] for d in found] == ["sa", "pr"]
    assert all("it holds" not in d.hints[0] for d in found), [d.hints for d in found]
    assert [d.data["reward"] for d in check_discounted(automaton, Discount(Fraction(995, 1000)))] == ["pr"]


@given(st.fractions(), st.integers(0, 400))
def test_a_bound_is_written_rounded_up(value: Fraction, scale: int) -> None:
    """A proved bound that is rounded for the fact is rounded up: to nearest, -184.9466 read -184.947, a
    bound below the value it bounds (the discounted values have denominators of thousands of digits)."""
    from rac.check.analysis.discount import upper_text

    value = value / Fraction(3) ** scale
    text = upper_text(value)
    shown = Fraction(text.removesuffix("…"))
    assert shown >= value and (text.endswith("…") or shown == value)


def test_a_synthesised_parameter_searches_the_discounted_p2(tmp_path: Path) -> None:
    """With --discount and a `param`, the synthesis searched P1, P2 and the range only, and its fact said so: the
    file was checked at PENALTY = 98, where E0410 refutes the discounted P2. A run's discounted value is affine in
    the penalty too, so the synthesis searches it: the least PENALTY for gamma 0.99 is 357.156…, exactly."""
    text = DRIVING.read_text(encoding="utf-8").replace("const PENALTY = 100", "param PENALTY in [0, 1000]")
    path = tmp_path / "driving_param.ra"
    path.write_text(text, encoding="utf-8")
    gamma = Discount(Fraction(99, 100))
    result = rac.compile_file(path, discount=gamma)
    assert result.ok and DISCOUNTED_P2 not in [d.code for d in result.diagnostics]
    (synthesis,) = [f for f in result.facts if f.check == "synthesis"]
    assert synthesis.message.startswith("synthesised: PENALTY >= 357.156… (every check holds for PENALTY in "
                                        "[357.156…, 1000]); checked with PENALTY = 357.1558, the least value")
    assert synthesis.message.endswith("; P2 of the discounted return (`--discount`) is searched too")
    assert result.synthesis is not None and result.synthesis.value("PENALTY") == Fraction(3571558, 10000)
    assert any(f.check == "P2-discounted" for f in result.facts)
    # a risk tolerance with gamma's powers in it is rounded once ("p* = 0.139995…"), not "0.139995… ≈ 0.139995…"
    (risk,) = [f.message for f in result.facts if f.message.startswith("risk tolerance")]
    assert risk.startswith("risk tolerance p* = 0.139995…; "), risk
    # the set's end is exact: the discounted check holds at it and fails just below
    (lowest,) = result.synthesis.inequalities
    end = Fraction(lowest.removeprefix("PENALTY >= ").replace(" ", ""))
    node = parse_text(text, "driving_param.ra").automata[0]
    for value, holds in ((end, True), (end - Fraction(1, 10**9), False)):  # (its digits are no literal's)
        fixed = Resolver(node, {"PENALTY": value}).run()
        assert fixed is not None and (not check_discounted(fixed, gamma)) is holds
    plain = compile_text(text, "driving_param.ra")
    assert "every check holds for PENALTY in [98, 1000]); checked with PENALTY = 98" in plain.facts[0].message


def test_a_synthesis_where_the_discounted_search_does_not_go_says_so() -> None:
    """An update that scales a reward (`pr = pr / 2`) is beyond the discounted search: the synthesis is that of
    the other checks, and the fact says the discounted P2 is checked at the value only (W0405 there)."""
    text = """automaton S {
    input bad : bool
    param P in [1, 100]
    reward sa, pr
    priority sa > pr
    objective 10 * sa + pr
    sample every 1
    horizon 5
    initial location Ok { sa' == 1; pr' == 1 }
    location Bad { sa' == 0; pr' == 1 }
    edge * -> Bad when bad do sa = sa - P, pr = pr / 2
    edge * -> Ok when !bad
}
"""
    result = compile_source(SourceFile("scaling.ra", text), discount=Discount(Fraction(9, 10)))
    assert [d.code for d in result.diagnostics] == ["W0405"]
    assert result.proved[0] == ("synthesised: P >= 5.25 (every check but P2 of the discounted return holds for P in "
                                "[5.25, 100]); checked with P = 5.25; P2 of the discounted return (`--discount`) is "
                                "checked at that value only")


def test_several_weights_search_the_discounted_p2() -> None:
    """Several weights: a run's discounted value is linear in them too (each reward's discounted sum of changes
    times its weight), so the polyhedron's oracle cuts with the discounted P2 as with P2; every integer point
    near its boundary is checked with the weights as constants."""
    def weighted(weights: str) -> str:
        return DRIVING.read_text(encoding="utf-8").replace("objective 10 * sa + 5 * pr + co", f"objective {weights}"
                                                           ).replace("const PENALTY = 100", "const PENALTY = 1000")
    gamma = Discount(Fraction(99, 100))
    text = weighted("w1 * sa + w2 * pr + co").replace("const PENALTY = 1000",
                                                       "const PENALTY = 1000\n    param w1, w2 in [1, 100]")
    result = compile_source(SourceFile("weights.ra", text), discount=gamma)
    assert result.ok, [d.message for d in result.diagnostics]
    assert result.proved[0] == (
        "synthesised: every check holds exactly where w1 >= 0.36134… * w2 + 0.237581… (w1, w2 in [1, 100]); checked "
        "with w1 = 1, w2 = 1, the lexicographically least integer weights, `w1` first; P2 of the discounted return "
        "(`--discount`) is searched too")
    assert result.proved[1].startswith("the set of (w1, w2) has 5 vertices, each checked: (1, 1), (1, 2.10998…), ")
    plain = compile_text(text, "weights.ra")
    assert plain.proved[0].startswith("synthesised: every check holds exactly where 97 * w1 >= 13 * w2 + 3 ")
    for w1, w2 in ((1, 2), (1, 3), (2, 4), (2, 5), (36, 100), (37, 100)):
        fixed = compile_source(SourceFile("fixed.ra", weighted(f"{w1} * sa + {w2} * pr + co")), discount=gamma)
        assert fixed.ok is (w1 >= Fraction(36134, 100000) * w2 + Fraction(237581, 1000000)), (w1, w2)


def test_several_weights_where_the_discounted_search_does_not_go_say_so() -> None:
    text = """automaton S {
    input bad : bool
    param u, v in [1, 100]
    reward sa, pr
    priority sa > pr
    objective u * sa + v * pr
    sample every 1
    horizon 5
    initial location Ok { sa' == 1; pr' == 1 }
    location Bad { sa' == 0; pr' == 1 }
    edge * -> Bad when bad do sa = sa - 20, pr = pr / 2
    edge * -> Ok when !bad
}
"""
    result = compile_source(SourceFile("scaling.ra", text), discount=Discount(Fraction(9, 10)))
    assert "W0405" in [d.code for d in result.diagnostics]
    assert "every check but P2 of the discounted return holds exactly where" in result.proved[0]
    assert result.proved[0].endswith("; P2 of the discounted return (`--discount`) is checked at that value only")
