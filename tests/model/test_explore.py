"""The vectorised model functions and the breadth-first exploration (rac.engine.explore).

The vectorised functions must equal rac.model.native bit for bit; explore() must find exactly
the states a plain scalar breadth-first search with NativeModel finds.
"""

from __future__ import annotations

import math
from dataclasses import replace
from fractions import Fraction as F
from pathlib import Path

import numpy as np
import pytest
from test_model_native import crossing_scenario, goal_scenario, make_spec, straight_scenario

from rac.engine.explore import COLUMNS, action_pairs, explore
from rac.ir import Action
from rac.model import ModelData, ModelRangeError, NativeModel, State, build_model_data
from rac.model.batch import collide_many, dist_goal_many, goal_many, mindist_many, offroad_many, sense_many

LEFT_TURN = Path(__file__).resolve().parents[2] / "examples" / "left_turn" / "model.ra"


def left_turn_data() -> ModelData:
    from rac.compiler import compile_file

    result = compile_file(LEFT_TURN)
    assert result.model_data is not None, result.diagnostics
    return result.model_data


def random_states(data: ModelData, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Random ego states around the road (some off it, some near obstacles) and samples."""
    rng = np.random.default_rng(seed)
    xs = np.asarray(data.road_x)
    ys = np.asarray(data.road_y)
    margin = 5 * data.scale
    x = rng.integers(xs.min() - margin, xs.max() + margin, n)
    y = rng.integers(ys.min() - margin, ys.max() + margin, n)
    # some states exactly on obstacle waypoints, so that collisions occur
    near = rng.random(n) < 0.3
    if data.obstacle_count:
        pick = rng.integers(0, len(data.wp_x), n)
        x = np.where(near, np.asarray(data.wp_x)[pick] + rng.integers(-3, 3, n) * data.scale, x)
        y = np.where(near, np.asarray(data.wp_y)[pick] + rng.integers(-3, 3, n) * data.scale, y)
    v = rng.integers(data.min_speed, data.max_speed + 1, n)
    acc = rng.integers(-data.max_acc, data.max_acc + 1, n)
    head = rng.integers(-7 * data.scale, 7 * data.scale, n)
    jerk = rng.choice(np.asarray(data.action("jerk").values), n)
    turn = rng.choice(np.asarray(data.action("turn").values), n)
    states = np.stack([x, y, v, acc, head, jerk, turn], axis=1).astype(np.int32)
    k = rng.integers(-2, 130, n)
    return states, k


def datasets() -> list[tuple[str, ModelData]]:
    return [
        ("straight", build_model_data(straight_scenario(), make_spec(3))),
        ("crossing", build_model_data(crossing_scenario(), make_spec(4, granularity=F(1, 4)))),
        ("goal", build_model_data(goal_scenario(), make_spec(2))),
        ("left_turn", left_turn_data()),
    ]


@pytest.mark.parametrize("name, data", datasets(), ids=lambda value: value if isinstance(value, str) else "")
def test_vectorised_functions_equal_native(name: str, data: ModelData) -> None:
    model = NativeModel(data)
    states, k = random_states(data, 3000, seed=len(name))
    rows = [State(*map(int, row)) for row in states]
    ks = [int(s) for s in k]
    sensed = sense_many(data, states)
    assert sensed.dtype == np.int32
    assert [tuple(row) for row in sensed.tolist()] == [tuple(model.sense(s)) for s in rows]
    mindist = mindist_many(data, states, k)
    expected = np.array([model.mindist(s, j) for s, j in zip(rows, ks)])
    assert np.array_equal(mindist.view(np.int64), expected.view(np.int64))  # bit for bit
    collide = collide_many(data, states, k)
    assert collide.tolist() == [model.collide(s, j) for s, j in zip(rows, ks)]
    offroad = offroad_many(data, states)
    assert offroad.tolist() == [model.offroad(s) for s in rows]
    goal = goal_many(data, states, k)
    assert goal.tolist() == [model.goal(s, j) for s, j in zip(rows, ks)]
    dist = dist_goal_many(data, states)
    assert dist.tolist() == [model.dist_goal(s) for s in rows]
    # every answer occurs, so the comparison means something
    if name != "goal":
        assert collide.any() and not collide.all()
    assert offroad.any() and not offroad.all()
    # one sample for the whole batch
    assert mindist_many(data, states, 40).tolist() == [model.mindist(s, 40) for s in rows]
    assert goal_many(data, states, 40).tolist() == [model.goal(s, 40) for s in rows]


def test_sense_many_overflow_raises() -> None:
    data = build_model_data(straight_scenario(), make_spec(6))
    states = np.array([[0, 0, 0, 0, 0, 0, 0], [2147000000, 0, 20000000, 0, 0, 0, 0]], dtype=np.int32)
    with pytest.raises(ModelRangeError, match="sense"):
        sense_many(data, states)


# ---------------------------------------------------------------- exploration
def tiny_data(scenario=None, horizon_decide: F = F(1, 5)) -> ModelData:
    spec = replace(make_spec(2, granularity=F(1, 2), decide=horizon_decide),
                   actions=(Action("jerk", F(-2), F(2), F(2)), Action("turn", F(-2, 5), F(2, 5), F(2, 5))))
    return build_model_data(scenario or straight_scenario(), spec)


def reference_layers(data: ModelData, horizon: int, prune_unsafe: bool) -> list[set[tuple[int, ...]]]:
    """A plain scalar breadth-first search with NativeModel: the set of states at each sample."""
    model = NativeModel(data)
    pairs = [(j, t) for j in data.action("jerk").values for t in data.action("turn").values]
    layers = [{tuple(model.initial_state())}]
    for k in range(horizon):
        following: set[tuple[int, ...]] = set()
        for state in layers[-1]:
            s = State(*state)
            if prune_unsafe and (model.collide(s, k) or model.offroad(s)):
                continue
            choices = [s._replace(jerk=j, turn=t) for j, t in pairs] if k % data.decide_every == 0 else [s]
            following.update(tuple(model.sense(c)) for c in choices)
        if not following:
            break
        layers.append(following)
    return layers


@pytest.mark.parametrize("prune_unsafe", [False, True])
def test_explore_matches_a_scalar_search(prune_unsafe: bool) -> None:
    # ego 12 m behind the obstacle that appears at sample 10, so that some runs collide
    scenario = replace(straight_scenario(), ego=straight_scenario().ego.__class__(22.0, 1.75, 0.0, 10.0))
    data = tiny_data(scenario, F(2, 5))
    horizon = 12
    calls: list[tuple[int, int, int]] = []
    graph = explore(data, horizon_samples=horizon, prune_unsafe=prune_unsafe,
                    progress=lambda *args: calls.append(args))
    graph.validate()
    assert graph.columns == COLUMNS and graph.states.dtype == np.int32
    assert graph.choice_target.dtype == np.int64 and graph.choice_offsets.dtype == np.int64
    reference = reference_layers(data, horizon, prune_unsafe)
    k = graph.states[:, 0]
    sizes = np.bincount(k).tolist()
    assert sizes == [len(layer) for layer in reference]
    for sample, layer in enumerate(reference):
        found = {tuple(row) for row in graph.states[k == sample, 1:].tolist()}
        assert found == layer
    assert [c[1] for c in calls] == sizes and calls[-1][2] == graph.n_states

    # no duplicates; the bound on the number of states per layer
    assert len({tuple(row) for row in graph.states.tolist()}) == graph.n_states
    n_pairs = len(action_pairs(data))
    assert n_pairs == 9
    for sample, size in enumerate(sizes):
        assert size <= n_pairs ** math.ceil(sample / data.decide_every)

    # labels and choices against native, state by state
    model = NativeModel(data)
    labels = graph.labels
    assert set(labels) == {"collide", "offroad", "goal", "safe"}
    pairs = action_pairs(data).tolist()
    for i, row in enumerate(graph.states.tolist()):
        sample, state = row[0], State(*row[1:])
        collide, offroad = model.collide(state, sample), model.offroad(state)
        assert (labels["collide"][i], labels["offroad"][i], labels["goal"][i], labels["safe"][i]) == (
            collide, offroad, model.goal(state, sample), not collide and not offroad)
        choices = graph.choices(i)
        if sample == horizon or (prune_unsafe and (collide or offroad)):
            assert len(choices) == 0
            continue
        decide = sample % data.decide_every == 0
        assert len(choices) == (n_pairs if decide else 1)
        for c in choices:
            action = int(graph.choice_action[c])
            chosen = state._replace(jerk=pairs[action][0], turn=pairs[action][1]) if decide else state
            assert action == (action if decide else -1)
            target = graph.states[graph.choice_target[c]].tolist()
            assert target == [sample + 1, *model.sense(chosen)]
    assert labels["collide"].any() and labels["safe"].any()
    assert graph.terminal()[k == horizon].all()


def test_explore_merges_states_and_stops_when_everything_is_pruned() -> None:
    # the L-shaped road: the ego starts 3.5 m from the road's start facing backwards, so every
    # run leaves the road; with pruning the exploration ends before the horizon
    scenario = replace(goal_scenario(), ego=goal_scenario().ego.__class__(5.0, 3.5, math.pi, 6.0))
    data = tiny_data(scenario)
    graph = explore(data, horizon_samples=40, prune_unsafe=True)
    graph.validate()
    assert graph.states[:, 0].max() < 40
    assert [len(layer) for layer in reference_layers(data, 40, True)] == np.bincount(graph.states[:, 0]).tolist()
    # speed clamped at 0 and zero turn: states merge (fewer than the bound)
    stopped = replace(scenario, ego=scenario.ego.__class__(20.0, 3.5, 0.0, 0.0))
    merged = explore(tiny_data(stopped), horizon_samples=6)
    merged.validate()
    sizes = np.bincount(merged.states[:, 0]).tolist()
    assert sizes == [len(layer) for layer in reference_layers(tiny_data(stopped), 6, False)]
    assert sizes[-1] < 9**3


def test_explore_horizon_defaults_to_the_goal_interval() -> None:
    data = tiny_data(goal_scenario(), horizon_decide=F(3, 2))
    graph = explore(data, prune_unsafe=True, max_states=10**6)
    assert graph.states[:, 0].max() == data.goal_high == 45
    assert graph.labels["goal"].any()
    with pytest.raises(MemoryError):
        explore(data, horizon_samples=10, max_states=50)
    with pytest.raises(ValueError):
        explore(data, horizon_samples=-1)


def test_point_in_polygons_on_vertices_and_edges() -> None:
    """The bounding-box shortcut of the vectorised crossing test changes no answer, also on
    vertices, on edges and just beside them."""
    from rac.model.native import point_in_polygons
    from rac.model.polygons import Polygons

    data = left_turn_data()
    model = NativeModel(data)
    xs, ys = np.asarray(model.road_xd), np.asarray(model.road_yd)
    rng = np.random.default_rng(7)
    pick = rng.integers(0, len(xs), 4000)
    other = rng.integers(0, len(xs), 4000)
    share = rng.choice([0.0, 0.5, 1.0, 1e-12, 1 - 1e-12], 4000)
    px = xs[pick] + (xs[other] - xs[pick]) * share + rng.choice([0.0, 1e-9, -1e-9, 1e-3], 4000)
    py = ys[pick] + (ys[other] - ys[pick]) * share + rng.choice([0.0, 1e-9, -1e-9, 1e-3], 4000)
    found = Polygons(model.road_xd, model.road_yd, data.road_start).inside(px, py)
    expected = [point_in_polygons(model.road_xd, model.road_yd, data.road_start, a, b)
                for a, b in zip(px.tolist(), py.tolist())]
    assert found.tolist() == expected
    assert found.any() and not found.all()
