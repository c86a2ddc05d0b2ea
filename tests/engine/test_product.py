"""The product of the scenario model and the reward automaton (rac.engine.product).

- the product's sampled states are exactly explore()'s states, with the same labels;
- along any path of choices, a scalar simulation (NativeModel + the bindings on one-state frames +
  rac.runtime.interpreter.RewardAutomaton) reaches the product's location, inputs and rewards at every sample,
  the state before each edge, and the state after `at end`;
- the mirrors' integer arithmetic truncates like C; query comparisons are exact on the integers;
- with `episode ends when`, a run ends at the sample whose inputs satisfy the condition: its `ended`
  state (the `at end` clauses applied) follows, terminal, exactly as the runtime ends it;
- Qe and Qh on examples/left_turn/model.ra, a false verdict with a trace, and an automaton whose
  static P2 check fails on inputs the scenario cannot produce while Qh holds in the model.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import replace
from fractions import Fraction as F
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tiny_scenarios import avoidable_obstacle

from rac import ir
from rac.check.analysis.priority import check_priorities, check_ranges
from rac.check.queries import lower_expression
from rac.compiler import compile_file
from rac.engine.evaluate import EvaluationError, Evaluator, Frame
from rac.engine.explore import action_pairs, explore
from rac.engine.product import (
    ACCRUED,
    ENDED,
    READ,
    SAMPLED,
    MirrorArithmetic,
    ProductGraph,
    decide_in_model,
    decide_product,
    explore_product,
)
from rac.ir import Action
from rac.ir import query as iq
from rac.model import ModelData, ModelRangeError, NativeModel, build_model_data
from rac.model.commonroad import load_scenario
from rac.runtime.interpreter import RewardAutomaton

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "examples" / "left_turn" / "model.ra"
SCENARIO = REPO / "examples" / "left_turn" / "left_turn.xml"
#: jerk in {-2, 0, 2}, turn in {-0.4, 0, 0.4}: 9 action pairs
COARSE = (Action("jerk", F(-2), F(2), F(2)), Action("turn", F(-2, 5), F(2, 5), F(2, 5)))
HORIZON = 8

#: Rates and updates that read a numeric input (so the first sample accrues on read!), an update
#: reading a reward updated before it, `at end`, and prev() of a number and of a condition.
METER = """\
automaton Meter {
    input near : bool
    input gain : bool
    input d    : real in [0, 1000]

    reward dist, pen
    objective dist + pen

    sample every 0.1
    horizon 1

    initial location Far { dist' == 10*d;      pen' == 0 }
    location Near        { dist' == 20 - 10*d; pen' == -1 }

    edge Far -> Near when near && d < 29 do pen = pen - d, dist = dist + 3*pen
    edge Near -> Far when !near          do dist = dist - 2

    at end when gain do pen = pen + 10

    model {
        scenario "left_turn.xml"
        bind near = mindist() < 14
        bind gain = v > prev(v) || prev(acc > 0)
        bind d    = dist_goal()
    }
}
"""

#: P2 fails: entering Unsafe costs sa only 0.5, so after 5 samples in Normal the objective stays > 0.
CAREFUL = """\
automaton Careful {
    input isClose : bool
    input prog    : bool

    reward sa, pr
    priority sa > pr
    objective 10*sa + pr

    sample every 0.1
    horizon 1

    initial location Normal { sa' == 1;  pr' == 1 }
    location Stalled        { sa' == 1;  pr' == -1 }
    location Unsafe         { sa' == -1; pr' == 0 }

    edge * -> Unsafe  when isClose           do sa = sa - 0.5
    edge * -> Stalled when !isClose && !prog
    edge * -> Normal  when !isClose && prog

    model {
        scenario "left_turn.xml"
        bind isClose = mindist() < CLOSE
        bind prog    = dist_goal() < prev(dist_goal())
    }

    query Qh: A[] Unsafe imply 10*sa + pr <= 0
}
"""


def coarse(automaton: ir.Automaton) -> ModelData:
    assert automaton.model is not None
    spec = replace(automaton.model, actions=COARSE)
    return build_model_data(load_scenario(spec.scenario_path), spec)


def compiled(folder: Path, text: str, scenario: bytes, *, analyse: bool = True) -> ir.Automaton:
    (folder / "left_turn.xml").write_bytes(scenario)
    path = folder / "automaton.ra"
    path.write_text(text, encoding="utf-8")
    result = compile_file(path, analyse=analyse)
    assert result.automaton is not None, [d.message for d in result.diagnostics]
    return result.automaton


def without_obstacles() -> bytes:
    text = SCENARIO.read_text(encoding="utf-8")
    return re.sub(r"\s*<dynamicObstacle .*?</dynamicObstacle>", "", text, flags=re.S).encode("utf-8")


def queries(automaton: ir.Automaton) -> dict[str, iq.QueryDecl]:
    return {decl.name: decl for decl in automaton.queries if isinstance(decl.query, iq.PathQuery)}


@pytest.fixture(scope="module")
def driving(tmp_path_factory: pytest.TempPathFactory) -> tuple[ir.Automaton, ModelData, ProductGraph]:
    """examples/left_turn/model.ra with a few extra queries, coarse actions, 8 samples."""
    extra = ("    query Uncomfy: A[] !Uncomfortable\n"
             "    query Peak: A[] Normal imply 10*sa + 5*pr + co <= 1.6\n"
             "    query Sum: E<> sa + pr + co == 0.6\n"
             "    query Qe:")
    text = EXAMPLE.read_text(encoding="utf-8").replace("    query Qe:", extra)
    automaton = compiled(tmp_path_factory.mktemp("driving"), text, SCENARIO.read_bytes())
    data = coarse(automaton)
    return automaton, data, explore_product(data, automaton, horizon_samples=HORIZON)


@pytest.fixture(scope="module")
def meter(tmp_path_factory: pytest.TempPathFactory) -> tuple[ir.Automaton, ModelData, ProductGraph]:
    automaton = compiled(tmp_path_factory.mktemp("meter"), METER, SCENARIO.read_bytes())
    data = coarse(automaton)
    return automaton, data, explore_product(data, automaton, horizon_samples=HORIZON)


# ---------------------------------------------------------------- structure
def test_sampled_states_are_explores_states(driving) -> None:
    automaton, data, graph = driving
    graph.validate()
    assert graph.horizon == HORIZON and graph.states.dtype == np.int32
    plain = explore(data, horizon_samples=HORIZON)
    sampled = graph.phase == SAMPLED
    ours = {tuple(row) for row in graph.states[sampled][:, [0, 2, 3, 4, 5, 6, 7, 8]].tolist()}
    assert ours == {tuple(row) for row in plain.states.tolist()}
    # the same labels wherever the same (k, ego) occurs, in every phase
    where = {tuple(row): i for i, row in enumerate(plain.states.tolist())}
    index = np.array([where[tuple(row)] for row in graph.states[:, [0, 2, 3, 4, 5, 6, 7, 8]].tolist()])
    for name in ("collide", "offroad", "goal", "safe"):
        assert np.array_equal(graph.labels[name], plain.labels[name][index])
    # phases in time order, one choice out of every state but the sampled ones and the last layer
    order = graph.k.astype(np.int64) * 4 + graph.phase
    assert np.all(np.diff(order) >= 0)
    counts = np.diff(graph.choice_offsets)
    assert np.all(counts[graph.phase == ACCRUED] == 1)
    assert set(np.unique(graph.phase).tolist()) == {ACCRUED, SAMPLED, ENDED}  # no rate reads an input
    assert np.all(counts[graph.phase == ENDED] == 0) and np.all(graph.k[graph.phase == ENDED] == HORIZON)
    decisions = sampled & (graph.k % data.decide_every == 0) & (graph.k < HORIZON)
    assert np.all(counts[decisions] == 9)


def test_pruning_ends_runs_at_unsafe_samples(driving) -> None:
    automaton, data, _ = driving
    calls: list[tuple[int, int, int]] = []
    graph = explore_product(data, automaton, horizon_samples=HORIZON, prune_unsafe=True,
                            progress=lambda *args: calls.append(args))
    graph.validate()
    sampled = graph.phase == SAMPLED
    unsafe = sampled & ~graph.labels["safe"]
    assert unsafe.any() and np.all(graph.terminal()[unsafe])  # off-road at a full turn: the run ends there
    ours = {tuple(row) for row in graph.states[sampled][:, [0, 2, 3, 4, 5, 6, 7, 8]].tolist()}
    assert ours == {tuple(row) for row in explore(data, horizon_samples=HORIZON, prune_unsafe=True).states.tolist()}
    assert [c[0] for c in calls] == list(range(HORIZON + 1)) and calls[-1][2] <= graph.n_states


def test_first_sample_reads_the_inputs_before_accruing(meter) -> None:
    automaton, data, graph = meter
    graph.validate()
    read = graph.phase == READ
    assert read.any() and np.all(graph.k[read] == 1)
    accrued_1 = (graph.phase == ACCRUED) & (graph.k == 1)
    assert np.all(graph.mirrors["dist"][accrued_1] == 0)  # nothing held yet: the accrual waits for read!
    assert np.all(graph.mirrors["dist"][read] == graph.inputs["d"][read])  # 10*d*0.1 s, in significands
    assert not graph.settled[read].any() and not graph.settled[accrued_1].any() and not graph.settled[0]
    assert graph.settled[(graph.phase == ACCRUED) & (graph.k == 2)].all()


# ---------------------------------------------------------------- the reference: one run at a time
def follow(graph: ProductGraph, state: int, action: int) -> int:
    choices = graph.choices(state)
    found = [c for c in choices if int(graph.choice_action[c]) == action]
    assert len(found) == 1, (state, action)
    return int(graph.choice_target[found[0]])


def grown(automaton: ir.Automaton, rates: tuple[ir.Linear, ...], rewards: dict[str, float],
          inputs: dict[str, object]) -> dict[str, float]:
    """The rewards after one sample's accrual at ``rates`` on ``inputs``."""
    period = F(automaton.period)
    return {r: rewards[r] + float(rate.const * period) + sum(float(c * period) * inputs[n] for n, c in rate.terms)
            for r, rate in zip(automaton.rewards, rates)}


def simulate_and_compare(automaton: ir.Automaton, data: ModelData, graph: ProductGraph, decisions: list[int]) -> None:
    """One run of ``decisions`` on the scalar model and the runtime, followed along the product; with
    `episode ends when`, the run ends where the runtime's does (``runtime`` shows the state before the
    end clauses, ``ending`` is the runtime with the declaration, which applies them)."""
    native, evaluator = NativeModel(data), Evaluator(data, automaton)
    runtime, ending = RewardAutomaton(replace(automaton, episode_ends=None)), RewardAutomaton(automaton)
    assert automaton.model is not None
    bound = {b.input: b.expr for b in automaton.model.bindings}
    pairs = action_pairs(data)
    names = automaton.location_names
    choices = iter(decisions)
    state, node = native.initial_state(), graph.initial
    held: dict[str, object] = {}

    def check(node: int, k: int, phase: int, rewards: dict[str, float], location: str) -> None:
        assert (int(graph.k[node]), int(graph.phase[node])) == (k, phase)
        assert names[int(graph.location[node])] == location
        for reward, value in rewards.items():
            assert int(graph.mirrors[reward][node]) / data.scale == pytest.approx(value, abs=1e-9)

    for k in range(graph.horizon):
        action = next(choices) if k % data.decide_every == 0 else -1
        moved = state if action < 0 else state._replace(jerk=int(pairs[action][0]), turn=int(pairs[action][1]))
        after = native.sense(moved)
        frame = Frame(np.array([k + 1]), np.array([after]), prev=Frame(np.array([k]), np.array([state])))
        values: dict[str, object] = {}
        for item in automaton.inputs:
            if item.is_bool:
                values[item.name] = bool(evaluator.evaluate_bool(bound[item.name], frame)[0])
            else:  # the automaton reads the significand d2i(e)
                values[item.name] = int(float(evaluator.evaluate(bound[item.name], frame)[0]) * data.scale) / data.scale
        location, rewards = runtime.location, runtime.rewards
        rates = automaton.locations[names.index(location)].rates
        node = follow(graph, node, action)
        assert tuple(graph.ego[node]) == tuple(after)
        if k == 0 and any(rate.terms for place in automaton.locations for rate in place.rates):
            check(node, 1, ACCRUED, rewards, location)  # nothing is held yet: the accrual waits for read!
            node = follow(graph, node, -1)
            check(node, 1, READ, grown(automaton, rates, rewards, values), location)
        else:  # before the edge: the last location, the rewards grown at its rates with the held inputs
            check(node, k + 1, ACCRUED, grown(automaton, rates, rewards, held), location)
        node = follow(graph, node, -1)
        runtime.step(values)
        ending.step(values)
        check(node, k + 1, SAMPLED, runtime.rewards, runtime.location)
        for item in automaton.inputs:
            significand = int(values[item.name]) if item.is_bool else round(values[item.name] * data.scale)
            assert int(graph.inputs[item.name][node]) == significand
        state, held = after, values
        if ending.terminated:
            break
    if automaton.end_clauses:
        runtime.end(values)
        node = follow(graph, node, -1)
        check(node, int(graph.k[node]), ENDED, runtime.rewards, runtime.location)
        if ending.terminated:
            check(node, int(graph.k[node]), ENDED, ending.rewards, ending.location)
    assert graph.terminal()[node]
    assert ending.terminated == (int(graph.k[node]) < graph.horizon)


@settings(max_examples=30, deadline=None)
@given(decisions=st.lists(st.integers(0, 8), min_size=HORIZON // 2, max_size=HORIZON // 2))
def test_the_driving_product_follows_the_runtime(driving, decisions: list[int]) -> None:
    simulate_and_compare(*driving, decisions)


@settings(max_examples=30, deadline=None)
@given(decisions=st.lists(st.integers(0, 8), min_size=HORIZON // 2, max_size=HORIZON // 2))
def test_the_meter_product_follows_the_runtime(meter, decisions: list[int]) -> None:
    simulate_and_compare(*meter, decisions)


# ---------------------------------------------------------------- episode ends when
#: The left turn's run ends at an uncomfortable sample (turning or braking hard) or at the goal.
UNCOMFORTABLE = ir.BOr((ir.BNot(ir.BInput("comf")), ir.BAtom("dgoal", "<", F(2))))


@pytest.fixture(scope="module")
def driving_ends(driving) -> tuple[ir.Automaton, ModelData, ProductGraph]:
    automaton, data, _ = driving
    ends = replace(automaton, episode_ends=UNCOMFORTABLE)
    return ends, data, explore_product(data, ends, horizon_samples=HORIZON)


@pytest.fixture(scope="module")
def meter_ends(meter) -> tuple[ir.Automaton, ModelData, ProductGraph]:
    automaton, data, _ = meter  # the run ends where `gain` holds, which its end clause rewards
    ends = replace(automaton, episode_ends=ir.BInput("gain"))
    return ends, data, explore_product(data, ends, horizon_samples=HORIZON)


def test_episode_ends_makes_ended_states_terminal(driving, driving_ends) -> None:
    _, _, full = driving
    automaton, _, graph = driving_ends
    graph.validate()
    ended = graph.phase == ENDED
    early = ended & (graph.k < HORIZON)
    assert early.any() and (ended & (graph.k == HORIZON)).any()  # some runs end early, some go on
    assert np.all(graph.terminal()[ended])
    # every sampled state (after the start) whose inputs end the run leads to its ended state only
    sampled = np.flatnonzero((graph.phase == SAMPLED) & (graph.k > 0) & (graph.k < HORIZON))
    comf = graph.inputs["comf"][sampled] != 0
    assert (~comf).any() and comf.any()
    for state, ok in zip(sampled.tolist(), comf.tolist()):
        targets = graph.choice_target[graph.choices(state)]
        assert np.all(graph.phase[targets] == (ACCRUED if ok else ENDED))
        assert len(targets) == (1 if not ok else len(targets))
    assert graph.n_states < full.n_states


@settings(max_examples=30, deadline=None)
@given(decisions=st.lists(st.integers(0, 8), min_size=HORIZON // 2, max_size=HORIZON // 2))
def test_the_driving_product_ends_like_the_runtime(driving_ends, decisions: list[int]) -> None:
    simulate_and_compare(*driving_ends, decisions)


@settings(max_examples=30, deadline=None)
@given(decisions=st.lists(st.integers(0, 8), min_size=HORIZON // 2, max_size=HORIZON // 2))
def test_the_meter_product_ends_like_the_runtime(meter_ends, decisions: list[int]) -> None:
    simulate_and_compare(*meter_ends, decisions)


def test_episode_ends_without_end_clauses_leaves_the_sampled_state_terminal(driving) -> None:
    automaton, data, _ = driving
    plain = replace(automaton, end_clauses=(), episode_ends=UNCOMFORTABLE)
    graph = explore_product(data, plain, horizon_samples=HORIZON)
    graph.validate()
    assert not (graph.phase == ENDED).any()
    sampled = (graph.phase == SAMPLED) & (graph.k > 0)
    ends = (graph.inputs["comf"][sampled] == 0) | (graph.k[sampled] == HORIZON)
    assert np.array_equal(graph.terminal()[sampled], ends)


# ---------------------------------------------------------------- integer arithmetic
def test_mirror_arithmetic_truncates_towards_zero_like_c() -> None:
    loc = ir.Location("L", (ir.Linear(F(1), (("d", F(3)),)),))  # r' == 1 + 3*d: +1000 + trunc(3*d/10) per sample
    halve = ir.Assignment("r", ir.Linear(F(1, 4), (("r", F(1, 2)), ("d", F(1, 3)))))  # (3*r + 2*d + 15000) / 6
    automaton = ir.Automaton(
        name="A", inputs=(ir.Input("d", "real", F(-10), F(10)),), rewards=("r",), locations=(loc,), initial=0,
        edges=((ir.Edge(0, 0, ir.BAtom("d", "<", F(1, 3)), (halve,)),),), end_clauses=(), assumptions=(),
        objective=ir.Linear.variable("r"), priority=(), strict=False, period=F(1, 10), horizon=F(1))
    arithmetic = MirrorArithmetic(automaton, 10_000)
    d = np.array([[-7], [7], [-13], [3333], [3334]], dtype=np.int64)
    r = np.array([[5], [5], [-4], [1], [0]], dtype=np.int64)
    grown = arithmetic.accrue(np.zeros(5, dtype=np.int64), d, r)
    assert grown[:, 0].tolist() == [5 + 1000 - 2, 5 + 1000 + 2, -4 + 1000 - 3, 1 + 1000 + 999, 1000 + 1000]
    loc2, after = arithmetic.edges(np.zeros(5, dtype=np.int64), d, np.array([[-9000], [9001], [-1], [2], [0]]))
    # d < 1/3 is d < 3334 on significands: the last row takes no edge
    expected = [int(F(3 * m + 2 * x + 15000, 6)) for m, x in ((-9000, -7), (9001, 7), (-1, -13), (2, 3333))]
    assert after[:, 0].tolist() == [*expected, 0] and loc2.tolist() == [0] * 5
    assert expected[0] == -2002 and expected[2] == 2495  # -2002.33 and 2495.17: truncated towards zero


def test_mirror_arithmetic_keeps_every_value_on_the_way_within_int32() -> None:
    """Regression: the engine summed an update's and an accrual's terms in int64, where the emitted
    model computes each product and partial sum in int32. A bound input beyond its declared range
    (bindings are not clipped) made `100000*d / 7` leave int32 in UPPAAL while the engine went on
    with the exact value; now the engine raises ModelRangeError, as for a mirror leaving int32."""
    loc = ir.Location("L", (ir.Linear(F(-1000), (("d", F(1)),)),))  # iR + d - 10000000 per sample (period 1)
    update = ir.Assignment("r", ir.Linear(F(0), (("d", F(100000, 7)),)))  # (100000*d) / 7
    automaton = ir.Automaton(
        name="A", inputs=(ir.Input("d", "real", F(0), F(1)),), rewards=("r",), locations=(loc,), initial=0,
        edges=((ir.Edge(0, 0, ir.BConst(True), (update,)),),), end_clauses=(), assumptions=(),
        objective=ir.Linear.variable("r"), priority=(), strict=False, period=F(1), horizon=F(2))
    arithmetic = MirrorArithmetic(automaton, 10_000)
    at = np.zeros(1, dtype=np.int64)
    inside = np.array([[10_000]], dtype=np.int64)  # d = 1: 100000*d is 1e9
    assert arithmetic.edges(at, inside, np.zeros((1, 1), dtype=np.int64))[1].tolist() == [[142857142]]
    beyond = np.array([[100_000]], dtype=np.int64)  # d = 10: 1e10, though 1e10 / 7 would fit
    with pytest.raises(ModelRangeError, match="a value inside the update of `r`"):
        arithmetic.edges(at, beyond, np.zeros((1, 1), dtype=np.int64))
    # the accrual's `iR + d` before `- 10000000`: the result fits, the partial sum does not
    near = np.array([[2_140_000_000]], dtype=np.int64)
    assert arithmetic.accrue(at, inside, near).tolist() == [[2_130_010_000]]
    with pytest.raises(ModelRangeError, match="a value inside the accrual of `r`"):
        arithmetic.accrue(at, np.array([[9_000_000]], dtype=np.int64), near)


def test_a_mirror_may_reach_the_least_int32_as_the_range_check_allows() -> None:
    """Regression: `rac check` proved the int32 range (E0501 allows -2147483648, which UPPAAL's `int32_t`
    holds) for two updates that take `r` to -214748.3648, but the product refused that mirror, so every
    query of the file was unknown (exit 4) where the emitted model goes on. One less still leaves int32."""
    twice = (ir.Assignment("r", ir.Linear(F(-1073741824, 10_000), (("r", F(1)),))),) * 2
    automaton = ir.Automaton(
        name="A", inputs=(ir.Input("near", "bool"),), rewards=("r",),
        locations=(ir.Location("L", (ir.Linear(F(0)),)),), initial=0,
        edges=((ir.Edge(0, 0, ir.BConst(True), twice),),), end_clauses=(), assumptions=(),
        objective=ir.Linear.variable("r"), priority=(), strict=False, period=F(1, 2), horizon=F(1, 2))
    facts: list = []
    assert check_ranges(automaton, facts=facts) == [] and "[-214748.3648, 0]" in facts[0].message
    at, inputs = np.zeros(1, dtype=np.int64), np.zeros((1, 1), dtype=np.int64)
    _, mirrors = MirrorArithmetic(automaton, 10_000).edges(at, inputs, np.zeros((1, 1), dtype=np.int64))
    assert mirrors.tolist() == [[-(2**31)]]
    with pytest.raises(ModelRangeError, match=r"outside int32 \[-2147483648, 2147483647\]"):
        MirrorArithmetic(automaton, 10_000).edges(at, inputs, np.full((1, 1), -1, dtype=np.int64))


def test_one_edge_per_sample() -> None:
    """A state that moves Normal -> Unsafe takes no second edge (Unsafe -> Unsafe when collide) in the
    same sample: the penalty is subtracted once, as in the emitted model and rac.runtime.interpreter."""
    automaton = compile_file(REPO / "stdlib" / "driving.ra").raise_for_errors()
    inputs = np.array([[1, 1, 0, 1, 0]], dtype=np.int64)  # isClose prog comf collide dgoal
    loc, mirrors = MirrorArithmetic(automaton, 10_000).edges(np.array([0]), inputs, np.zeros((1, 3), dtype=np.int64))
    assert automaton.location_names[int(loc[0])] == "Unsafe" and mirrors[0].tolist() == [-1_000_000, 0, 0]
    runtime = RewardAutomaton(automaton)
    runtime.step({"isClose": True, "prog": True, "comf": False, "collide": True, "dgoal": 0.0})
    assert runtime.location == "Unsafe" and runtime.rewards["sa"] == pytest.approx(-100 + 0.1)


def test_two_edges_enabled_where_the_bindings_break_assume_are_refused() -> None:
    """stdlib/driving.ra's `assume collide imply isClose` makes it deterministic; the bindings may
    break it (under `collision sticky` collide() stays true once the obstacle is far). In Unsafe with
    collide and !isClose both `Unsafe -> Unsafe when collide` and a `*` edge are enabled: the emitted
    model takes either, the product took the first alone and answered, e.g., `E<> Unsafe && !isClose
    && collide` false where UPPAAL finds it. It now refuses with the edges and the inputs."""
    automaton = compile_file(REPO / "stdlib" / "driving.ra").raise_for_errors()
    unsafe = automaton.location_names.index("Unsafe")
    inputs = np.array([[1, 1, 1, 1, 0], [0, 1, 1, 1, 250]], dtype=np.int64)  # isClose prog comf collide dgoal
    arithmetic = MirrorArithmetic(automaton, 10_000)
    loc, _ = arithmetic.edges(np.array([unsafe]), inputs[:1], np.zeros((1, 3), dtype=np.int64))  # assume holds
    assert automaton.location_names[int(loc[0])] == "Unsafe"
    with pytest.raises(EvaluationError, match=r"the edges `Unsafe -> Normal` and `Unsafe -> Unsafe` are both "
                                              r"enabled .* \(isClose = false, prog = true, comf = true, collide = "
                                              r"true, dgoal = 0.025\) that `assume` excludes"):
        arithmetic.edges(np.array([unsafe, unsafe]), inputs, np.zeros((2, 3), dtype=np.int64))


def test_a_sticky_collision_that_breaks_assume_is_not_answered(tmp_path: Path) -> None:
    """The same in a whole run: the driving automaton in the tiny scenario avoidable_obstacle under
    `collision sticky`, where a run collides with the van and leaves it behind still colliding."""
    tiny = avoidable_obstacle()
    tiny.write(tmp_path)
    text = (REPO / "stdlib" / "driving.ra").read_text(encoding="utf-8")
    text = text[:text.index("    query ")].replace("sample every 0.1", "sample every 0.5")
    text = text.replace("horizon 30", "horizon 4")
    block = tiny.settings.model_block(f"{tiny.name}.xml", (
        "isClose = mindist() < 3 * collision_distance", "prog = dist_goal() < prev(dist_goal())",
        "comf = fabs(acc) < comfort_acceleration * max_acceleration", "collide = collide()", "dgoal = dist_goal()"))
    text += block[:block.rindex("}")] + "collision sticky\n}\n}\n"
    path = tmp_path / "sticky.ra"
    path.write_text(text, encoding="utf-8")
    result = compile_file(path)
    automaton = result.raise_for_errors()
    assert result.model_data is not None and result.model_data.sticky
    with pytest.raises(EvaluationError, match="`Unsafe -> .*` are both enabled"):
        explore_product(result.model_data, automaton)


def test_query_comparisons_are_exact_on_the_integers(driving) -> None:
    automaton, _, graph = driving
    query = queries(automaton)["Sum"]  # E<> sa + pr + co == 0.6
    mirrors = [graph.mirrors[r].tolist() for r in ("sa", "pr", "co")]
    exact = [F(a + b + c, 10_000) == F(6, 10) for a, b, c in zip(*mirrors)]
    assert graph.evaluate(query.query.expr).tolist() == exact and any(exact)
    # in doubles 0.2 + 0.2 + 0.2 is not 0.6: the emitted query compares iSa + iPr + iCo == 6000
    assert graph.evaluator is not None
    frame = dataclasses.replace(graph.frame(), mirrors=None)  # rewards as doubles only
    assert graph.evaluator.evaluate_bool(query.query.expr, frame).tolist() != exact
    verdict = decide_product(graph, query)
    assert verdict.holds and verdict.trace is not None and exact[verdict.trace[-1]]


def test_a_formula_that_reads_inputs_counts_in_settled_states_only(driving) -> None:
    automaton, _, graph = driving
    not_prog, prog = lower_expression(automaton, "!prog"), lower_expression(automaton, "prog")
    assert graph.evaluate(not_prog)[0]  # before the first reading every boolean input is false...
    assert not graph.label(not_prog, box=False)[0] and graph.label(prog, box=True)[0]  # ...unsettled
    with pytest.raises(EvaluationError, match="prev"):
        graph.evaluate(lower_expression(automaton, "prev(sa) > 0"))


# ---------------------------------------------------------------- queries
def test_qe_and_qh_on_the_left_turn(driving) -> None:
    automaton, data, graph = driving
    found = queries(automaton)
    qe, qh = decide_product(graph, found["Qe"]), decide_product(graph, found["Qh"])
    assert qe.holds and qh.holds and qe.trace is None
    assert qe.query == "A[] isClose imply Unsafe" and qe.n_states == graph.n_states
    # comfort is lost at the first full turn: a false verdict comes with its trace
    uncomfy = decide_product(graph, found["Uncomfy"])
    assert not uncomfy.holds and uncomfy.trace is not None
    trace = uncomfy.trace
    assert trace[0] == graph.initial and automaton.location_names[graph.location[trace[-1]]] == "Uncomfortable"
    assert all(int(b) in [int(graph.choice_target[c]) for c in graph.choices(a)] for a, b in zip(trace, trace[1:]))
    peak = decide_product(graph, found["Peak"])
    assert not peak.holds and peak.trace is not None and not graph.evaluate(found["Peak"].query.expr)[peak.trace[-1]]
    # after one sample the objective is 1.6 at most (before the edge, in Normal, and after it)
    assert decide_in_model(automaton, data, found["Peak"], horizon_samples=1).holds


def test_fewer_false_alarms_than_the_static_check(tmp_path: Path) -> None:
    far = compiled(tmp_path, CAREFUL.replace("CLOSE", "3 * collision_distance"), without_obstacles(),
                   analyse=False)
    (diagnostic,) = check_priorities(far)  # P2 needs isClose, at the end of the second at the latest
    assert diagnostic.code == "E0402"
    verdict = decide_in_model(far, coarse(far), "Qh")
    assert verdict.holds and verdict.trace is None
    # where an obstacle does come within 12 m, the model finds the violation, with the run that produces it
    near = compiled(tmp_path, CAREFUL.replace("CLOSE", "12"), SCENARIO.read_bytes(), analyse=False)
    data = coarse(near)
    graph = explore_product(data, near)
    assert graph.horizon == near.steps == 10
    verdict = decide_product(graph, queries(near)["Qh"])
    assert not verdict.holds and verdict.trace is not None
    last = verdict.trace[-1]
    assert near.location_names[graph.location[last]] == "Unsafe"
    assert 10 * int(graph.mirrors["sa"][last]) + int(graph.mirrors["pr"][last]) > 0
    assert graph.inputs["isClose"][last] == 1


def test_max_states_raises_memory_error(driving) -> None:
    automaton, data, _ = driving
    with pytest.raises(MemoryError, match="more than 1,000 states"):
        explore_product(data, automaton, horizon_samples=HORIZON, max_states=1000)


def test_an_input_without_a_binding_is_rejected(driving) -> None:
    automaton, data, _ = driving
    assert automaton.model is not None
    unbound = replace(automaton, model=replace(automaton.model, bindings=automaton.model.bindings[:-1]))
    with pytest.raises(ValueError, match="`dgoal` has no binding"):
        explore_product(data, unbound, horizon_samples=2)
