"""Storm verdicts and the permissive safety shield against a plain fixpoint reference (rac.engine.storm)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rac.engine import storm
from rac.engine.graph import ExploredGraph
from rac.engine.storm import KINDS, decide, safety_shield, to_mdp

# --- reference: least / greatest fixpoints over the choice arrays, plain Python -------------------------------


def successors(graph: ExploredGraph, state: int) -> list[int]:
    return [int(graph.choice_target[c]) for c in graph.choices(state)]


def ref_reach(graph: ExploredGraph, p: np.ndarray) -> np.ndarray:
    """States from which some path reaches a p-state (least fixpoint)."""
    reach = p.copy()
    changed = True
    while changed:
        changed = False
        for s in range(graph.n_states):
            if not reach[s] and any(reach[t] for t in successors(graph, s)):
                reach[s] = changed = True
    return reach


def ref_stay(graph: ExploredGraph, p: np.ndarray) -> np.ndarray:
    """States from which some maximal path keeps p in every state (greatest fixpoint)."""
    stay = p.copy()
    changed = True
    while changed:
        changed = False
        for s in range(graph.n_states):
            succ = successors(graph, s)
            if stay[s] and succ and not any(stay[t] for t in succ):
                stay[s] = False
                changed = True
    return stay


def ref_verdict(graph: ExploredGraph, kind: str, p: np.ndarray) -> bool:
    i = graph.initial
    return {"E<>": lambda: ref_reach(graph, p)[i], "A[]": lambda: not ref_reach(graph, ~p)[i],
            "E[]": lambda: ref_stay(graph, p)[i], "A<>": lambda: not ref_stay(graph, ~p)[i]}[kind]()


def check_trace(graph: ExploredGraph, kind: str, p: np.ndarray, trace: list[int]) -> None:
    """The trace is a path from the initial state with the property its kind claims."""
    assert trace and trace[0] == graph.initial
    for a, b in zip(trace, trace[1:]):
        assert b in successors(graph, a), f"{a} -> {b} is not a transition"
    if kind == "E<>":
        assert p[trace[-1]]
    elif kind == "A[]":
        assert not p[trace[-1]]
    else:
        inside = p if kind == "E[]" else ~p
        assert all(inside[s] for s in trace)
        assert graph.terminal()[trace[-1]]


# --- graphs ------------------------------------------------------------------------------------------------


def make_graph(succ: list[list[int]], labels: dict[str, list[bool]], actions: bool = True) -> ExploredGraph:
    n = len(succ)
    offsets = np.zeros(n + 1, dtype=np.int64)
    offsets[1:] = np.cumsum([len(s) for s in succ])
    targets = np.array([t for s in succ for t in s], dtype=np.int64)
    action = np.concatenate([np.arange(len(s)) if actions else -np.ones(len(s)) for s in succ] or [[]])
    graph = ExploredGraph(states=np.arange(n, dtype=np.int64)[:, None], columns=("id",), choice_offsets=offsets,
                          choice_action=action.astype(np.int64), choice_target=targets,
                          labels={k: np.array(v, dtype=bool) for k, v in labels.items()})
    graph.validate()
    return graph


@st.composite
def layered_graphs(draw: st.DrawFn) -> ExploredGraph:
    """5-60 states in time layers; each non-final state has 1-3 choices into the next one or two layers
    (duplicates allowed), so every path ends in a terminal state of the last layer."""
    n = draw(st.integers(5, 60))
    n_layers = draw(st.integers(2, min(n, 10)))
    cuts = sorted(draw(st.lists(st.integers(1, n - 1), min_size=n_layers - 1, max_size=n_layers - 1, unique=True)))
    layer_start = [0, *cuts, n]
    succ: list[list[int]] = []
    for layer in range(len(layer_start) - 1):
        for _ in range(layer_start[layer], layer_start[layer + 1]):
            if layer == len(layer_start) - 2:
                succ.append([])
                continue
            hi = layer_start[min(layer + 3, len(layer_start) - 1)] - 1
            k = draw(st.integers(1, 3))
            succ.append(draw(st.lists(st.integers(layer_start[layer + 1], hi), min_size=k, max_size=k)))
    labels = {}
    for name in ("p", "safe"):  # a density per label, so that both verdicts of every kind are common
        density = draw(st.integers(3, 10))
        labels[name] = [x < density for x in draw(st.lists(st.integers(0, 9), min_size=n, max_size=n))]
    return make_graph(succ, labels)


# --- properties -------------------------------------------------------------------------------------------------


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(layered_graphs())
def test_storm_agrees_with_reference(graph: ExploredGraph) -> None:
    for kind in KINDS:
        verdict = decide(graph, kind, "p")
        assert verdict.holds == ref_verdict(graph, kind, graph.labels["p"]), kind
        assert (verdict.n_states, verdict.n_choices) == (graph.n_states, graph.n_choices)
        witness_expected = verdict.holds if kind in ("E<>", "E[]") else not verdict.holds
        assert (verdict.trace is not None) == witness_expected, kind
        if verdict.trace is not None:
            check_trace(graph, kind, graph.labels["p"], verdict.trace)

    shield = safety_shield(graph, "safe")
    winning = ref_stay(graph, graph.labels["safe"])
    np.testing.assert_array_equal(shield.winning, winning)
    assert shield.shield_exists == bool(winning[graph.initial])
    # never a choice into a losing state; every choice of a winning state into a winning one is allowed
    source = np.repeat(np.arange(graph.n_states), np.diff(graph.choice_offsets))
    assert not np.any(shield.allowed_choices & ~winning[graph.choice_target])
    np.testing.assert_array_equal(shield.allowed_choices, winning[source] & winning[graph.choice_target])
    for s in range(graph.n_states):
        expected = [int(graph.choice_action[c]) for c in graph.choices(s)
                    if winning[s] and winning[graph.choice_target[c]]]
        assert shield.allowed(s).tolist() == expected
        # a winning non-terminal state always keeps at least one choice
        if winning[s] and not graph.terminal()[s]:
            assert expected


# --- examples -----------------------------------------------------------------------------------------------


@pytest.fixture
def diamond() -> ExploredGraph:
    """0 -> {1, 2}; 1 -> 3; 2 terminal; 3 terminal. p holds in 0, 1, 3."""
    return make_graph([[1, 2], [3], [], []], {"p": [True, True, False, True], "safe": [True, True, False, True]})


def test_to_mdp_layout(diamond: ExploredGraph) -> None:
    mdp = to_mdp(diamond)
    assert (mdp.nr_states, mdp.nr_choices) == (4, 5)  # 3 choices + 2 terminal self-loops
    assert list(mdp.initial_states) == [0]
    assert set(mdp.labeling.get_labels()) >= {"p", "safe", "init", "terminal"}
    assert sorted(mdp.labeling.get_states("terminal")) == [2, 3]
    matrix = mdp.transition_matrix
    assert [matrix.get_row_group_start(s) for s in range(4)] == [0, 2, 3, 4]
    rows = [[(e.column, e.value) for e in matrix.get_row(r)] for r in range(5)]
    assert rows == [[(1, 1.0)], [(2, 1.0)], [(3, 1.0)], [(2, 1.0)], [(3, 1.0)]]


def test_verdicts_on_diamond(diamond: ExploredGraph) -> None:
    assert decide(diamond, "E<>", "p").trace == [0]
    assert decide(diamond, "E[]", "p").trace == [0, 1, 3]
    a_box = decide(diamond, "A[]", "p")
    assert not a_box.holds and a_box.trace == [0, 2]
    assert decide(diamond, "A<>", "p").holds
    assert a_box.seconds >= 0 and a_box.query == "A[] p"


def test_shield_on_diamond(diamond: ExploredGraph) -> None:
    shield = safety_shield(diamond, "safe")
    assert shield.shield_exists
    assert shield.winning.tolist() == [True, True, False, True]
    assert shield.allowed(0).tolist() == [0] and shield.allowed(2).tolist() == []


@pytest.mark.parametrize("kind", KINDS)
def test_bfs_fallback_traces(diamond: ExploredGraph, kind: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Without Storm's scheduler the traces come from a BFS over the winning set, with the same properties."""
    expected = decide(diamond, kind, "p")
    monkeypatch.setattr(storm, "_scheduler_trace", lambda *args: None)
    verdict = decide(diamond, kind, "p")
    assert verdict.holds == expected.holds and (verdict.trace is None) == (expected.trace is None)
    if verdict.trace is not None:
        check_trace(diamond, kind, diamond.labels["p"], verdict.trace)


def test_rejects_bad_input(diamond: ExploredGraph) -> None:
    with pytest.raises(ValueError):
        decide(diamond, "E<<", "p")
    with pytest.raises(KeyError):
        decide(diamond, "E<>", "nope")
    clash = make_graph([[1], []], {"init": [True, False]})
    with pytest.raises(ValueError, match="reserved"):
        to_mdp(clash)


@pytest.mark.parametrize("size", [0, 1, 63, 64, 65, 1000])
def test_bit_vectors_from_packed_masks(size: int) -> None:
    """storm.bit_vector(mask) is the BitVector of the mask's set indices, at every length."""
    from stormpy import datastructures as sd

    from rac.engine.storm import bit_vector

    for seed in range(3):
        mask = np.random.default_rng(seed).random(size) < 0.4
        assert bit_vector(mask) == sd.BitVector(size, np.flatnonzero(mask).tolist())
