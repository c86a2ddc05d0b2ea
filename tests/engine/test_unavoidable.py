"""rac.engine.penalties: the decision states where every allowed choice is followed by a penalising
location, against a brute force that walks each choice of each state one by one.

The graphs are products of a safety automaton with the highway of :mod:`rac.model.scenes`
(tests/support/spawn_scene.py): the truck inside the unsafe distance at the start, and away; a decision
every sample and every second sample (the chain between decisions is followed); with `allow when`
leaving some actions out.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from spawn_scene import AWAY, SPAWNED, spawn_program

from rac.engine.penalties import choice_penalties, decision_states, unavoidable
from rac.engine.product import SAMPLED, ProductGraph, explore_product

#: (truck, options of the automaton): a decision per sample, a decision every 2 samples, `allow when`.
CASES = {
    "spawned": (SPAWNED, {}),
    "away": (AWAY, {}),
    "spawned_every_second_sample": (SPAWNED, {"sample": "0.1", "horizon": "0.6"}),
    "away_allow": (AWAY, {"allow": "v <= 20"}),
    "spawned_allow": (SPAWNED, {"sample": "0.1", "horizon": "0.6", "allow": "turn >= 0"}),
}


def product(tmp_path: Path, name: str) -> ProductGraph:
    truck, options = CASES[name]
    program = spawn_program(tmp_path, truck, **options)
    return explore_product(program.data, program.automaton)


def brute_force(graph: ProductGraph, mask: tuple[bool, ...]) -> tuple[set[int], dict[int, int]]:
    """The decision states where every choice incurs a penalty, and each decision choice's first
    penalising location (-1: none), by walking each choice until the next decision."""
    def is_decision(state: int) -> bool:
        return any(graph.choice_action[c] >= 0 for c in graph.choices(state))

    found, first = set(), {}
    for state in range(graph.n_states):
        if not is_decision(state):
            continue
        every = True
        for c in graph.choices(state):
            at, hit = int(graph.choice_target[c]), -1
            while True:
                location = int(graph.location[at])
                if graph.phase[at] == SAMPLED and graph.k[at] > 0 and mask[location]:
                    hit = location
                    break
                if is_decision(at) or len(graph.choices(at)) != 1:
                    break
                at = int(graph.choice_target[graph.choices(at)[0]])
            first[c] = hit
            every &= hit >= 0
        if every:
            found.add(state)
    return found, first


@pytest.mark.parametrize("name", list(CASES))
def test_unavoidable_matches_brute_force(tmp_path: Path, name: str) -> None:
    graph = product(tmp_path, name)
    decisions = decision_states(graph)
    assert decisions.sum() > 1
    for mask in itertools.product((False, True), repeat=2):  # every set of penalising locations
        expected, first = brute_force(graph, mask)
        found = unavoidable(graph, {"o": mask})["o"]
        assert set(found.states.tolist()) == expected, mask
        assert found.decisions == int(decisions.sum())
        ks = graph.k[found.states]
        assert np.all(np.diff(ks) >= 0)  # earliest sample first
        locations = choice_penalties(graph, mask)
        assert {c: int(locations[c]) for c in first} == first
        if not any(mask):
            assert found.states.size == 0


def test_the_spawn_is_unavoidable_at_the_start_and_the_scene_away_is_not(tmp_path: Path) -> None:
    spawned = unavoidable(product(tmp_path, "spawned"), {"sa": (False, True)})["sa"]
    assert spawned.first == 0  # the start: every action leads into Unsafe at the first sample
    away = unavoidable(product(tmp_path / "away", "away"), {"sa": (False, True)})["sa"]
    assert away.first is None


def test_allow_when_restricts_the_actions_tried(tmp_path: Path) -> None:
    graph = product(tmp_path, "spawned_allow")
    start = graph.choices(graph.initial)
    assert 0 < len(start) < 9  # `turn >= 0` leaves out the right turns
    assert unavoidable(graph, {"sa": (False, True)})["sa"].first == graph.initial


def test_before_leaves_out_the_later_decisions(tmp_path: Path) -> None:
    graph = product(tmp_path, "spawned")
    every = unavoidable(graph, {"sa": (False, True)})["sa"]
    early = unavoidable(graph, {"sa": (False, True)}, before=1)["sa"]
    assert early.states.tolist() == [s for s in every.states.tolist() if graph.k[s] < 1] == [0]
    assert early.decisions == 1


def test_an_incomplete_graph_is_refused(tmp_path: Path) -> None:
    truck, options = CASES["spawned"]
    program = spawn_program(tmp_path, truck, **options)
    graph = explore_product(program.data, program.automaton, beam=(2, lambda layer: np.zeros(layer.n_states)))
    with pytest.raises(ValueError, match="complete product"):
        unavoidable(graph, {"sa": (False, True)})
