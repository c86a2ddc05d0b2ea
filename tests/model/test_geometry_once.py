"""Exploration reads the model's geometry once per distinct position (issue 20): the ``allow when`` rule,
the sticky collision test and the labels share one evaluation of ``offroad``/``mindist``/``goal`` per
distinct successor position, counted by wrapping the batch model's functions; the graph is the same
whatever the chunk size (the chunks' geometry merges with their rows)."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from engine_files import safety_source

from rac.compiler import compile_file
from rac.engine import explore as explore_module
from rac.engine.explore import GEOMETRY, action_pairs, explore
from rac.engine.graph import ExploredGraph
from rac.ir.vocabulary import MODEL_FUNCTIONS
from rac.model.batch import batch_model, sense_many
from rac.model.data import ModelData
from rac.model.scenes import write_scene

#: The rule and the history read the model before the successors merge. The ego starts at the right
#: edge of the road (its right side 0.3 m inside), so that turning right leaves it.
RULED = """\
scenario "highway.xml"
exponent 2
decide_period 0.4
granularity 1
dynamics increments
start_y 1.2
collision sticky
action jerk in [-2, 2] step 2
action turn in [-0.2, 0.2] step 0.2
allow when turn == 0 || (fabs(head) <= 0.1 && !offroad())
bind close = mindist() < 3 * collision_distance
"""
#: Nothing reads the model before the successors merge: the labels only.
PLAIN = """\
scenario "highway.xml"
exponent 2
decide_period 0.4
granularity 0.25
start_y 1.2
action jerk in [-2, 2] step 2
action turn in [-0.2, 0.2] step 0.2
bind close = mindist() < 3 * collision_distance
"""
HORIZON = 12  # samples


def model_data(folder: Path, model: str) -> ModelData:
    write_scene("highway", folder / "highway.xml")
    source = folder / "scene.ra"
    source.write_text(safety_source("Scene", 2, model, {}), encoding="utf-8")
    data = compile_file(source).model_data
    assert data is not None
    return data


def counted(data: ModelData, monkeypatch: pytest.MonkeyPatch) -> dict[str, Counter[tuple[int, ...]]]:
    """Wrap the batch model's functions of position: each call's rows, as (k, x, y, v, acc, head), counted."""
    model = batch_model(data)
    calls: dict[str, Counter[tuple[int, ...]]] = {name: Counter() for name in GEOMETRY}
    for name in GEOMETRY:
        original = getattr(model, name)

        def wrapped(states: np.ndarray, k: int | np.ndarray | None = None, *, _name: str = name,
                    _original=original) -> np.ndarray:
            samples = np.broadcast_to(np.asarray(-1 if k is None else k), (states.shape[0],))
            for sample, row in zip(samples.tolist(), np.asarray(states)[:, :5].tolist()):
                calls[_name][(sample, *row)] += 1
            return _original(states) if k is None else _original(states, k)

        monkeypatch.setattr(model, name, wrapped)
    return calls


def positions(graph: ExploredGraph, rows: np.ndarray) -> set[tuple[int, ...]]:
    """(k, x, y, v, acc, head) of graph rows (the ``k`` column first)."""
    return {tuple(row) for row in rows[:, :6].tolist()}


def successor_positions(data: ModelData, graph: ExploredGraph) -> set[tuple[int, ...]]:
    """Every successor's (k, position) of every expanded state, allowed or not, by sense() afresh."""
    pairs = action_pairs(data)
    found: set[tuple[int, ...]] = set()
    expanded = np.flatnonzero(~graph.terminal())
    for state in expanded.tolist():
        row = graph.states[state]
        k = int(row[0])
        ego = np.repeat(row[None, 1:8], len(pairs) if k % data.decide_every == 0 else 1, axis=0)
        if k % data.decide_every == 0:
            ego[:, 5:7] = pairs
        for moved in sense_many(data, ego).tolist():
            found.add((k + 1, *moved[:5]))
    return found


def test_the_geometry_is_every_model_function_of_position() -> None:
    # collide() is mindist() < TD (or the history); prev(e) is no function of the model
    assert set(GEOMETRY) == set(MODEL_FUNCTIONS) - {"collide", "prev"}


@pytest.mark.parametrize("forget", [False, True])
@pytest.mark.parametrize("prune", [False, True])
def test_the_rule_the_collision_test_and_the_labels_share_one_evaluation(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, prune: bool, forget: bool) -> None:
    data = model_data(tmp_path, RULED)
    calls = counted(data, monkeypatch)
    graph = explore(data, horizon_samples=HORIZON, prune_unsafe=prune, forget_actions=forget)
    stored = positions(graph, graph.states)
    reached = successor_positions(data, graph) | positions(graph, graph.states[:1])
    assert graph.n_choices >= graph.n_states > 100 and (~graph.labels["safe"]).any()
    for name in ("offroad", "mindist"):
        assert max(calls[name].values()) == 1, name  # never twice for one position
        # the rule (offroad) and the sticky collision (mindist) read every successor, merged by position
        assert stored <= set(calls[name]) <= reached, name
    assert set(calls["goal"]) == stored  # the labels only: the stored states' positions
    assert not calls["dist_goal"]


def test_without_a_rule_the_labels_read_each_stored_position_once(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    data = model_data(tmp_path, PLAIN)
    calls = counted(data, monkeypatch)
    graph = explore(data, horizon_samples=HORIZON, forget_actions=True)
    stored = positions(graph, graph.states)
    for name in ("offroad", "mindist", "goal"):
        assert max(calls[name].values()) == 1, name
        assert set(calls[name]) == stored, name


@pytest.mark.parametrize("model", [RULED, PLAIN], ids=["ruled", "plain"])
@pytest.mark.parametrize("forget", [False, True])
def test_the_graph_does_not_depend_on_the_chunks(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, model: str,
                                                 forget: bool) -> None:
    """Chunks of 7 successors, merged as they come (their geometry too): the same graph and labels."""
    data = model_data(tmp_path, model)
    whole = explore(data, horizon_samples=HORIZON, forget_actions=forget)
    monkeypatch.setattr(explore_module, "CHUNK_ROWS", 7)
    chunked = explore(data, horizon_samples=HORIZON, forget_actions=forget)
    for name in ("states", "choice_offsets", "choice_action", "choice_target"):
        np.testing.assert_array_equal(getattr(chunked, name), getattr(whole, name), err_msg=name)
    for name, mask in whole.labels.items():
        np.testing.assert_array_equal(chunked.labels[name], mask, err_msg=name)
