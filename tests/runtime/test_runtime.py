"""The in-process interpreter and its batch form on hand-computed traces of the driving automaton.

Expected values are written out as the float operations the runtime semantics prescribe (rates
are ``float(rate * period)``, linear forms evaluate ``const`` first, then each term in order), and
checked against the closed-form numbers they approximate.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from fractions import Fraction
from types import MappingProxyType

import numpy as np
import pytest
from driving_ir import compiled_driving, driving_automaton, inputs

from rac import ir
from rac.compiler import compile_text
from rac.runtime.batch import BatchRewardAutomaton
from rac.runtime.interpreter import RewardAutomaton
from rac.runtime.semantics import check_automaton

COMPILED = compiled_driving()
SOURCES = ["hand", "compiled"]


@pytest.fixture(params=SOURCES)
def driving(request: pytest.FixtureRequest) -> ir.Automaton:
    return driving_automaton() if request.param == "hand" else COMPILED


def objective(sa: float, pr: float, co: float) -> float:
    """``10*sa + 5*pr + co`` as the runtime evaluates it: ``((0.0 + 10.0*sa) + 5.0*pr) + 1.0*co``."""
    return 0.0 + 10.0 * sa + 5.0 * pr + 1.0 * co


# ---------------------------------------------------------------- the compiler agrees with the hand-built IR
def test_hand_built_ir_equals_compiled() -> None:
    assert driving_automaton() == COMPILED


# ---------------------------------------------------------------- traces
def test_normal_then_close_goes_unsafe(driving: ir.Automaton) -> None:
    ra = RewardAutomaton(driving)
    assert (ra.location, ra.rewards, ra.objective, ra.samples, ra.ended) == ("Normal", {"sa": 0.0, "pr": 0.0,
                                                                              "co": 0.0}, 0.0, 0, False)
    sa = pr = co = 0.0
    previous = 0.0
    for k in range(1, 4):
        got = ra.step(inputs())
        sa, pr, co = sa + 0.1, pr + 0.1, co + 0.1
        assert ra.location == "Normal"  # no implicit self-loop, no edge enabled: stay
        assert ra.rewards == {"sa": sa, "pr": pr, "co": co}
        assert got == objective(sa, pr, co) - previous
        assert got == pytest.approx(1.6)
        previous = objective(sa, pr, co)
        assert ra.objective == previous
        assert ra.samples == k
    assert ra.rewards["sa"] == 0.30000000000000004  # three float additions of 0.1
    assert ra.time == 0.3  # samples * period, correctly rounded

    # isClose: accrue in Normal first (held inputs), then the edge to Unsafe subtracts PENALTY
    got = ra.step(inputs(is_close=True))
    sa, pr, co = -100.0 + (sa + 0.1), pr + 0.1, co + 0.1
    assert ra.location == "Unsafe"
    assert ra.rewards == {"sa": sa, "pr": pr, "co": co}
    assert sa == pytest.approx(-99.6) and pr == pytest.approx(0.4)
    assert got == objective(sa, pr, co) - previous
    assert ra.objective == objective(sa, pr, co) == pytest.approx(-993.6)
    previous = ra.objective

    # in Unsafe, a collision takes the self-loop (sa - 100) at every sample; pr and co are frozen
    for _ in range(2):
        got = ra.step(inputs(is_close=True, collide=True))
        sa = -100.0 + (sa + -0.1)
        assert ra.location == "Unsafe"
        assert ra.rewards == {"sa": sa, "pr": pr, "co": co}
        assert got == objective(sa, pr, co) - previous
        previous = ra.objective
    assert sa == pytest.approx(-299.8)

    # still close, no collision: Unsafe has no enabled edge, only its rate applies
    ra.step(inputs(is_close=True))
    sa = sa - 0.1
    assert (ra.location, ra.rewards["sa"]) == ("Unsafe", sa)

    # leaving: progress without comfort goes to Uncomfortable (rates of Unsafe accrue first)
    ra.step(inputs(comf=False))
    sa = sa - 0.1
    assert (ra.location, ra.rewards) == ("Uncomfortable", {"sa": sa, "pr": pr, "co": co})
    ra.step(inputs(prog=False))
    sa, pr, co = sa + 0.1, pr + 0.1, co - 0.1
    assert (ra.location, ra.rewards) == ("Stalled", {"sa": sa, "pr": pr, "co": co})
    ra.step(inputs())
    sa, pr = sa + 0.1, pr - 0.1
    assert (ra.location, ra.rewards) == ("Normal", {"sa": sa, "pr": pr, "co": co})
    assert ra.samples == 10


def test_end_bonus_and_return_equals_final_objective(driving: ir.Automaton) -> None:
    ra = RewardAutomaton(driving)
    total = sum(ra.step(inputs(dgoal=400.0 - 40 * k)) for k in range(10))
    before = dict(ra.rewards)
    bonus = ra.end(inputs(dgoal=1.5))
    assert ra.ended
    assert ra.rewards == {**before, "pr": 100.0 + before["pr"]}
    assert bonus == ra.objective - objective(before["sa"], before["pr"], before["co"])
    assert bonus == pytest.approx(500.0)
    assert total + bonus == pytest.approx(ra.objective, rel=1e-12)
    assert ra.objective == pytest.approx(10 * 1.0 + 5 * 101.0 + 1.0)


def test_end_without_bonus_and_the_threshold_is_strict(driving: ir.Automaton) -> None:
    ra = RewardAutomaton(driving)
    ra.step(inputs())
    assert ra.end(inputs(dgoal=2.0)) == 0.0
    assert ra.rewards["pr"] == 0.1
    ra.reset()
    ra.step(inputs())
    assert ra.end(inputs(dgoal=math.nextafter(2.0, 0.0))) == pytest.approx(500.0)


def test_end_right_after_reset(driving: ir.Automaton) -> None:
    ra = RewardAutomaton(driving)
    assert ra.end(inputs(dgoal=0.0)) == 500.0
    assert ra.rewards == {"sa": 0.0, "pr": 100.0, "co": 0.0}


def test_reset_restores_the_initial_state(driving: ir.Automaton) -> None:
    ra = RewardAutomaton(driving)
    for _ in range(3):
        ra.step(inputs(is_close=True))
    ra.end(inputs())
    ra.reset()
    assert (ra.location, ra.rewards, ra.objective, ra.samples, ra.time, ra.ended) == (
        "Normal", {"sa": 0.0, "pr": 0.0, "co": 0.0}, 0.0, 0, 0.0, False)
    assert ra.step(inputs()) == pytest.approx(1.6)


def test_description(driving: ir.Automaton) -> None:
    ra = RewardAutomaton(driving)
    assert ra.name == "Driving"
    assert ra.inputs == ("isClose", "prog", "comf", "collide", "dgoal")
    assert ra.reward_names == ("sa", "pr", "co")
    assert ra.locations == ("Normal", "Uncomfortable", "Stalled", "Unsafe")
    assert ra.period == 0.1 and ra.steps == 300


# ---------------------------------------------------------------- zero-order hold and first-edge semantics
def held_automaton() -> ir.Automaton:
    """One location, ``d' == x`` with x in [-10, 10]; period 1/2; ``k`` an int input in [0, 3]."""
    return ir.Automaton(
        name="Held",
        inputs=(ir.Input("x", "real", Fraction(-10), Fraction(10)),
                ir.Input("k", "int", Fraction(0), Fraction(3))),
        rewards=("d",), locations=(ir.Location("A", (ir.Linear(Fraction(0), (("x", Fraction(1)),)),)),),
        initial=0, edges=((),), end_clauses=(), assumptions=(),
        objective=ir.Linear(Fraction(1), (("d", Fraction(1)),)), priority=("d",), strict=False,
        period=Fraction(1, 2), horizon=Fraction(10))


def test_rates_use_the_inputs_held_from_the_previous_sample() -> None:
    ra = RewardAutomaton(held_automaton())
    assert ra.objective == 1.0  # the objective's constant counts from the start
    assert ra.step({"x": 2, "k": 0}) == 1.0  # first sample: held = current -> 0.5 * 2
    assert ra.step({"x": 4.0, "k": 1}) == 1.0  # held 2 again
    assert ra.step({"x": -6.0, "k": 3}) == 2.0  # held 4
    assert ra.rewards == {"d": 4.0} and ra.objective == 5.0
    ra.reset()
    assert ra.step({"x": -6.0, "k": 0}) == -3.0  # held inputs do not survive a reset
    with pytest.raises(ValueError, match="integer"):
        ra.step({"x": 1.0, "k": 1.5})
    with pytest.raises(ValueError, match="'k'"):
        ra.step({"x": 1.0, "k": 4})


def test_first_enabled_edge_wins_and_self_loops_fire_every_sample() -> None:
    b = ir.BInput("b")
    add = ir.Assignment("r", ir.Linear(Fraction(1), (("r", Fraction(1)),)))
    double = ir.Assignment("r", ir.Linear(Fraction(0), (("r", Fraction(2)),)))
    automaton = ir.Automaton(
        name="First", inputs=(ir.Input("b", "bool"),), rewards=("r",),
        locations=(ir.Location("A", (ir.Linear(),)), ir.Location("B", (ir.Linear(),))), initial=0,
        edges=((ir.Edge(0, 0, b, (add, double)), ir.Edge(0, 1, ir.TRUE, ())), ()),
        end_clauses=(), assumptions=(), objective=ir.Linear.variable("r"), priority=("r",), strict=False,
        period=Fraction(1), horizon=Fraction(10))
    ra = RewardAutomaton(automaton)
    assert ra.step({"b": 1}) == 2.0  # (0 + 1) * 2, updates left to right
    assert ra.step({"b": True}) == 4.0  # self-loop again: (2 + 1) * 2 = 6
    assert ra.rewards == {"r": 6.0} and ra.location == "A"
    assert ra.step({"b": 0}) == 0.0 and ra.location == "B"


# ---------------------------------------------------------------- validation
@pytest.mark.parametrize(("values", "message"), [
    ({k: v for k, v in inputs().items() if k != "prog"}, "missing input.*prog"),
    ({**inputs(), "speed": 3.0}, "unknown input.*speed"),
    ({k: v for k, v in {**inputs(), "spd": 1}.items() if k != "comf"}, "missing input.*comf.*unknown.*spd"),
    (inputs(dgoal=500.5), "dgoal.*outside"),
    (inputs(dgoal=-1e-300), "dgoal.*outside"),
    # "nan is outside [0.0, 500.0]" alone left the reader to see why
    (inputs(dgoal=math.nan), r"'dgoal' = nan is outside \[0\.0, 500\.0\]: NaN \(not a number\) is in no range"),
    (inputs(dgoal=math.inf), "dgoal"),
    (inputs(collide=True), r"assume collide imply isClose` \(driving\.ra:9\): collide=True, isClose=False$"),
])
def test_invalid_inputs_raise_and_leave_the_state_alone(driving: ir.Automaton, values: dict[str, object],
                                                        message: str) -> None:
    ra = RewardAutomaton(driving)
    ra.step(inputs())
    before = (ra.location, ra.rewards, ra.objective, ra.samples)
    with pytest.raises(ValueError, match=message):
        ra.step(values)
    with pytest.raises(ValueError, match=message):
        ra.end(values)
    assert (ra.location, ra.rewards, ra.objective, ra.samples, ra.ended) == (*before, False)


def test_inputs_are_converted(driving: ir.Automaton) -> None:
    """Booleans: True/False (Python's or numpy's) or 0/1; numbers: any real number, numpy's too."""
    ra = RewardAutomaton(driving)
    ra.step({"isClose": 0, "prog": True, "comf": np.bool_(True), "collide": False, "dgoal": np.int64(499)})
    assert ra.location == "Normal"
    ra.step({"isClose": 1, "prog": 1, "comf": 1, "collide": 1, "dgoal": np.float32(500)})
    assert ra.location == "Unsafe"


def test_common_inputs_are_read_without_the_checks(driving: ir.Automaton,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """A dict of True/False and floats skips check_mapping, boolean_input and number_input (their
    isinstance checks against Mapping and numbers.Real cost more than the rest of a sample); other
    values still go through them."""
    import rac.runtime.interpreter as interpreter

    calls: list[str] = []
    for name in ("check_mapping", "boolean_input", "number_input"):
        original = getattr(interpreter, name)

        def counted(*args: object, original: Callable[..., object] = original,
                    name: str = name) -> object:
            calls.append(name)
            return original(*args)
        monkeypatch.setattr(interpreter, name, counted)
    ra = RewardAutomaton(driving)
    for x in (inputs(), inputs(is_close=True, collide=True), inputs(prog=False, dgoal=0.0)):
        ra.step(x)
    ra.end(inputs())
    assert calls == []
    ra.reset()
    ra.step(MappingProxyType({"isClose": np.bool_(True), "prog": 1, "comf": True, "collide": 0,
                              "dgoal": np.float64(40.0)}))
    assert ra.location == "Unsafe"
    assert calls == ["check_mapping", "boolean_input", "boolean_input", "boolean_input", "number_input"]


@pytest.mark.parametrize(("name", "value", "message"), [
    ("prog", "yes", "is not a boolean"), ("collide", None, "is not a boolean"), ("isClose", 2, "is not a boolean"),
    ("comf", 0.5, "is not a boolean"), ("dgoal", "5", "is not a number"), ("dgoal", None, "is not a number"),
    ("dgoal", [1.0], "is not a number"), ("dgoal", 1j, "is not a number"),
    ("dgoal", np.array([1.0, 2.0]), "is not a number"), ("dgoal", 10**400, "too large for a float"),
])
def test_inputs_of_the_wrong_kind_are_refused_with_valueerror(driving: ir.Automaton, name: str, value: object,
                                                              message: str) -> None:
    """Issue 12: a string, None, a complex number or a sequence was read by its truth or by
    float() (or raised TypeError/OverflowError); now ValueError, as documented, and nothing changes."""
    ra = RewardAutomaton(driving)
    good = inputs()
    with pytest.raises(ValueError, match=message):
        ra.step({**good, name: value})
    with pytest.raises(ValueError, match="must map input names"):
        ra.step(None)  # type: ignore[arg-type]
    assert ra.samples == 0 and ra.location == "Normal"


def test_step_and_end_after_end_raise(driving: ir.Automaton) -> None:
    ra = RewardAutomaton(driving)
    ra.end(inputs())
    with pytest.raises(RuntimeError, match="reset"):
        ra.step(inputs())
    with pytest.raises(RuntimeError, match="reset"):
        ra.end(inputs())
    ra.reset()
    ra.step(inputs())


def test_malformed_ir_is_refused() -> None:
    good = held_automaton()
    bad_rate = ir.Location("A", (ir.Linear(Fraction(0), (("d", Fraction(1)),)),))  # a rate reading a reward
    with pytest.raises(ValueError, match="rate"):
        check_automaton(ir.Automaton(**{**good.__dict__, "locations": (bad_rate,)}))
    tiny = ir.Location("A", (ir.Linear(Fraction(-1, 10**400)),))  # would round to -0.0
    with pytest.raises(ValueError, match="too small"):
        RewardAutomaton(ir.Automaton(**{**good.__dict__, "locations": (tiny,)}))
    with pytest.raises(ValueError, match="not a boolean input"):
        RewardAutomaton(ir.Automaton(**{**good.__dict__, "assumptions": (ir.Assumption(ir.BInput("x"), "x"),)}))


DRIVING_VIOLATION = "inputs violate `assume collide imply isClose` (driving.ra:9): collide=True, isClose=False"

#: Two assumptions, the second written over two lines with a comment: messages quote each as written.
TWO_ASSUMPTIONS = """\
automaton Two {
    input b : bool
    input c : bool
    input x : real in [-5, 5]
    input m : int in [0, 3]
    assume b imply x <= 3
    assume m != 2 ||   // two is special
           c
    reward r
    objective r
    sample every 1
    horizon 10
    initial location L { r' == 1 }
}
"""


def test_an_assume_violation_names_the_clause_and_the_values(driving: ir.Automaton) -> None:
    """Issue 12: the message said only "inputs violate `assume`"; it quotes the clause as written, its
    line, and the values of the inputs the clause reads (in the order it reads them)."""
    ra = RewardAutomaton(driving)
    for call in (ra.step, ra.end):
        with pytest.raises(ValueError) as caught:
            call(inputs(collide=True))
        assert str(caught.value) == DRIVING_VIOLATION
    batch = BatchRewardAutomaton(driving, 3)
    with pytest.raises(ValueError) as caught:
        batch.step_batch(columns([inputs(), inputs(collide=True), inputs(collide=True, dgoal=1.0)]))
    assert str(caught.value) == f"{DRIVING_VIOLATION} (automata [1, 2])"


def test_the_first_violated_assumption_in_source_order_is_named() -> None:
    from rac.compiler import compile_text

    ra = RewardAutomaton(compile_text(TWO_ASSUMPTIONS, "two.ra").raise_for_errors())
    both = {"b": True, "c": False, "x": 4.5, "m": 2}
    second = {**both, "x": 3.0}
    with pytest.raises(ValueError) as caught:
        ra.step(both)
    assert str(caught.value) == "inputs violate `assume b imply x <= 3` (two.ra:6): b=True, x=4.5"
    with pytest.raises(ValueError) as caught:
        ra.end(second)
    # an int input shows as an int; the comment and the line break are not part of the clause
    assert str(caught.value) == "inputs violate `assume m != 2 || c` (two.ra:7): m=2, c=False"


# ---------------------------------------------------------------- batch
def columns(values: list[dict[str, object]]) -> dict[str, np.ndarray]:
    return {name: np.array([v[name] for v in values]) for name in values[0]}


@pytest.mark.parametrize("strategy", ["table", "direct"])
def test_batch_trace_and_masked_reset(driving: ir.Automaton, strategy: str) -> None:
    batch = BatchRewardAutomaton(driving, 3, strategy=strategy)
    assert batch.strategy == strategy
    out = batch.step_batch(columns([inputs(), inputs(prog=False), inputs(is_close=True)]))
    assert out.dtype == np.float64 and out.shape == (3,)
    assert batch.location_names() == ["Normal", "Stalled", "Unsafe"]
    assert batch.locations.tolist() == [0, 2, 3]
    assert out.tolist() == [objective(0.1, 0.1, 0.1)] * 2 + [objective(-100.0 + 0.1, 0.1, 0.1)]
    batch.step_batch(columns([inputs(), inputs(), inputs(is_close=True, collide=True)]))
    sa = batch.rewards["sa"]
    assert sa.tolist() == [0.2, 0.2, -100.0 + (-100.0 + 0.1 + -0.1)]

    batch.reset(mask=np.array([False, True, True]))
    assert batch.location_names() == ["Normal", "Normal", "Normal"]
    assert batch.rewards["sa"].tolist() == [0.2, 0.0, 0.0]
    assert batch.samples.tolist() == [2, 0, 0]
    assert batch.objective.tolist() == [objective(0.2, 0.2, 0.2), 0.0, 0.0]
    out = batch.step_batch(columns([inputs()] * 3))
    third = 0.2 + 0.1
    assert out.tolist() == [objective(third, third, third) - objective(0.2, 0.2, 0.2),
                            objective(0.1, 0.1, 0.1), objective(0.1, 0.1, 0.1)]
    assert batch.time.tolist() == [0.3, 0.1, 0.1]


@pytest.mark.parametrize("strategy", ["table", "direct"])
def test_batch_step_with_mask(driving: ir.Automaton, strategy: str) -> None:
    """A masked step moves only the masked copies (as if the others were not there); unmasked
    copies may have ended, and their inputs are not read."""
    batch = BatchRewardAutomaton(driving, 3, strategy=strategy)
    alone = BatchRewardAutomaton(driving, 2, strategy=strategy)
    batch.step_batch(columns([inputs()] * 3))
    alone.step_batch(columns([inputs()] * 2))
    batch.end_batch(columns([inputs()] * 3), mask=np.array([False, False, True]))
    before = (batch.locations.tolist(), batch.rewards["sa"].tolist(), batch.objective.tolist())
    step = [inputs(prog=False), inputs(is_close=True)]
    garbage = {**inputs(), "dgoal": -1.0}  # out of range: must not be read for an unmasked copy
    out = batch.step_batch(columns([*step, garbage]), mask=np.array([True, True, False]))
    expected = alone.step_batch(columns(step))
    assert out.tolist() == [*expected.tolist(), 0.0]
    assert batch.locations.tolist()[:2] == alone.locations.tolist()
    assert batch.rewards["sa"].tolist()[:2] == alone.rewards["sa"].tolist()
    assert batch.samples.tolist() == [2, 2, 1]
    assert (batch.locations.tolist()[2], batch.rewards["sa"].tolist()[2], batch.objective.tolist()[2]) == (
        before[0][2], before[1][2], before[2][2])
    with pytest.raises(RuntimeError):  # an ended copy cannot be stepped
        batch.step_batch(columns([inputs()] * 3), mask=np.array([False, False, True]))


@pytest.mark.parametrize("strategy", ["table", "direct"])
def test_batch_end_with_mask(driving: ir.Automaton, strategy: str) -> None:
    batch = BatchRewardAutomaton(driving, 3, strategy=strategy)
    batch.step_batch(columns([inputs()] * 3))
    final = columns([inputs(dgoal=1.0), inputs(dgoal=1.0), inputs(dgoal=3.0)])
    final["dgoal"][1] = np.nan  # unmasked: not validated
    out = batch.end_batch(final, mask=[True, False, True])
    assert out.tolist() == [500.0, 0.0, 0.0]
    assert batch.ended.tolist() == [True, False, True]
    assert batch.rewards["pr"].tolist() == [100.0 + 0.1, 0.1, 0.1]
    with pytest.raises(RuntimeError, match="reset"):
        batch.step_batch(columns([inputs()] * 3))
    with pytest.raises(RuntimeError, match="reset"):
        batch.end_batch(columns([inputs()] * 3), mask=[True, False, False])
    assert batch.end_batch(columns([inputs()] * 3), mask=[False, True, False]).tolist() == [0.0, 0.0, 0.0]
    batch.reset(mask=[True, True, False])
    with pytest.raises(RuntimeError, match=r"\[2\]"):
        batch.step_batch(columns([inputs()] * 3))
    batch.reset()
    assert not batch.ended.any()
    batch.step_batch(columns([inputs()] * 3))


@pytest.mark.parametrize("strategy", ["table", "direct"])
def test_batch_validation(driving: ir.Automaton, strategy: str) -> None:
    batch = RewardAutomaton(driving).batch(4) if strategy == "table" else BatchRewardAutomaton(driving, 4,
                                                                                                 strategy=strategy)
    good = columns([inputs()] * 4)
    batch.step_batch(good)
    before = (batch.locations.tolist(), batch.rewards["sa"].tolist(), batch.samples.tolist())
    with pytest.raises(ValueError, match="missing input.*dgoal"):
        batch.step_batch({k: v for k, v in good.items() if k != "dgoal"})
    with pytest.raises(ValueError, match="unknown input"):
        batch.step_batch({**good, "x": np.zeros(4)})
    with pytest.raises(ValueError, match=r"'dgoal'\[2\]"):
        batch.step_batch({**good, "dgoal": np.array([1.0, 2.0, 600.0, np.nan])})
    with pytest.raises(ValueError, match=r"collide=True, isClose=False \(automata \[3\]\)$"):
        batch.step_batch({**good, "collide": np.array([False, False, False, True])})
    with pytest.raises(ValueError, match="shape"):
        batch.step_batch({**good, "prog": np.ones(5, dtype=bool)})
    after = (batch.locations.tolist(), batch.rewards["sa"].tolist(), batch.samples.tolist())
    assert after == before
    out = batch.step_batch({**good, "prog": False, "dgoal": 7})  # scalars broadcast
    assert batch.location_names() == ["Stalled"] * 4 and out.shape == (4,)
    with pytest.raises(ValueError, match="shape"):
        batch.reset(mask=[True])


def test_batch_matches_scalar_on_held_inputs() -> None:
    automaton = held_automaton()
    batch = BatchRewardAutomaton(automaton, 2)
    assert batch.step_batch({"x": np.array([2.0, -3.0]), "k": np.array([0, 3])}).tolist() == [1.0, -1.5]
    batch.reset(mask=[False, True])
    assert batch.step_batch({"x": np.array([4.0, 8.0]), "k": 1}).tolist() == [1.0, 4.0]
    assert batch.step_batch({"x": np.array([0.0, 0.0]), "k": 1}).tolist() == [2.0, 4.0]
    with pytest.raises(ValueError, match="integer"):
        batch.step_batch({"x": 0.0, "k": np.array([1.0, 0.5])})


def many_atoms_automaton(n_flags: int) -> ir.Automaton:
    """Two locations; edges guarded by conjunctions/disjunctions over ``n_flags`` booleans and ``x``."""
    flags = tuple(f"f{k}" for k in range(n_flags))
    x_low = ir.BAtom("x", "<", Fraction(1, 2))
    even = ir.BAnd(tuple(ir.BInput(f) for f in flags[::2]) + (x_low,))
    odd = ir.BOr(tuple(ir.BInput(f) for f in flags[1::2]))
    bump = ir.Assignment("r", ir.Linear(Fraction(1, 3), (("r", Fraction(3, 2)), ("x", Fraction(-1)))))
    return ir.Automaton(
        name="Many",
        inputs=(*(ir.Input(f, "bool") for f in flags), ir.Input("x", "real", Fraction(0), Fraction(1))),
        rewards=("r",), locations=(ir.Location("A", (ir.Linear(Fraction(1)),)),
                                   ir.Location("B", (ir.Linear(Fraction(-1), (("x", Fraction(2)),)),))),
        initial=0, edges=((ir.Edge(0, 1, even, (bump,)), ir.Edge(0, 0, ir.BNot(even), ())),
                          (ir.Edge(1, 0, ir.BAnd((odd, ir.BNot(x_low))), (bump,)),)),
        end_clauses=(ir.EndClause(odd, (bump,)),),
        assumptions=(ir.Assumption(ir.BNot(ir.BAnd((ir.BInput(flags[1]), ir.BAtom("x", "==", Fraction(1))))),
                                   f"!({flags[1]} && x == 1)"),),
        objective=ir.Linear(Fraction(0), (("r", Fraction(-2)),)), priority=("r",), strict=False,
        period=Fraction(1, 4), horizon=Fraction(10))


@pytest.mark.parametrize(("n_flags", "auto"), [(3, "table"), (11, "table"), (20, "direct")])
def test_batch_strategies_agree_with_scalars(n_flags: int, auto: str) -> None:
    automaton = many_atoms_automaton(n_flags)
    n, rng = 64, np.random.default_rng(n_flags)
    assert BatchRewardAutomaton(automaton, n).strategy == auto
    strategies = ("table", "direct") if n_flags < 16 else ("direct",)
    batches = [BatchRewardAutomaton(automaton, n, strategy=s) for s in strategies]
    scalars = [RewardAutomaton(automaton) for _ in range(n)]
    moves = set()
    for t in range(12):
        values = {f"f{k}": rng.random(n) < (0.9 if k % 2 == 0 else 0.15) for k in range(n_flags)}
        values["x"] = rng.choice([0.0, 0.25, 0.5, 1.0, rng.random()], size=n)
        values["f1"] &= values["x"] != 1.0  # the assumption
        rows = [{k: v[j] for k, v in values.items()} for j in range(n)]
        if t == 11:
            expected = [ra.end(row) for ra, row in zip(scalars, rows)]
            outs = [b.end_batch(values) for b in batches]
        else:
            expected = [ra.step(row) for ra, row in zip(scalars, rows)]
            outs = [b.step_batch(values) for b in batches]
        moves.update(ra.location for ra in scalars)
        for batch, out in zip(batches, outs):
            assert out.tolist() == expected
            assert batch.location_names() == [ra.location for ra in scalars]
            assert batch.rewards["r"].tolist() == [ra.rewards["r"] for ra in scalars]
    assert moves == {"A", "B"}


def test_the_batch_takes_what_the_scalar_runtimes_take(driving: ir.Automaton) -> None:
    """A Fraction is a number (the batch refused object arrays of them), numpy's bool counts 0 or 1 for
    a numeric input as Python's does (the scalar runtimes refused it, the batch took it): the same rule
    in the interpreter, the generated module and the batch."""
    import types

    from rac.targets.python import generate_python

    namespace = types.ModuleType("generated_driving")
    exec(compile(generate_python(driving), "<generated>", "exec"), namespace.__dict__)  # noqa: S102
    module = getattr(namespace, namespace.__all__[0])
    for value, read in [(Fraction(1, 3), 1 / 3), (np.True_, 1.0), (True, 1.0), (np.float32(0.5), 0.5)]:
        row = {**inputs(), "dgoal": value}
        expected = {**inputs(), "dgoal": read}
        ra, generated, reference = RewardAutomaton(driving), module(), RewardAutomaton(driving)
        assert ra.step(row) == generated.step(row) == reference.step(expected)
        batch = BatchRewardAutomaton(driving, 2)
        column = np.array([value, value], dtype=object) if isinstance(value, Fraction) else np.array([value, value])
        assert batch.step_batch({**{k: np.array([v, v]) for k, v in inputs().items()}, "dgoal": column}).tolist() \
            == [reference.objective] * 2


def test_the_batch_refuses_inputs_of_the_wrong_kind(driving: ir.Automaton) -> None:
    """Complex arrays lost their imaginary part, numeric strings were read, a NaN mask counted as
    True and batch(2.5) made two automata (issue 12): each is a ValueError now."""
    from rac.runtime.batch import BatchRewardAutomaton

    batch = BatchRewardAutomaton(driving, 2)
    good = {name: np.array([value, value]) for name, value in inputs().items()}
    for name, value, message in [("dgoal", np.array([1 + 1j, 2]), "real numbers"),
                                 ("dgoal", np.array(["5", "6"]), "real numbers"),
                                 ("dgoal", np.array([None, 1.0], dtype=object), r"'dgoal'\[0\] = None is not a number"),
                                 ("isClose", np.array([0.5, 1.0]), "booleans"),
                                 ("isClose", np.array([2, 0]), r"'isClose'\[0\] = 2 is not a boolean")]:
        with pytest.raises(ValueError, match=message):
            batch.step_batch({**good, name: value})
    with pytest.raises(ValueError, match=r"mask must hold booleans \(True/False or 0/1\), not float64 values"):
        batch.step_batch(good, mask=np.array([np.nan, 1.0]))
    with pytest.raises(ValueError, match=r"mask must hold booleans \(True/False or 0/1\), not the value 2$"):
        batch.step_batch(good, mask=np.array([2, 0]))  # 0/1 ints are masks: say which value is not
    with pytest.raises(ValueError, match="must map input names"):
        batch.step_batch(None)  # type: ignore[arg-type]
    for n in (2.5, True, 0):
        with pytest.raises(ValueError, match="whole number of automata"):
            BatchRewardAutomaton(driving, n)  # type: ignore[arg-type]
    batch.step_batch(good, mask=np.array([1, 0]))  # 0/1 masks and inputs of the right kinds still work


def test_object_columns_are_read_row_by_row_as_the_scalar_runtime_reads_them(driving: ir.Automaton) -> None:
    """gymnasium's vector info holds numpy bools (``action == 1``) in an object array, None in the rows of
    sub-environments that did not report the key: the batch refused every such column ("not object
    values") although ``step`` takes np.True_, and it read the float32 at a bound of an object column
    widened (refusing what ``step`` takes as the bound). Now each row read follows the scalar rule."""
    batch = BatchRewardAutomaton(driving, 3)
    reference = [RewardAutomaton(driving) for _ in range(3)]
    row = {"isClose": np.array([np.True_, np.False_, None], dtype=object), "prog": True, "comf": True,
           "collide": np.array([np.False_, np.False_, None], dtype=object),
           "dgoal": np.array([np.float32(500.0), Fraction(1, 2), None], dtype=object)}
    got = batch.step_batch(row, mask=np.array([True, True, False]))
    expected = [reference[0].step(inputs(is_close=True, dgoal=np.float32(500.0))),
                reference[1].step(inputs(dgoal=0.5)), 0.0]
    assert got.tolist() == expected and batch.location_names()[:2] == [reference[0].location, reference[1].location]
    assert batch.samples.tolist() == [1, 1, 0]
    for name, value, message in [("isClose", None, r"input 'isClose'\[2\] = None is not a boolean"),
                                 ("isClose", 0.5, r"input 'isClose'\[2\] = 0.5 is not a boolean"),
                                 ("dgoal", "5", r"input 'dgoal'\[2\] = '5' is not a number")]:
        full = {**row, "isClose": np.array([True, False, False], dtype=object),
                "collide": np.array([False, False, False], dtype=object),
                "dgoal": np.array([1.0, 1.0, 1.0], dtype=object)}
        full[name][2] = value
        with pytest.raises(ValueError, match=message):
            batch.step_batch(full)  # every row read: the third is refused, by name
    assert batch.samples.tolist() == [1, 1, 0]  # and nothing changed


def test_take_and_resume_refuse_a_mask_or_floats_for_indices(driving: ir.Automaton) -> None:
    """``take(mask)`` cast the mask [True, False, True] to the rows [1, 0, 1] and copied those, floats were
    truncated and negative rows wrapped round, all silently; ``resume`` read the locations [0.5, ...] as 0 and
    an unknown reward name was a KeyError. Both now take indices only, and say what they got otherwise."""
    batch = BatchRewardAutomaton(driving, 3)
    batch.step_batch(columns([inputs(), inputs(is_close=True), inputs()]))
    assert batch.take([1, 1, 0]).location_names() == ["Unsafe", "Unsafe", "Normal"]
    assert batch.take(np.array([2], dtype=np.uint8)).location_names() == ["Normal"]
    for rows in (np.array([True, False, True]), [0.7], [-1], [3], [[0, 1]]):
        with pytest.raises(ValueError, match=r"rows must be a sequence of row indices in \[0, 3\) \(not a mask\)"):
            batch.take(rows)
    before = batch.location_names()
    for locations in ([0.5, 0, 0], [True, False, False], [0, 0, 9], [0, 0]):
        with pytest.raises(ValueError, match=r"locations must be 3 location indices"):
            batch.resume(locations)
    with pytest.raises(ValueError, match=r"unknown reward\(s\): 'zz' \(the rewards are sa, pr, co\)"):
        batch.resume([0, 1, 2], {"zz": [1.0, 2.0, 3.0]})
    assert batch.location_names() == before  # refused before anything changed
    batch.resume(np.array([0, 1, 2]), {"pr": [1.0, 2.0, 3.0]})
    assert batch.rewards["pr"].tolist() == [1.0, 2.0, 3.0] and batch.locations.tolist() == [0, 1, 2]


def test_an_int_column_of_booleans_is_read_on_the_masked_rows_only(driving: ir.Automaton) -> None:
    """A mask leaves the other rows' inputs unread (a NaN there is fine), but an int column for a boolean
    input was checked on every row: a 2 in an unmasked row refused the whole call, saying "must hold booleans
    ..., not int64 values" of a column whose read rows were 0/1. Now only the read rows count, and a
    wrong one is named with its value, as an object column's is."""
    batch = BatchRewardAutomaton(driving, 3)
    reference = RewardAutomaton(driving)
    good = {name: np.array([value] * 3) for name, value in inputs().items()}
    got = batch.step_batch({**good, "isClose": np.array([1, 2, 0]), "collide": np.array([0, 7, 0]),
                            "dgoal": np.array([1.0, np.nan, 1.0])}, mask=np.array([True, False, True]))
    assert got.tolist() == [reference.step(inputs(is_close=True, dgoal=1.0)), 0.0, RewardAutomaton(driving).step(
        inputs(dgoal=1.0))]
    assert batch.samples.tolist() == [1, 0, 1]
    with pytest.raises(ValueError, match=r"^input 'isClose'\[2\] = 5 is not a boolean \(True or False\)$"):
        batch.step_batch({**good, "isClose": np.array([1, 2, 5], dtype=np.uint8)}, mask=np.array([True, False, True]))
    assert batch.samples.tolist() == [1, 0, 1]


def test_run_samples_reads_its_masks_and_repeat_as_step_batch_does(driving: ir.Automaton) -> None:
    """``run_samples`` copied its ``active``/``ending`` rows into bool arrays, so [1.0, 0.5] was read as two
    True rows, and it refused ``repeat=np.int64(2)``, a whole number (``batch(np.int64(n))`` takes one).
    Its masks are now read by step_batch's rule (True/False or 0/1) and a numpy integer repeats."""
    row = columns([inputs(), inputs(is_close=True)])
    expected = BatchRewardAutomaton(driving, 4).run_samples([(row, np.array([True, True]), np.array([False, True]))],
                                                            repeat=2)
    batch = BatchRewardAutomaton(driving, 4)
    got = batch.run_samples([(row, [1, 1], [0, 1])], repeat=np.int64(2))
    assert got.tobytes() == expected.tobytes() and batch.ended.tolist() == [False, False, True, True]
    for active, ending, message in [([1.0, 0.5], [False, False], "active must hold booleans"),
                                    ([True, True], [2, 0], "ending must hold booleans .* not the value 2"),
                                    ([True], [False, False], r"active must have shape \(2,\)")]:
        with pytest.raises(ValueError, match=message):
            BatchRewardAutomaton(driving, 4).run_samples([(row, active, ending)], repeat=2)


def test_a_resumed_run_reads_the_held_inputs_it_is_given() -> None:
    """A rate reads the inputs held from the previous sample; ``resume`` had no way to give them, so a run
    resumed mid-way (a counterfactual replay of a step) accrued on the step's own inputs instead."""
    rated = compile_text("""automaton Rated {
        input v : real in [0, 10]
        input b : bool
        reward r
        objective r
        sample every 0.5
        horizon 10
        initial location A { r' == v }
        location B { r' == -2 * v }
        edge A -> B when b do r = r * 3
    }""", "rated.ra").raise_for_errors()
    first, second = {"v": np.array([4.0]), "b": np.array([True])}, {"v": np.array([1.0]), "b": np.array([False])}
    run = BatchRewardAutomaton(rated, 1)
    run.step_batch(first)
    rewards, where = run.rewards, run.locations
    paid = run.step_batch(second)
    resumed = BatchRewardAutomaton(rated, 1)
    resumed.resume(where, rewards, held={"v": first["v"], "b": first["b"]})
    assert resumed.step_batch(second).tolist() == paid.tolist() == [-4.0]  # B's rate on the held v = 4
    resumed.resume(where, rewards)  # no held inputs: a first sample, which holds its own
    assert resumed.step_batch(second).tolist() == [-1.0]
    with pytest.raises(ValueError, match="held must give the inputs the rates read: v missing"):
        resumed.resume(where, rewards, held={"b": first["b"]})


def test_a_list_mixing_float32_at_a_bound_with_floats_is_read_as_the_scalar_runtime_reads_it() -> None:
    """A list ``[np.float32(-1.2), 0.0]`` (per-environment float32 observations and a Python default) was
    widened to float64 by numpy, so the batch refused the float32 at the bound that ``step`` takes as the
    bound, telling the user to pass the float32 value itself, which they had; with ``clip=True`` it was
    clipped and counted. Now such a list is read value by value, as ``step`` reads it."""
    program = compile_text("automaton M {\n input pos : real in [-1.2, 0.6]\n reward pr\n objective pr\n"
                           " sample every 1\n horizon 10\n initial location A { pr' == pos }\n}\n",
                           "m.ra").raise_for_errors()
    values = [np.float32(-1.2), np.float32(0.6), 0.0]
    expected = []
    for value in values:
        one = RewardAutomaton(program)
        expected.append(one.step({"pos": value}))
    for column in (values, tuple(values)):
        for clip in (False, True):
            batch = BatchRewardAutomaton(program, 3)
            assert batch.step_batch({"pos": column}, clip=clip).tolist() == expected
            if clip:
                assert batch.clipped == {"pos": 0}
    with pytest.raises(ValueError, match="is outside"):  # a float32 bound made a Python float is still outside
        BatchRewardAutomaton(program, 3).step_batch({"pos": [float(np.float32(-1.2)), 0.0, 0.0]})
