"""The safety shield without Storm (rac.engine.layered, issue 20) against Storm's (the oracle): the same
winning states and allowed choices on random graphs (layered by time, and any graph, cycles too), on
every shipped example with a model block, on benchmarks/zam_ramp.ra's model and on the built scenes."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from engine_files import safety_source
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rac.compiler import compile_file
from rac.engine import shield as shields
from rac.engine.budget import BudgetExceeded
from rac.engine.explore import explore
from rac.engine.graph import ExploredGraph
from rac.engine.layered import layer_bounds, safety_game
from rac.engine.storm import Shield, safety_shield, safety_shield_storm
from rac.model.data import ModelData
from rac.model.scenes import SCENES, write_scene

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = sorted(path for path in REPO.glob("examples/**/*.ra") if "model {" in path.read_text(encoding="utf-8"))
ZAM_RAMP = REPO / "benchmarks" / "zam_ramp.ra"
#: A graph compared on a model has at most about this many states (the horizon is chosen so).
STATES = 40_000


def assert_same(graph: ExploredGraph, label: str = "safe") -> Shield:
    """The fast shield equals Storm's on ``graph``: winning states, allowed choices, allowed actions."""
    fast, oracle = safety_shield(graph, label), safety_shield_storm(graph, label)
    np.testing.assert_array_equal(fast.winning, oracle.winning)
    np.testing.assert_array_equal(fast.allowed_choices, oracle.allowed_choices)
    assert fast.shield_exists == oracle.shield_exists
    return fast


def make_graph(succ: list[list[int]], safe: list[bool], k: list[int] | None) -> ExploredGraph:
    n = len(succ)
    offsets = np.zeros(n + 1, dtype=np.int64)
    offsets[1:] = np.cumsum([len(s) for s in succ])
    targets = np.array([t for s in succ for t in s], dtype=np.int64)
    actions = np.concatenate([np.arange(len(s)) for s in succ] or [[]]).astype(np.int64)
    if k is None:
        states, columns = np.arange(n, dtype=np.int32)[:, None], ("id",)
    else:
        states, columns = np.array(k, dtype=np.int32)[:, None], ("k",)
    graph = ExploredGraph(states, columns, offsets, actions, targets, 0, {"safe": np.array(safe, dtype=bool)})
    graph.validate()
    return graph


@st.composite
def time_layered(draw: st.DrawFn) -> ExploredGraph:
    """States in layers of one sample each (a ``k`` column), choices from each layer into the next
    one (some into a later one), duplicates allowed, some states without choices before the last layer."""
    sizes = draw(st.lists(st.integers(1, 6), min_size=1, max_size=8))
    starts = np.concatenate([[0], np.cumsum(sizes)]).tolist()
    succ: list[list[int]] = []
    k: list[int] = []
    for layer, size in enumerate(sizes):
        for _ in range(size):
            k.append(layer)
            if layer == len(sizes) - 1:
                succ.append([])
                continue
            last = starts[min(layer + 3, len(sizes))] - 1 if draw(st.booleans()) else starts[layer + 2] - 1
            succ.append(draw(st.lists(st.integers(starts[layer + 1], last), max_size=4)))
    density = draw(st.integers(4, 10))
    safe = [x < density for x in draw(st.lists(st.integers(0, 9), min_size=len(k), max_size=len(k)))]
    return make_graph(succ, safe, k)


@st.composite
def any_graph(draw: st.DrawFn) -> ExploredGraph:
    """Any graph of 1-25 states: choices to any state (cycles, self-loops), with or without a ``k``
    column that does not layer it."""
    n = draw(st.integers(1, 25))
    succ = [draw(st.lists(st.integers(0, n - 1), max_size=3)) for _ in range(n)]
    density = draw(st.integers(4, 10))
    safe = [x < density for x in draw(st.lists(st.integers(0, 9), min_size=n, max_size=n))]
    k = draw(st.one_of(st.none(), st.lists(st.integers(0, 3), min_size=n, max_size=n)))
    return make_graph(succ, safe, k)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(time_layered())
def test_the_backward_pass_equals_storm_on_layered_graphs(graph: ExploredGraph) -> None:
    assert layer_bounds(graph) is not None  # the backward pass, not the fallback
    shield = assert_same(graph)
    table, oracle = shields.table(shield), shields.table(safety_shield_storm(graph, "safe"))
    np.testing.assert_array_equal(table.masks, oracle.masks)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(any_graph())
def test_the_attractor_equals_storm_on_any_graph(graph: ExploredGraph) -> None:
    assert_same(graph)


def test_a_choice_into_its_own_layer_is_not_layered() -> None:
    """k = 0, 1, 1: state 1 -> 2 stays in layer 1, a cycle 2 -> 1 too; the fallback decides it."""
    graph = make_graph([[1], [2], [1]], [True, True, True], [0, 1, 1])
    assert layer_bounds(graph) is None
    assert assert_same(graph).winning.all()  # the cycle 1 -> 2 -> 1 stays safe forever
    acyclic = make_graph([[1, 2], [], []], [True, True, False], [0, 1, 1])
    assert layer_bounds(acyclic).tolist() == [0, 1, 3]
    assert safety_game(acyclic, acyclic.labels["safe"])[1].tolist() == [True, False]


def test_a_safe_state_without_choices_wins_as_in_storm() -> None:
    """A run that stops safely (``allow when`` left no action, or the horizon) is a safe run."""
    graph = make_graph([[1, 2], [], [3], []], [True, True, True, False], [0, 1, 1, 2])
    shield = assert_same(graph)
    assert shield.winning.tolist() == [True, True, False, False]
    assert shield.allowed(0).tolist() == [0]


# ---------------------------------------------------------------- models
def explored(data: ModelData, prune: bool, forget: bool) -> ExploredGraph:
    """The model explored to the longest horizon of 1, 2, 4, 8, ... samples (at most its goal's last)
    with at most :data:`STATES` states."""
    last = None
    horizon = 1
    while horizon <= min(data.goal_high, 256):
        try:
            last = explore(data, horizon_samples=horizon, prune_unsafe=prune, max_states=STATES,
                           forget_actions=forget)
        except BudgetExceeded:
            break
        horizon *= 2
    assert last is not None
    return last


def assert_same_on(data: ModelData) -> None:
    """Fast shield = Storm's on ``data`` explored pruned (and merged, as ``synthesise`` does) and whole,
    for its ``safe`` label and for a seeded random tenth of its states made unsafe too (at the short
    horizons a test affords, many models are safe everywhere)."""
    rng = np.random.default_rng(20)
    for prune, forget in ((True, True), (False, False)):
        graph = explored(data, prune, forget)
        assert layer_bounds(graph) is not None
        assert_same(graph)
        thinned = graph.labels["safe"] & (rng.random(graph.n_states) >= 0.1)
        shield = assert_same(dataclasses.replace(graph, labels={**graph.labels, "thinned": thinned}), "thinned")
        assert not shield.winning.all()


def test_every_example_is_found() -> None:
    assert {path.relative_to(REPO).as_posix() for path in EXAMPLES} >= {
        "examples/left_turn/model.ra", "examples/paper/model.ra", "examples/stdlib/speed_limit.ra"}


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda path: path.relative_to(REPO).as_posix())
def test_the_fast_shield_equals_storm_on_every_example(path: Path) -> None:
    data = compile_file(path).model_data
    assert data is not None
    assert_same_on(data)


def zam_ramp_over(scenario: Path, folder: Path) -> ModelData:
    """benchmarks/zam_ramp.ra (increments, ``allow when``, ``collision sticky``) over ``scenario``."""
    text = ZAM_RAMP.read_text(encoding="utf-8")
    start, end = text.index('scenario "') + len('scenario "'), text.index('.xml"') + len(".xml")
    source = folder / "zam_ramp.ra"
    source.write_text(text[:start] + str(scenario.resolve()) + text[end:], encoding="utf-8")
    data = compile_file(source).model_data
    assert data is not None
    return data


@pytest.mark.parametrize("name", sorted(SCENES))
def test_the_fast_shield_equals_storm_on_the_built_scenes(name: str, tmp_path: Path) -> None:
    scene = write_scene(name, tmp_path / f"{name}.xml")
    model = f'scenario "{scene.name}"\nexponent 2\ndecide_period 1\ngranularity 0.25\n' \
            "action jerk in [-2, 2] step 2\naction turn in [-0.2, 0.2] step 0.2\n" \
            "bind close = mindist() < 3 * collision_distance"
    source = tmp_path / f"{name}.ra"
    source.write_text(safety_source("Scene", 6, model, {}), encoding="utf-8")
    data = compile_file(source).model_data
    assert data is not None
    assert_same_on(data)
    # ZAM_Ramp's modelling choices (increments, an `allow when`, sticky collisions) over the scene;
    # its own start lies where these scenes have no road, so off-road runs are compared too
    assert_same_on(zam_ramp_over(scene, tmp_path))


def test_the_fast_shield_equals_storm_on_zam_ramp(tmp_path: Path) -> None:
    scenario = REPO.parent / "shared" / "scenarios" / "ZAM_Ramp-1_1-T-1.xml"
    if not scenario.is_file():
        pytest.skip("the shared ZAM_Ramp scenario is not beside this checkout")
    data = zam_ramp_over(scenario, tmp_path)
    for horizon in (10, 20):
        for prune in (True, False):
            graph = explore(data, horizon_samples=horizon, prune_unsafe=prune, forget_actions=prune)
            assert_same(graph)
