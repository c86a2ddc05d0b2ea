"""What must be shown (issue 4): tiny scenarios whose answers are known by construction.

- Known answers (tiny_scenarios): Qb ``E[] !collide() && !offroad()`` and Qc
  ``E<> !collide() && !offroad() && goal()`` on the four named scenarios, the actions the safety
  shield allows at the start, witness traces that are paths of the graph and replay on
  :class:`rac.model.native.NativeModel`, and shielded runs that never collide.
- Properties over random small straight-road scenarios (hypothesis): every choice the shield
  allows leads to a winning, safe state (replayed with NativeModel), every winning state keeps an
  allowed choice until the horizon, and a random walk under the saved and loaded shield never
  collides or leaves the road.
- Storm's verdicts equal a plain breadth-first / fixpoint reference on graphs explored from the
  tiny scenarios (all four kinds, labels safe, goal, collide; with and without pruning).
"""

from __future__ import annotations

import math
import random
import tempfile
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import replace
from fractions import Fraction as F
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from test_storm import check_trace, successors
from tiny_scenarios import (
    LANE_WIDTH,
    TINY_SCENARIOS,
    Block,
    GoalBox,
    StraightRoad,
    TinyScenario,
    TinySettings,
    avoidable_obstacle,
    goal_behind_wall,
    narrow_road,
    straight_road,
)

from rac.engine import shield as shield_file
from rac.engine.explore import action_pairs, explore
from rac.engine.graph import ExploredGraph
from rac.engine.storm import KINDS, Shield, decide, safety_shield
from rac.model import ModelData, NativeModel, State
from rac.model.commonroad import EgoStart, Obstacle, Polygon, Waypoint, load_scenario

NAMES = tuple(TINY_SCENARIOS)
#: The label the tests add for Qc's proposition ``!collide() && !offroad() && goal()``.
SAFE_GOAL = "safe_goal"


class Explored(NamedTuple):
    tiny: TinyScenario
    data: ModelData
    graph: ExploredGraph


def with_safe_goal(graph: ExploredGraph) -> ExploredGraph:
    return replace(graph, labels={**graph.labels, SAFE_GOAL: graph.labels["safe"] & graph.labels["goal"]})


@pytest.fixture(scope="module")
def explored(tmp_path_factory: pytest.TempPathFactory) -> Callable[[str, bool], Explored]:
    """``explored(name, prune)``: the tiny scenario written, loaded and explored to its horizon (cached)."""
    folder = tmp_path_factory.mktemp("tiny")
    cache: dict[tuple[str, bool], Explored] = {}

    def get(name: str, prune: bool = True) -> Explored:
        if (name, prune) not in cache:
            tiny = TINY_SCENARIOS[name]()
            data = tiny.model_data(folder)
            graph = with_safe_goal(explore(data, horizon_samples=tiny.settings.horizon_samples, prune_unsafe=prune))
            graph.validate()
            cache[name, prune] = Explored(tiny, data, graph)
        return cache[name, prune]

    return get


# ---------------------------------------------------------------- helpers: paths, replay, plans
def sig(data: ModelData, value: F) -> int:
    """A model-block value as its significand (``trunc(v * SCALE)``, as rac.model.data does)."""
    return math.trunc(value * data.scale)


def pair_significands(data: ModelData, pairs: set[tuple[F, F]] | frozenset[tuple[F, F]]) -> set[tuple[int, int]]:
    return {(sig(data, jerk), sig(data, turn)) for jerk, turn in pairs}


def allowed_pairs(data: ModelData, shield: Shield, state: int) -> set[tuple[int, int]]:
    """The (jerk, turn) significands the shield allows in ``state``."""
    pairs = action_pairs(data).tolist()
    return {tuple(pairs[a]) for a in shield.allowed(state).tolist()}


def replay(data: ModelData, graph: ExploredGraph, trace: Sequence[int]) -> None:
    """``trace`` is a path of the graph from its initial state, and NativeModel, fed the actions of
    the trace's choices, computes exactly its states and their labels."""
    assert trace and trace[0] == graph.initial
    model = NativeModel(data)
    pairs = action_pairs(data).tolist()
    assert graph.states[trace[0]].tolist() == [0, *model.initial_state()]
    for a, b in zip(trace, trace[1:]):
        choice = next((c for c in graph.choices(a) if graph.choice_target[c] == b), None)
        assert choice is not None, f"{a} -> {b} is not a transition"
        k, *ego = graph.states[a].tolist()
        action = int(graph.choice_action[choice])
        state = State(*ego)
        if k % data.decide_every == 0:
            state = state._replace(jerk=pairs[action][0], turn=pairs[action][1])
        else:
            assert action == -1
        assert graph.states[b].tolist() == [k + 1, *model.sense(state)]
    for s in trace:
        k, *ego = graph.states[s].tolist()
        state = State(*ego)
        collide, offroad = model.collide(state, k), model.offroad(state)
        assert (graph.labels["collide"][s], graph.labels["offroad"][s], graph.labels["goal"][s]) == (
            collide, offroad, model.goal(state, k))


def run_plan(data: ModelData, plan: Sequence[tuple[F, F]], horizon: int) -> list[tuple[int, State]]:
    """NativeModel's run that takes ``plan[i]`` at the i-th decision: (sample, state) from 0 to ``horizon``."""
    model = NativeModel(data)
    state = model.initial_state()
    run = [(0, state)]
    for k in range(horizon):
        if k % data.decide_every == 0:
            jerk, turn = plan[k // data.decide_every]
            state = state._replace(jerk=sig(data, jerk), turn=sig(data, turn))
        state = model.sense(state)
        run.append((k + 1, state))
    return run


def safe_at(model: NativeModel, k: int, state: State) -> bool:
    return not model.collide(state, k) and not model.offroad(state)


# ---------------------------------------------------------------- reference: plain BFS / fixpoints
def predecessors(graph: ExploredGraph) -> list[list[int]]:
    """One entry per choice: ``pred[t]`` lists the source of every choice into t."""
    pred: list[list[int]] = [[] for _ in range(graph.n_states)]
    for s in range(graph.n_states):
        for t in successors(graph, s):
            pred[t].append(s)
    return pred


def ref_reach(graph: ExploredGraph, p: np.ndarray, through: np.ndarray | None = None) -> np.ndarray:
    """States from which some path reaches a p-state (passing only ``through`` states before it):
    breadth-first backwards from the p-states."""
    pred = predecessors(graph)
    reach = p.copy()
    queue = deque(np.flatnonzero(p).tolist())
    while queue:
        t = queue.popleft()
        for s in pred[t]:
            if not reach[s] and (through is None or through[s]):
                reach[s] = True
                queue.append(s)
    return reach


def ref_stay(graph: ExploredGraph, p: np.ndarray) -> np.ndarray:
    """States from which some maximal path keeps p in every state (greatest fixpoint): a p-state
    drops out when it is not terminal and none of its choices leads to a state still in."""
    pred = predecessors(graph)
    stay = p.copy()
    alive = np.array([sum(1 for t in successors(graph, s) if stay[t]) for s in range(graph.n_states)])
    terminal = graph.terminal()
    queue = deque(s for s in range(graph.n_states) if stay[s] and not terminal[s] and alive[s] == 0)
    while queue:
        s = queue.popleft()
        if not stay[s]:
            continue
        stay[s] = False
        for r in pred[s]:
            alive[r] -= 1
            if stay[r] and alive[r] == 0:
                queue.append(r)
    return stay


def ref_verdict(graph: ExploredGraph, kind: str, p: np.ndarray) -> bool:
    i = graph.initial
    if kind == "E<>":
        return bool(ref_reach(graph, p)[i])
    if kind == "A[]":
        return not ref_reach(graph, ~p)[i]
    if kind == "E[]":
        return bool(ref_stay(graph, p)[i])
    return not ref_stay(graph, ~p)[i]


# ---------------------------------------------------------------- the files
def test_tiny_scenarios_load_as_built(tmp_path: Path) -> None:
    for name, build in TINY_SCENARIOS.items():
        tiny = build()
        assert tiny.name == name and tiny.xml == build().xml  # byte-stable
        scenario = load_scenario(tiny.write(tmp_path))
        assert scenario.dt == 0.1 and scenario.planning_problem_id == 100
        assert scenario.ego.heading == 0.0 and scenario.ego.x == 10.0
        assert (scenario.goal.time_low, scenario.goal.time_high) == (0.0, 4.0)
        assert len(scenario.road) == 1
        assert tiny.model_spec().scenario == f"{name}.xml"
        assert tiny.settings.horizon_samples == 8 and tiny.settings.decide_every == 2
    scenario = load_scenario(avoidable_obstacle().write(tmp_path))
    assert scenario.name == "ZAM_AvoidableObstacle-1_1_T-1"
    assert scenario.road == (Polygon(((100.0, 0.0), (100.0, 3.0), (0.0, 3.0), (0.0, 0.0))),)
    assert scenario.obstacles == (Obstacle(11, 6.0, 2.4, (Waypoint(0.0, 25.0, 1.5, 0.0, 0.0),), static=True,
                                           kind="parkedVehicle"),)
    assert scenario.ego == EgoStart(10.0, 1.5, 0.0, 5.0)
    assert scenario.goal.regions == (Polygon(((50.0, 0.0), (50.0, 3.0), (40.0, 3.0), (40.0, 0.0))),)
    wall = load_scenario(goal_behind_wall().write(tmp_path)).obstacles
    assert [(o.length, o.width, o.static, o.kind, o.waypoints[0].x) for o in wall] == [
        (6.0, 4.5, True, "constructionZone", 36.0)]
    assert load_scenario(narrow_road().write(tmp_path)).road[0].points[1] == (60.0, 1.0)


def test_moving_obstacles_and_lanes_load(tmp_path: Path) -> None:
    road = StraightRoad(50.0, EgoStart(5.0, 1.75, 0.0, 4.0), GoalBox(30.0, 40.0, 1.0, 2.0), lanes=2,
                        obstacles=(Block(11, 20.0, 5.25, velocity=3.0, heading=math.pi),))
    tiny = straight_road("two_lanes", road)
    assert tiny.stays_safe is None and tiny.start_actions is None  # nothing known by construction
    scenario = load_scenario(tiny.write(tmp_path / "two.xml"))
    assert [p.points for p in scenario.road] == [((50.0, 0.0), (50.0, 3.5), (0.0, 3.5), (0.0, 0.0)),
                                                 ((50.0, 3.5), (50.0, 7.0), (0.0, 7.0), (0.0, 3.5))]
    (car,) = scenario.obstacles
    assert not car.static and car.kind == "car" and len(car.waypoints) == 21  # the initial state and 20 steps
    assert car.waypoints[-1].time == 2.0 and car.waypoints[-1].x == pytest.approx(14.0)
    assert car.waypoints[-1].velocity == 3.0 and car.waypoints[-1].heading == pytest.approx(math.pi, abs=1e-6)
    assert (scenario.goal.time_low, scenario.goal.time_high) == (1.0, 2.0)
    with pytest.raises(ValueError, match="unique"):
        replace(road, obstacles=(Block(2, 20.0, 1.75),))


def test_model_block_compiles_to_the_same_model(tmp_path: Path) -> None:
    from rac.compiler import compile_file

    tiny = avoidable_obstacle()
    tiny.write(tmp_path)
    block = tiny.settings.model_block(f"{tiny.name}.xml", ["hit = collide()"])
    source = ("automaton Tiny {\n    input hit : bool\n    reward sa\n    objective sa\n    sample every 0.5\n"
              "    horizon 4\n    initial location Normal { sa' == 1 }\n"
              + "".join(f"    {line}\n" for line in block.splitlines()) + "}\n")
    (tmp_path / "tiny.ra").write_text(source)
    result = compile_file(tmp_path / "tiny.ra")
    assert result.model_data is not None, result.diagnostics
    assert result.model_data == tiny.model_data(tmp_path)
    assert "action turn in [-0.2, 0.2] step 0.2" in block and "sense_period 0.5" in block


# ---------------------------------------------------------------- known answers
def test_narrow_road_is_off_the_road_everywhere(explored: Callable[[str, bool], Explored]) -> None:
    full = explored("narrow_road", False)
    graph = full.graph
    assert graph.n_states > 1000 and graph.labels["offroad"].all()  # by construction: every state
    assert decide(graph, "A[]", "offroad").holds
    qb = decide(graph, "E[]", "safe")
    assert not qb.holds and qb.trace is None
    assert not safety_shield(graph, "safe").shield_exists
    pruned = explored("narrow_road", True)
    assert pruned.graph.n_states == 1  # the start is off the road: nothing is expanded
    shield = safety_shield(pruned.graph, "safe")
    assert not shield.shield_exists and shield.allowed(0).size == 0
    assert pruned.tiny.start_actions == frozenset()


@pytest.mark.parametrize("name", NAMES)
def test_known_verdicts_with_traces(name: str, explored: Callable[[str, bool], Explored]) -> None:
    tiny, data, graph = explored(name, True)
    horizon = tiny.settings.horizon_samples
    safe, safe_goal = graph.labels["safe"], graph.labels[SAFE_GOAL]

    qb = decide(graph, "E[]", "safe")
    assert qb.holds == tiny.stays_safe
    if qb.holds:  # a run safe in every state up to the horizon
        assert qb.trace is not None
        replay(data, graph, qb.trace)
        assert all(safe[s] for s in qb.trace)
        assert graph.states[qb.trace[-1], 0] == horizon and len(qb.trace) == horizon + 1
    else:
        assert qb.trace is None

    qc = decide(graph, "E<>", SAFE_GOAL)
    assert qc.holds == tiny.reaches_goal
    if qc.holds:  # a run to a goal state, safe on the way (the graph is pruned)
        assert qc.trace is not None
        replay(data, graph, qc.trace)
        assert safe_goal[qc.trace[-1]] and all(safe[s] for s in qc.trace)
    else:
        assert qc.trace is None

    shield = safety_shield(graph, "safe")
    assert shield.shield_exists == tiny.stays_safe
    assert tiny.start_actions is not None
    assert allowed_pairs(data, shield, graph.initial) == pair_significands(data, tiny.start_actions)


@pytest.mark.parametrize("name", NAMES)
def test_plans_show_the_answers_on_the_model(name: str, explored: Callable[[str, bool], Explored]) -> None:
    """The runs each scenario documents, simulated with NativeModel alone, and found in the graph."""
    tiny, data, graph = explored(name, True)
    model = NativeModel(data)
    horizon = tiny.settings.horizon_samples
    known = {tuple(row) for row in graph.states.tolist()}
    assert bool(tiny.safe_plan) == tiny.stays_safe and bool(tiny.goal_plan) == tiny.reaches_goal
    if tiny.safe_plan:
        run = run_plan(data, tiny.safe_plan, horizon)
        assert all(safe_at(model, k, state) for k, state in run)
        assert all((k, *state) in known for k, state in run)
    if tiny.goal_plan:
        run = run_plan(data, tiny.goal_plan, horizon)
        first = next(i for i, (k, state) in enumerate(run) if model.goal(state, k))
        assert all(safe_at(model, k, state) for k, state in run[:first + 1])
    # jerk 0 throughout: where a shield forbids it at the start, it collides (or is off the road)
    # before the horizon; on the empty road it stays safe but misses the goal
    keep = run_plan(data, [(F(0), F(0))] * 4, horizon)
    keep_allowed = (sig(data, F(0)), 0) in pair_significands(data, tiny.start_actions or frozenset())
    assert all(safe_at(model, k, state) for k, state in keep) == keep_allowed
    if name == "goal_ahead":
        assert not any(model.goal(state, k) for k, state in keep)


@pytest.mark.parametrize("name, stop, keep_stop, threshold", [
    ("avoidable_obstacle", 1696, 2196, 1827),  # x in cm: 16.96 m, 21.96 m, 18.27 m
    ("goal_behind_wall", 2531, 3331, 2837),  # 25.31 m, 33.31 m, 28.37 m
])
def test_braking_facts(name: str, stop: int, keep_stop: int, threshold: int,
                       explored: Callable[[str, bool], Explored]) -> None:
    """The numbers the builders' docstrings derive, checked on the model: where braking at once
    stops, where braking after a second of jerk 0 stops, the collision threshold straight behind
    the obstacle, and that a turn held for the first second leaves the road at sample 2."""
    data = explored(name, True).data
    model = NativeModel(data)
    brake = run_plan(data, [(F(-2), F(0))] * 6, 12)
    assert brake[-1][1].v == 0 and brake[-1][1].x == stop
    assert all(safe_at(model, k, s) for k, s in brake)
    late = run_plan(data, [(F(0), F(0))] + [(F(-2), F(0))] * 5, 12)
    assert late[-1][1].v == 0 and late[-1][1].x == keep_stop
    assert any(model.collide(s, k) for k, s in late[:9])  # within the 4 s horizon
    at = model.initial_state()
    assert not model.collide(at._replace(x=threshold - 1), 0) and model.collide(at._replace(x=threshold + 1), 0)
    for jerk in (F(-2), F(0), F(2)):
        for turn in (F(-1, 5), F(1, 5)):
            swerve = run_plan(data, [(jerk, turn)] + [(F(-2), F(0))] * 3, 8)
            assert model.offroad(swerve[2][1]), (jerk, turn)


def test_goal_behind_wall_qc_means_reaching_the_goal_without_colliding(
        explored: Callable[[str, bool], Explored]) -> None:
    """In the model a collision does not end a run: on the full graph some run drives through the
    wall (colliding on the way) and ends in a safe goal state, so ``E<> safe && goal`` holds there.
    Qc's answer "false" is that of the pruned graph: the goal is not reachable through safe states."""
    graph = explored("goal_behind_wall", False).graph
    through = decide(graph, "E<>", SAFE_GOAL)
    assert through.holds and through.trace is not None
    assert graph.labels[SAFE_GOAL][through.trace[-1]]
    assert any(graph.labels["collide"][s] for s in through.trace)
    assert not ref_reach(graph, graph.labels[SAFE_GOAL], through=graph.labels["safe"])[graph.initial]
    # without the wall the same goal is reachable (the wall is the reason)
    assert decide(explored("goal_ahead", False).graph, "E<>", SAFE_GOAL).holds


@pytest.mark.parametrize("name", ["avoidable_obstacle", "goal_behind_wall", "goal_ahead"])
def test_shielded_runs_never_collide(name: str, explored: Callable[[str, bool], Explored], tmp_path: Path) -> None:
    tiny, data, graph = explored(name, True)
    shield = safety_shield(graph, "safe")
    n_actions = len(action_pairs(data))
    table = shield_file.load(shield_file.save(shield, tmp_path / "safe.npz", n_actions=n_actions), unseen="error")
    start = graph.states[graph.initial]
    assert set(table.allowed(start).tolist()) == set(shield.allowed(graph.initial).tolist())
    for seed in range(20):
        shielded_walk(data, table, tiny.settings.horizon_samples, random.Random(seed))


def shielded_walk(data: ModelData, table: shield_file.ShieldTable, horizon: int, rng: random.Random) -> None:
    """A run to the horizon that picks a random allowed action at every decision (the loaded shield,
    which raises on a state it has not seen), simulated with NativeModel: safe in every state."""
    model = NativeModel(data)
    pairs = action_pairs(data).tolist()
    state = model.initial_state()
    assert safe_at(model, 0, state)
    for k in range(horizon):
        if k % data.decide_every == 0:
            allowed = table.allowed([k, *state]).tolist()
            assert allowed, f"the shield allows nothing at sample {k}"
            jerk, turn = pairs[rng.choice(allowed)]
            state = state._replace(jerk=jerk, turn=turn)
        state = model.sense(state)
        assert safe_at(model, k + 1, state), f"a shielded run is unsafe at sample {k + 1}: {state}"


# ---------------------------------------------------------------- properties over random roads
def grids(low: Sequence[F], step: Sequence[F]) -> st.SearchStrategy[tuple[F, F, F]]:
    """``(low, high, step)`` of an action with 1 to 3 values."""
    return st.tuples(st.sampled_from(low), st.sampled_from(step), st.integers(1, 3)).map(
        lambda t: (t[0], t[0] + t[1] * (t[2] - 1), t[1]))


@st.composite
def random_roads(draw: st.DrawFn) -> TinyScenario:
    """A straight road of 1 or 2 lanes; the ego at x = 10 in lane 1; 1 or 2 obstacles 8 to 50 m ahead,
    parked or driving either way at up to 6 m/s; random coarse action grids, periods and horizon
    (at most 4 decisions, so at most 9**4 states per sample)."""
    lanes = draw(st.integers(1, 2))
    blocks = []
    for i in range(draw(st.integers(1, 2))):
        lane = draw(st.integers(0, lanes - 1))
        speed = draw(st.sampled_from([0.0, 0.0, 2.0, 4.0, 6.0]))
        blocks.append(Block(11 + i, x=draw(st.integers(36, 120)) / 2,
                            y=LANE_WIDTH * (lane + 0.5) + draw(st.sampled_from([-0.5, 0.0, 0.5])),
                            velocity=speed, heading=draw(st.sampled_from([0.0, math.pi])) if speed else 0.0))
    decide_period = draw(st.sampled_from([F(1, 2), F(1)]))
    horizon = F(2) if decide_period == F(1, 2) else draw(st.sampled_from([F(2), F(3), F(4)]))
    settings = TinySettings(jerk=draw(grids([F(-3), F(-2), F(-1), F(0)], [F(1), F(2), F(3)])),
                            # mostly grids with 0: without it every run turns and soon leaves the road
                            turn=draw(st.sampled_from([(F(0), F(0), F(1, 10)), (F(-1, 10), F(1, 10), F(1, 10)),
                                                       (F(-1, 5), F(1, 5), F(1, 5)), (F(-1, 5), F(0), F(1, 5)),
                                                       (F(0), F(1, 10), F(1, 10))]) | grids(
                                [F(-1, 5), F(-1, 10), F(0)], [F(1, 10), F(1, 5)])),
                            decide_period=decide_period, horizon=horizon)
    ego = EgoStart(10.0, LANE_WIDTH / 2, 0.0, float(draw(st.sampled_from([0, 2, 4, 6, 8]))))
    road = StraightRoad(80.0, ego, GoalBox(40.0, 60.0, 0.0, float(horizon)), lanes=lanes, obstacles=tuple(blocks))
    return straight_road("random_road", road, settings=settings)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(random_roads(), st.randoms(use_true_random=False))
def test_shield_allows_only_choices_that_stay_safe(tiny: TinyScenario, rng: random.Random) -> None:
    with tempfile.TemporaryDirectory(prefix="rac-known-") as folder:
        data = tiny.model_data(folder)
        horizon = tiny.settings.horizon_samples
        graph = explore(data, horizon_samples=horizon, prune_unsafe=True)
        shield = safety_shield(graph, "safe")
        np.testing.assert_array_equal(shield.winning, ref_stay(graph, graph.labels["safe"]))
        assert shield.shield_exists == decide(graph, "E[]", "safe").holds

        model = NativeModel(data)
        pairs = action_pairs(data).tolist()
        k_of = graph.states[:, 0]
        for s in range(graph.n_states):
            allowed = [c for c in graph.choices(s) if shield.allowed_choices[c]]
            if not shield.winning[s]:
                assert not allowed
                continue
            # a winning state is safe, and keeps an allowed choice unless it is at the horizon
            assert graph.labels["safe"][s]
            assert allowed or k_of[s] == horizon
            k, *ego = graph.states[s].tolist()
            for c in allowed:
                target = int(graph.choice_target[c])
                assert shield.winning[target]
                state = State(*ego)
                if graph.choice_action[c] >= 0:
                    jerk, turn = pairs[int(graph.choice_action[c])]
                    state = state._replace(jerk=jerk, turn=turn)
                after = model.sense(state)
                assert graph.states[target].tolist() == [k + 1, *after]
                assert not model.collide(after, k + 1) and not model.offroad(after)

        # what the examples cover (pytest --hypothesis-show-statistics)
        source = np.repeat(np.arange(graph.n_states), np.diff(graph.choice_offsets))
        forbids = bool((shield.winning[source] & ~shield.allowed_choices).any())
        event("no shield" if not shield.shield_exists else "the shield forbids a choice of a winning state"
              if forbids else "the shield allows every choice of the winning states")
        if shield.shield_exists:
            path = shield_file.save(shield, Path(folder) / "safe.npz", n_actions=len(pairs))
            table = shield_file.load(path, unseen="error")
            for _ in range(3):
                shielded_walk(data, table, horizon, rng)


# ---------------------------------------------------------------- Storm against the reference
@pytest.mark.parametrize("prune", [True, False], ids=["pruned", "full"])
@pytest.mark.parametrize("name", NAMES)
def test_storm_equals_reference(name: str, prune: bool, explored: Callable[[str, bool], Explored]) -> None:
    graph = explored(name, prune).graph
    for label in ("safe", "goal", "collide", SAFE_GOAL):
        p = graph.labels[label]
        for kind in KINDS:
            verdict = decide(graph, kind, label)
            assert verdict.holds == ref_verdict(graph, kind, p), (kind, label)
            witness_expected = verdict.holds if kind in ("E<>", "E[]") else not verdict.holds
            assert (verdict.trace is not None) == witness_expected, (kind, label)
            if verdict.trace is not None:
                check_trace(graph, kind, p, verdict.trace)
    shield = safety_shield(graph, "safe")
    winning = ref_stay(graph, graph.labels["safe"])
    np.testing.assert_array_equal(shield.winning, winning)
    source = np.repeat(np.arange(graph.n_states), np.diff(graph.choice_offsets))
    np.testing.assert_array_equal(shield.allowed_choices, winning[source] & winning[graph.choice_target])

