"""The incentive checks of issue 25 (R_goal, R_stall, R_crash, p*, and the three loopholes) against a
brute force over every run of tiny random automata, and their witnesses replayed.

Automata are generated as `.ra` text (deterministic by construction, as in test_worst.py: each
location partitions the input cells among its edges), compiled by the real front end; the `goal`,
`collision` and `episode ends` conditions are random guards set on the IR. The brute force
(tests/support/reference.py's valuations and sample semantics) simulates every input sequence with
exact fractions: a run ends at the first sample whose inputs satisfy `episode ends`, else at the
horizon, and its `at end` clauses read that sample's inputs. Every witness run printed (`--format
json`: the loopholes' `better` and `worse`, p*'s `witnesses`) is replayed by the interpreter
(rac.runtime.interpreter, what rac.load gives), which ends a run itself where `episode ends when`
holds: it must end, reach the goal and collide as it claims, a loophole's pair must show its claim
(the better run's return above the worse run's), and a run that only approaches a value (a
supremum) must be near enough its limit to.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import os
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from reference import ZERO, accrue, assign, at_end, edge_for, valuations

from rac import ir
from rac.check.analysis.affine import moves
from rac.check.analysis.behaviour import input_space
from rac.check.analysis.incentives import (
    Findings,
    Run,
    Unchecked,
    analyse,
    check_incentives,
    risk_tolerance,
    split_guards,
)
from rac.check.analysis.priority import replay
from rac.compiler import compile_file, compile_text
from rac.core.diagnostics import Fact
from rac.ir.inputs import InputSpace
from rac.runtime.interpreter import RewardAutomaton

SETTINGS = settings(max_examples=int(os.environ.get("RAC_EXAMPLES", "150")), deadline=None,
                    derandomize=not os.environ.get("RAC_EXAMPLES"),
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
REPO = Path(__file__).resolve().parents[2]
#: The brute force enumerates at most this many input sequences (the horizon shrinks to fit).
MAX_SEQUENCES = 5000


@dataclass
class Case:
    text: str
    automaton: ir.Automaton

    def __repr__(self) -> str:
        a = self.automaton
        return (f"Case(steps={a.steps}, goal={a.goal!r}, collision={a.collision!r}, "
                f"episode_ends={a.episode_ends!r}, text=\n{self.text})")


@st.composite
def conditions(draw, bools: list[str], numeric: bool, threshold: Fraction) -> ir.Guard:
    leaves: list[ir.Guard] = [ir.BInput(b) for b in bools] + [ir.BNot(ir.BInput(b)) for b in bools]
    if numeric:
        leaves += [ir.BAtom("x", "<", threshold), ir.BAtom("x", ">=", threshold), ir.BAtom("x", "==", threshold),
                   ir.BAtom("x", ">", Fraction(1, 2))]
    first = draw(st.sampled_from(leaves))
    shape = draw(st.sampled_from(["leaf", "leaf", "and", "or"]))
    if shape == "leaf":
        return first
    second = draw(st.sampled_from(leaves))
    return ir.BAnd((first, second)) if shape == "and" else ir.BOr((first, second))


@st.composite
def cases(draw, real: bool = False) -> Case:
    """``real``: a real input the rates and updates read (its guards cut where runs approach a value)."""
    bools = ["a", "b", "c"][: draw(st.sampled_from([1, 1, 2, 2, 3]))]
    kind = "real" if real else draw(st.sampled_from([None, None, None, "int", "real"]))
    # Crashes that cost: `collision when a`, and every sample with `a` goes to the last location with a
    # penalty (else random rewards rarely make R_crash < R_goal, and p* is rarely a probability).
    crashy = draw(st.booleans())
    threshold = Fraction(draw(st.sampled_from([1, 2])))
    in_rates = kind is not None and (real or draw(st.booleans()))
    in_updates = kind is not None and (real or draw(st.booleans()))
    rewards = ["p", "q"][: draw(st.integers(1, 2))]
    n_loc = draw(st.integers(2, 3))
    locs = [f"L{i}" for i in range(n_loc)]
    literal_sets = [[b, f"!{b}"] for b in bools]
    if kind is not None:
        literal_sets.append([f"x < {threshold}", f"x >= {threshold}"])
    cells = [" && ".join(combo) for combo in itertools.product(*literal_sets)]

    def guard(chosen: list[int]) -> str:
        return "true" if len(chosen) == len(cells) else " || ".join(f"({cells[i]})" for i in sorted(chosen))

    def rate() -> str:
        text = str(draw(st.integers(-2, 2)))
        if in_rates and draw(st.booleans()):
            text += f" + {draw(st.sampled_from(['1', '-1']))}*x"
        return text

    def update() -> str:
        r = draw(st.sampled_from(rewards))
        c = draw(st.integers(-3, 3))
        if in_updates and draw(st.booleans()):
            return f"{r} = {r} + {draw(st.sampled_from(['1', '-1']))}*x + {c}"
        return f"{r} = {r} + {c}"

    def updates() -> str:
        items = [update() for _ in range(draw(st.integers(0, 2)))]
        return f" do {', '.join(items)}" if items else ""

    lines = ["automaton Random {"]
    lines += [f"    input {b} : bool" for b in bools]
    if kind is not None:
        lines.append(f"    input x : {kind} in [0, 3]")
    if len(cells) > 2 and draw(st.booleans()):
        lines.append(f"    assume !({guard([draw(st.integers(0, len(cells) - 1))])})")
    lines.append(f"    reward {', '.join(rewards)}")
    weights = [draw(st.integers(1, 3) if crashy and r == "p" else st.integers(-2, 3)) for r in rewards]
    constant = draw(st.integers(-1, 1))
    lines.append(f"    objective {' + '.join(f'{w} * {r}' for w, r in zip(weights, rewards))} + {constant}")
    lines.append("    sample every 1")
    lines.append("    horizon 5")
    initial = draw(st.integers(0, n_loc - 1))
    for i, name in enumerate(locs):
        flows = "; ".join(f"{r}' == {rate()}" for r in rewards)
        lines.append(f"    {'initial ' if i == initial else ''}location {name} {{ {flows} }}")
    crashing = [c for c in range(len(cells)) if crashy and cells[c].startswith("a")]
    for name in locs:
        if crashing:
            lines.append(f"    edge {name} -> {locs[-1]} when {guard(crashing)} do p = p - {draw(st.integers(4, 9))}")
        choice = {c: draw(st.sampled_from([None, *range(n_loc)])) for c in range(len(cells)) if c not in crashing}
        for target in range(n_loc):
            chosen = [c for c in choice if choice[c] == target]
            if chosen:
                lines.append(f"    edge {name} -> {locs[target]} when {guard(chosen)}{updates()}")
    for _ in range(draw(st.integers(0, 1))):
        chosen = draw(st.lists(st.integers(0, len(cells) - 1), min_size=1, max_size=len(cells), unique=True))
        when = "" if len(chosen) == len(cells) else f" when {guard(chosen)}"
        lines.append(f"    at end{when} do {update()}")
    lines.append("}")
    text = "\n".join(lines) + "\n"
    result = compile_text(text, "random.ra", analyse=False)
    assert result.automaton is not None, (text, result.diagnostics)
    numeric = kind is not None
    goal = draw(st.one_of(st.none(), conditions(bools, numeric, threshold), conditions(bools, numeric, threshold)))
    collision = ir.BInput("a") if crashy else draw(st.one_of(st.none(), conditions(bools, numeric, threshold)))
    ends = draw(st.one_of(st.none(), conditions(bools, numeric, threshold)))
    automaton = dataclasses.replace(result.automaton, goal=goal, collision=collision, episode_ends=ends)
    count = len(valuations(automaton))
    steps = draw(st.integers(2, 5))
    while steps > 1 and count ** steps > MAX_SEQUENCES:
        steps -= 1
    automaton = dataclasses.replace(automaton, horizon=Fraction(steps))
    return Case(text, automaton)


# ---------------------------------------------------------------- the brute force
@dataclass
class Sampled:
    """One sample of a brute-force run: where it started, the objective before it, the flags."""

    location: int
    before: Fraction
    ends: bool
    goal: bool
    collision: bool


@dataclass
class BruteRun:
    value: Fraction
    samples: list[Sampled]

    @property
    def safe(self) -> bool:
        return not any(s.collision for s in self.samples)

    @property
    def first_goal(self) -> int | None:
        return next((k for k, s in enumerate(self.samples, start=1) if s.goal), None)


def holds(guard: ir.Guard | None, values: dict[str, object]) -> bool:
    return guard is not None and ir.evaluate_guard(guard, values)


def brute_runs(automaton: ir.Automaton) -> list[BruteRun]:
    """Every run over every input sequence, simulated from the semantics."""
    xs = valuations(automaton)
    steps = automaton.steps

    def objective(r: tuple[Fraction, ...]) -> Fraction:
        return automaton.objective.const + sum((automaton.objective.coefficient(n) * v
                                                for n, v in zip(automaton.rewards, r)), ZERO)

    found: list[BruteRun] = []

    def go(k: int, location: int, r: tuple[Fraction, ...], held, done: list[Sampled]) -> None:
        for v in xs:
            if k == 1:
                before = objective(r)
                accrued = accrue(automaton, location, r, v.values)
            else:
                accrued = accrue(automaton, location, r, held.values)
                before = objective(accrued)
            edge = edge_for(automaton, location, v.guards)
            after = assign(automaton, edge.updates, accrued, v.values) if edge else accrued
            target = edge.target if edge else location
            here = Sampled(location, before, holds(automaton.episode_ends, v.guards),
                           holds(automaton.goal, v.guards), holds(automaton.collision, v.guards))
            if here.ends or k == steps:
                found.append(BruteRun(objective(at_end(automaton, after, v)), [*done, here]))
            else:
                go(k + 1, target, after, v, [*done, here])

    go(1, automaton.initial, tuple(ZERO for _ in automaton.rewards), None, [])
    return found


def best(values) -> Fraction | None:
    values = list(values)
    return max(values) if values else None


@dataclass
class Oracle:
    goal: Fraction | None
    stall: Fraction | None
    crash: Fraction | None
    by_sample: dict[int, Fraction]
    early_delta: Fraction | None  # max E - V over the points where ending early pays (None: none)


def oracle(automaton: ir.Automaton, runs: list[BruteRun]) -> Oracle:
    by_sample: dict[int, Fraction] = {}
    for run in runs:
        k = run.first_goal
        if run.safe and k is not None:
            by_sample[k] = max(by_sample.get(k, run.value), run.value)
    early: dict[tuple[int, int], Fraction] = {}
    safe: dict[tuple[int, int], Fraction] = {}
    for run in runs:
        n = len(run.samples)
        for k, s in enumerate(run.samples, start=1):
            point = (k, s.location)
            rest = run.value - s.before
            if k == n and s.ends and not s.goal:
                early[point] = max(early.get(point, rest), rest)
            elif not any(t.collision for t in run.samples[k - 1:]):
                safe[point] = max(safe.get(point, rest), rest)
    gaps = [early[p] - safe[p] for p in early if p in safe and early[p] > safe[p]]
    return Oracle(best(r.value for r in runs if r.safe and r.first_goal is not None),
                  best(r.value for r in runs if r.safe and r.first_goal is None),
                  best(r.value for r in runs if not r.safe),
                  by_sample, max(gaps) if gaps else None)


# ---------------------------------------------------------------- witnesses
def check_witness(automaton: ir.Automaton, space: InputSpace, run: Run) -> None:
    """The run's flags are what it claims and its exact replay gives its value (the interpreter replays
    the run as printed: :func:`check_printed_witnesses`)."""
    steps = run.worst.steps
    valuations_ = [space.valuation(step.outcome.cls) for step in steps]
    ends = [holds(automaton.episode_ends, v) for v in valuations_]
    assert not any(ends[:-1])
    assert (run.ended_by == "episode") == ends[-1]
    if not ends[-1]:
        assert len(steps) == automaton.steps
    goals = [k for k, v in enumerate(valuations_, start=1) if holds(automaton.goal, v)]
    assert run.goal_sample == (goals[0] if goals else None)
    for k, step in enumerate(steps, start=1):
        assert step.sample == k
    values, _ = replay(automaton, space, run.worst)
    objective = automaton.objective
    assert objective.const + sum((objective.coefficient(n) * v for n, v in zip(automaton.rewards, values)),
                                 ZERO) == run.value


def approaches(witness: dict) -> bool:
    """Whether a printed run only approaches a value somewhere (a supremum: its inputs are near the limit)."""
    return any(e["approached"] for e in witness["run"]) or bool((witness["end"] or {}).get("approached"))


@dataclass
class Replayed:
    value: float
    ended_by: str
    goal_sample: int | None
    collided: bool
    inputs: list[dict[str, object]]  # per sample


def replay_json(automaton: ir.Automaton, witness: dict) -> Replayed:
    """A printed witness run fed to the interpreter sample by sample, as a user replays it with rac.load;
    at the horizon the training loop passes the end's inputs to end(), as the checks assume."""
    def exact(inputs: dict) -> dict[str, object]:
        return {k: v if isinstance(v, bool) else Fraction(v) for k, v in inputs.items()}

    samples = [exact(e["inputs"]) for e in witness["run"] for _ in range(e["sample"], e["last_sample"] + 1)]
    assert [k for e in witness["run"] for k in range(e["sample"], e["last_sample"] + 1)] == \
        list(range(1, len(samples) + 1))
    interpreter = RewardAutomaton(automaton)
    for x in samples:
        assert not interpreter.ended
        interpreter.step({k: v if isinstance(v, bool) else float(v) for k, v in x.items()})
    ended_by = "episode" if interpreter.terminated else "horizon"
    if not interpreter.terminated:
        assert len(samples) == automaton.steps
        end = exact(witness["end"]["inputs"])
        assert end == samples[-1]
        interpreter.end({k: v if isinstance(v, bool) else float(v) for k, v in end.items()})
    assert interpreter.ended
    goals = [k for k, x in enumerate(samples, start=1) if holds(automaton.goal, x)]
    return Replayed(interpreter.objective, ended_by, goals[0] if goals else None,
                    any(holds(automaton.collision, x) for x in samples), samples)


def check_printed(automaton: ir.Automaton, witness: dict) -> Replayed:
    """The printed run, replayed, ends, reaches the goal and earns as it says (below its return when it
    only approaches a value: the return is then a supremum)."""
    got = replay_json(automaton, witness)
    assert (got.ended_by, got.goal_sample) == (witness["ended_by"], witness["goal_sample"])
    claimed = float(Fraction(witness["return"]))
    if approaches(witness):
        assert got.value <= claimed + 1e-9, (got.value, witness)
    else:
        assert math.isclose(got.value, claimed, abs_tol=1e-9), (got.value, witness)
    return got


def check_printed_witnesses(automaton: ir.Automaton, space: InputSpace, outs) -> None:
    """Every witness run `rac check` prints for the incentive checks, replayed by the interpreter: p*'s
    three runs, and each loophole's pair, which must show the loophole's claim."""
    facts: list[Fact] = []
    diagnostics = check_incentives(automaton, space, facts, outs)
    for fact in facts:
        if fact.check == "risk":
            witnesses = fact.data["witnesses"]
            assert isinstance(witnesses, dict)
            for name, witness in witnesses.items():
                if witness is not None:
                    got = check_printed(automaton, witness)
                    assert got.collided == (name == "crash")
    for d in diagnostics:
        if d.code not in ("W1002", "W1004", "W1006"):
            continue
        better, worse = d.data["better"], d.data["worse"]
        b, w = check_printed(automaton, better), check_printed(automaton, worse)
        if d.code == "W1002":  # the run ends early there without the goal; a safe rest goes on from there
            k = d.data["sample"]
            assert (b.ended_by, len(b.inputs)) == ("episode", k) and not holds(automaton.goal, b.inputs[-1])
            assert b.inputs[:k - 1] == w.inputs[:k - 1] and len(w.inputs) >= k
            assert not any(holds(automaton.collision, x) for x in w.inputs[k - 1:])
            assert not (w.ended_by == "episode" and len(w.inputs) == k and not holds(automaton.goal, w.inputs[-1]))
        elif d.code == "W1004":  # first reaching the goal later pays more, both runs safe
            assert (b.goal_sample, w.goal_sample) == (d.data["sample"], d.data["other_sample"])
            assert not b.collided and not w.collided
        else:  # stalling beats reaching the goal, both runs safe
            assert (b.goal_sample, w.goal_sample) == (None, d.data["sample"])
            assert not b.collided and not w.collided
        # the claim, replayed: the better run earns more, by at least half the gap the returns claim
        gap = Fraction(better["return"]) - Fraction(worse["return"])
        assert gap > 0 and b.value - w.value >= float(gap) / 2 - 1e-9, (b.value, w.value, d.data)


# ---------------------------------------------------------------- the property
@SETTINGS
@given(cases())
def test_incentives_agree_with_brute_force(case: Case) -> None:
    automaton = case.automaton
    space, problems = input_space(automaton)
    assert space is not None and not problems
    if not space.valid.any():
        return
    outs = moves(automaton, space, split_guards(automaton))
    found = analyse(automaton, space, outs)
    assert isinstance(found, Findings)
    check_printed_witnesses(automaton, space, outs)
    runs = brute_runs(automaton)
    expected = oracle(automaton, runs)
    verdicts = found.verdicts
    if automaton.episode_ends is None:
        assert "ending_early_never_pays" not in verdicts
    else:
        early = verdicts["ending_early_never_pays"]
        assert (early is None) == (expected.early_delta is None)
        if early is not None:
            assert early.delta == expected.early_delta
            assert early.better.value - early.worse.value == early.delta
            assert early.better.worst.steps[:early.prefix] == early.worse.worst.steps[:early.prefix]
            assert early.better.ended_by == "episode" and early.better.samples == early.sample
            for run in (early.better, early.worse):
                check_witness(automaton, space, run)
    if automaton.goal is None:
        assert found.incentives is None and set(verdicts) <= {"ending_early_never_pays"}
        return
    incentives = found.incentives
    assert incentives is not None
    for name in ("goal", "stall", "crash"):
        run = getattr(incentives, name)
        assert (None if run is None else run.value) == getattr(expected, name), name
        if run is not None:
            check_witness(automaton, space, run)
    if incentives.goal is not None:
        assert incentives.goal.goal_sample is not None
    if incentives.crash is not None:
        assert any(holds(automaton.collision, space.valuation(s.outcome.cls)) for s in incentives.crash.worst.steps)
    assert incentives.goal_by_sample == expected.by_sample
    # p*, from the oracle's returns by the formula.
    p, _ = risk_tolerance(incentives.goal, incentives.stall, incentives.crash, automaton.collision is not None)
    assert incentives.p_star == p
    if None not in (expected.goal, expected.stall, expected.crash) and automaton.collision is not None:
        assert expected.goal is not None and expected.stall is not None and expected.crash is not None
        if expected.crash < expected.goal:
            assert p == (expected.goal - expected.stall) / (expected.goal - expected.crash)
        else:
            assert p is None
    else:
        assert p is None
    # Reaching the goal earlier never pays less.
    g = expected.by_sample
    pairs = [(k1, k2) for k1 in g for k2 in g if k1 < k2 and g[k1] < g[k2]]
    earlier = verdicts["goal_earlier_never_pays_less"]
    assert (earlier is None) == (not pairs)
    if earlier is not None:
        k2, k1 = earlier.sample, earlier.other_sample
        assert (k1, k2) in pairs and earlier.delta == g[k2] - g[k1]
        assert g[k2] == max(g[b] for _, b in pairs)
        assert k2 == min(b for _, b in pairs if g[b] == g[k2])
        assert k1 == min(a for a, b in pairs if b == k2)
        assert (earlier.better.goal_sample, earlier.worse.goal_sample) == (k2, k1)
        assert (earlier.better.value, earlier.worse.value) == (g[k2], g[k1])
        for run in (earlier.better, earlier.worse):
            check_witness(automaton, space, run)
    # Stalling never beats reaching the goal.
    beaten = [k for k in g if expected.stall is not None and expected.stall > g[k]]
    stalling = verdicts["stalling_never_pays"]
    assert (stalling is None) == (not beaten)
    if stalling is not None:
        assert expected.stall is not None
        assert stalling.sample == max(beaten)
        assert stalling.delta == expected.stall - min(g[k] for k in beaten)
        assert stalling.better.value == expected.stall and stalling.worse.value == g[max(beaten)]
        assert stalling.worse.goal_sample == max(beaten)


def test_scaling_updates_are_not_checked() -> None:
    text = """automaton A {
    input a : bool
    reward p
    objective p
    sample every 1
    horizon 3
    initial location L { p' == 1 }
    edge L -> L when a do p = p / 2
}
"""
    automaton = compile_text(text).raise_for_errors()
    automaton = dataclasses.replace(automaton, goal=ir.BInput("a"))
    space = InputSpace(automaton)
    found = analyse(automaton, space)
    assert isinstance(found, Unchecked) and "scales" in found.reason


@pytest.mark.parametrize("ends", [False, True])
def test_driving_with_a_goal(ends: bool) -> None:
    """stdlib/driving.ra over 3 s, `goal when dgoal < 2`, `collision when collide`: the numbers docs/checks.md shows."""
    automaton = compile_file(REPO / "stdlib" / "driving.ra").raise_for_errors()
    goal, collide = ir.BAtom("dgoal", "<", Fraction(2)), ir.BInput("collide")
    automaton = dataclasses.replace(automaton, horizon=Fraction(3), goal=goal, collision=collide,
                                    episode_ends=ir.BOr((collide, goal)) if ends else None)
    space = InputSpace(automaton)
    found = analyse(automaton, space)
    assert isinstance(found, Findings) and found.incentives is not None
    incentives = found.incentives
    assert incentives.goal is not None and incentives.stall is not None and incentives.crash is not None
    # 30 samples in Normal: 10 + 5 + 1 per second, 3 s -> 48; the goal adds 100 to pr (x5).
    assert (incentives.goal.value, incentives.stall.value) == (548, 48)
    assert incentives.crash.value == 548 - 1000
    assert incentives.p_star == Fraction(1, 2)
    earlier = found.verdicts["goal_earlier_never_pays_less"]
    assert (earlier is not None) == ends


# ---------------------------------------------------------------- diagnostics and facts
NAIVE = """automaton Naive {
    input collide : bool
    input dgoal   : real in [0, 500]

    reward time, crash, arrived
    objective -1 * time - 5 * crash + 10 * arrived

    sample every 0.1
    horizon 30

    initial location Driving { time' == 1; crash' == 0; arrived' == 0 }

    edge Driving -> Driving when collide do crash = crash + 1

    at end when dgoal < 2 do arrived = arrived + 1
}
"""


def naive(**changes: object) -> ir.Automaton:
    """A naive weighted sum: time costs every sample, a collision ends the episode with a small penalty."""
    automaton = compile_text(NAIVE).raise_for_errors()
    goal, collide = ir.BAtom("dgoal", "<", Fraction(2)), ir.BInput("collide")
    return dataclasses.replace(automaton, goal=goal, collision=collide, episode_ends=collide, **changes)


def driving(ends: bool, **changes: object) -> ir.Automaton:
    automaton = compile_file(REPO / "stdlib" / "driving.ra").raise_for_errors()
    goal, collide = ir.BAtom("dgoal", "<", Fraction(2)), ir.BInput("collide")
    return dataclasses.replace(automaton, goal=goal, collision=collide,
                               episode_ends=ir.BOr((collide, goal)) if ends else None, **changes)


def checked(automaton: ir.Automaton) -> tuple[list[str], dict[str, Fact]]:
    facts: list[Fact] = []
    diagnostics = check_incentives(automaton, InputSpace(automaton), facts)
    return [d.code for d in diagnostics], {f.check: f for f in facts}


def require(*checks: str, bound: Fraction = Fraction(1, 10000)) -> tuple[ir.Requirement, ...]:
    return tuple(ir.Requirement(c, bound if c == "risk" else None) for c in checks)


def test_driving_facts() -> None:
    codes, facts = checked(driving(False))
    assert codes == []
    assert set(facts) == {"risk", "goal_earlier_never_pays_less", "stalling_never_pays"}
    risk = facts["risk"]
    assert risk.message.startswith("risk tolerance p* = 0.5; R_goal = 980, R_stall = 480, R_crash = -20")
    assert risk.data["p_star"] == "1/2" and risk.data["p_star_decimal"] == "0.5"
    witnesses = risk.data["witnesses"]
    assert isinstance(witnesses, dict) and witnesses["crash"]["return"] == "-20"


def test_driving_with_episode_ends_delays_the_goal() -> None:
    codes, facts = checked(driving(True))
    assert codes == ["W1004"] and "ending_early_never_pays" in facts
    codes, _ = checked(driving(True, requirements=require(*ir.REQUIREMENT_CHECKS)))
    assert sorted(codes) == ["E1001", "E1005"]
    codes, _ = checked(driving(True, requirements=require("risk", bound=Fraction(1, 2))))
    assert codes == ["W1004"]  # p* = 1/2 is within the bound


def test_naive_weighted_sum_ending_early_pays() -> None:
    automaton = naive()
    space = InputSpace(automaton)
    found = analyse(automaton, space)
    assert isinstance(found, Findings) and found.incentives is not None
    early = found.verdicts["ending_early_never_pays"]
    assert early is not None and early.sample == 1 and early.delta == Fraction(149, 10)
    assert found.incentives.p_star is None and "any crash risk" in found.incentives.p_note
    codes, facts = checked(automaton)
    assert sorted(codes) == ["W1002"]
    codes, _ = checked(naive(requirements=require("ending_early_never_pays", "risk")))
    assert sorted(codes) == ["E1001", "E1003"]


def test_stalling_beats_the_goal() -> None:
    # Stalling in Normal earns more than reaching the goal (which carries a cost here).
    automaton = compile_text(NAIVE.replace("objective -1 * time", "objective 1 * time")
                             .replace("+ 10 * arrived", "- 10 * arrived")).raise_for_errors()
    automaton = dataclasses.replace(automaton, goal=ir.BAtom("dgoal", "<", Fraction(2)),
                                    collision=ir.BInput("collide"))
    codes, facts = checked(automaton)
    assert codes == ["W1006"]
    codes, _ = checked(dataclasses.replace(automaton, requirements=require("stalling_never_pays")))
    assert codes == ["E1007"]


def test_not_done_is_a_warning() -> None:
    automaton = naive()
    scaled = dataclasses.replace(automaton, end_clauses=(dataclasses.replace(
        automaton.end_clauses[0], updates=(ir.Assignment("arrived", ir.Linear(Fraction(1))),)),))
    codes, facts = checked(scaled)
    assert codes == ["W1008"] and not facts
    codes, _ = checked(dataclasses.replace(automaton, horizon=Fraction(20_000)))
    assert codes == ["W1008"]


def test_json_of_facts_and_diagnostics() -> None:
    """Every fact and diagnostic of the checks serialises (``rac check --format json``), exact numbers as strings."""
    automaton = driving(True, requirements=require(*ir.REQUIREMENT_CHECKS))
    facts: list[Fact] = []
    diagnostics = check_incentives(automaton, InputSpace(automaton), facts)
    data = json.loads(json.dumps([d.to_json() for d in diagnostics] + [f.to_json() for f in facts]))
    risk = next(item for item in data if item.get("code") == "E1001")["data"]
    assert (risk["bound"], risk["p_star"], risk["R_goal"], risk["R_stall"], risk["R_crash"]) == (
        "1/10000", "1/2", "980", "480", "-20")
    delayed = next(item for item in data if item.get("code") == "E1005")["data"]
    assert (delayed["sample"], delayed["other_sample"], delayed["delta"]) == (300, 1, "2392/5")
    assert delayed["better"]["run"][-1]["sample"] == 300 and delayed["better"]["ended_by"] == "episode"


@SETTINGS
@given(cases(real=True))
def test_every_printed_loophole_replays_its_claim(case: Case) -> None:
    """As the brute-force property, on programs whose rates and updates read a real input its guards cut:
    many of their witness runs only approach a value (a supremum), and each must still replay."""
    automaton = case.automaton
    space, problems = input_space(automaton)
    assert space is not None and not problems
    if space.valid.any():
        check_printed_witnesses(automaton, space, moves(automaton, space, split_guards(automaton)))


STALLING = """automaton Stalling {
    input x : real in [0, 3]
    reward p
    objective p
    sample every 1
    horizon 1
    initial location Drive { p' == 10 * x }
    location Arrived { p' == 0 }
    edge Drive -> Arrived when x >= 2 do p = p - 10 * x + 19
    goal when x >= 2
}
"""


def test_an_approached_stalling_run_replays_its_claim() -> None:
    """R_stall = 20 is a supremum, approached as x tends to 2 from below (x = 2 reaches the goal), against
    a goal run earning 19. The JSON's stalling run once gave x the middle of (0, 2), x = 1, earning 10:
    replayed, stalling did not beat the goal. x is now near enough 2 that it does, by at least half the
    gap of 1."""
    (warning,) = [d for d in compile_text(STALLING, "stalling.ra").diagnostics if d.code == "W1006"]
    automaton = compile_text(STALLING, "stalling.ra").raise_for_errors()
    better, worse = warning.data["better"], warning.data["worse"]
    assert (better["return"], worse["return"]) == ("20", "19")
    assert better["run"][0]["approached"] == {"x": "2"} and not approaches(worse)
    stalled, arrived = replay_json(automaton, better), replay_json(automaton, worse)
    assert (stalled.goal_sample, arrived.goal_sample) == (None, 1)
    assert arrived.value == 19 and 19.5 <= stalled.value < 20
    assert 1.95 <= Fraction(better["run"][0]["inputs"]["x"]) < 2
