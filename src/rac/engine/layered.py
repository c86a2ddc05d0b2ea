"""The safety game of an explored graph solved without Storm: a backward pass over its layers (issue 20).

:func:`safety_game` gives the winning states and the allowed choices of ``control: A[] safe``, the
same as Storm's ``Pmax=? [G "safe"]`` (:func:`rac.engine.storm.safety_shield_storm`, the oracle in
the tests) on every graph: a state wins when it is safe and it is terminal (a run ends there; Storm's
self-loop) or one of its choices leads to a winning state; a choice is allowed when its state and
its successor win. The greatest such set is Storm's value-1 set, since every choice has a single
successor (probabilities 0 or 1).

An explored graph is layered by time (:func:`rac.engine.explore.explore`: the states of sample
``k`` are contiguous and every choice goes from sample ``k`` to ``k + 1``), so one pass from the last
layer to the first decides each layer from the next one's verdicts: a few array operations per
layer, and beyond the two results (one byte per state and per choice) only one layer's
temporaries. A graph that is not layered that way (a hand-made one, or a cycle) is solved by the
attractor of its unsafe states, computed in rounds over the predecessors (linear in the graph).

Example::

    winning, allowed = safety_game(graph, graph.labels["safe"])
"""

from __future__ import annotations

import numpy as np

from rac.engine.graph import ExploredGraph

__all__ = ["layer_bounds", "safety_game"]


def layer_bounds(graph: ExploredGraph) -> np.ndarray | None:
    """The boundaries ``b`` (``b[0] = 0 < ... < b[-1] = n``) of the graph's runs of states with the
    same ``k``, when every choice of a state in ``b[i]:b[i + 1]`` leads to a state at ``b[i + 1]`` or
    beyond; None when the graph has no ``k`` column or is not layered so."""
    n = graph.n_states
    if n == 0 or "k" not in graph.columns:
        return None
    k = graph.states[:, graph.columns.index("k")]
    bounds = np.concatenate([[0], np.flatnonzero(k[1:] != k[:-1]) + 1, [n]]).astype(np.int64)
    offsets, target = graph.choice_offsets, graph.choice_target
    for low, high in zip(bounds[:-1].tolist(), bounds[1:].tolist()):
        first, last = int(offsets[low]), int(offsets[high])
        if last > first and int(target[first:last].min()) < high:
            return None
    return bounds


def safety_game(graph: ExploredGraph, safe: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(winning (n,) bool, allowed (m,) bool)`` of ``control: A[] safe`` on ``graph`` (see the module
    docstring): the winning states, and the choices of winning states whose successor wins."""
    safe = np.asarray(safe, dtype=bool)
    if safe.shape != (graph.n_states,):
        raise ValueError(f"safe must have shape ({graph.n_states},), not {safe.shape}")
    bounds = layer_bounds(graph)
    if bounds is None:
        return _attractor(graph, safe)
    offsets, target = graph.choice_offsets, graph.choice_target
    winning = np.zeros(graph.n_states, dtype=bool)
    allowed = np.zeros(graph.n_choices, dtype=bool)
    for low, high in zip(bounds[-2::-1].tolist(), bounds[:0:-1].tolist()):  # the last layer first
        first, last = int(offsets[low]), int(offsets[high])
        if last == first:  # terminal states only: a run ends there, safe or not
            winning[low:high] = safe[low:high]
            continue
        onward = winning[target[first:last]]  # the next layers are decided
        counts = np.diff(offsets[low:high + 1])
        deciding = counts > 0
        some = np.zeros(high - low, dtype=bool)
        # reduceat over the non-empty groups: each runs to the next non-empty group's start
        some[deciding] = np.logical_or.reduceat(onward, offsets[low:high][deciding] - first)
        wins = safe[low:high] & (some | ~deciding)
        winning[low:high] = wins
        allowed[first:last] = onward & np.repeat(wins, counts)
    return winning, allowed


def _attractor(graph: ExploredGraph, safe: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`safety_game` on any graph: a safe state with choices loses once all its choices lead to
    losing states (the unsafe ones first), round by round until no state is added."""
    n = graph.n_states
    counts = np.diff(graph.choice_offsets)
    source = np.repeat(np.arange(n, dtype=np.int64), counts)
    target = graph.choice_target
    order = np.argsort(target, kind="stable")  # the choices into each state: a reverse adjacency
    into = np.searchsorted(target[order], np.arange(n + 1))
    losing = ~safe
    alive = np.bincount(source[safe[target]], minlength=n)  # choices to a state not (yet) losing
    fresh = np.flatnonzero(safe & (counts > 0) & (alive == 0))
    while fresh.size:
        losing[fresh] = True
        starts, ends = into[fresh], into[fresh + 1]
        sizes = ends - starts
        choices = order[np.repeat(starts - np.cumsum(sizes) + sizes, sizes) + np.arange(int(sizes.sum()))]
        sources = source[choices]
        np.subtract.at(alive, sources, 1)
        candidates = np.unique(sources)
        fresh = candidates[~losing[candidates] & (alive[candidates] == 0)]
    winning = ~losing
    return winning, winning[source] & winning[target]
