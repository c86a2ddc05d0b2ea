"""Handing an explored graph to Storm: verdicts for E<>, E[], A[], A<>; the permissive safety shield.

The shield (:func:`safety_shield`) is solved without Storm, by a backward pass over the graph's
layers (:mod:`rac.engine.layered`); :func:`safety_shield_storm` reads it from Storm, the oracle the
tests compare it with.

The graph (``ExploredGraph``) becomes a Storm MDP with one row group per state and one row per
choice (probability 1 to its single successor). Terminal states (the horizon) get one self-loop
row, since Storm needs every state to have a choice; they carry the label ``"terminal"``. Runs
are the maximal paths of the graph, so a run ending in a terminal state is, for Storm, that path
followed by the terminal state forever: ``G p`` over the self-loop holds exactly when the
terminal state satisfies p itself.

Choices are deterministic, so every probability Storm computes here is 0 or 1: ``Pmax F p`` is
1 exactly where some path reaches p, ``Pmax G p`` is 1 exactly where some run keeps p forever.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np
import stormpy
from stormpy import datastructures as sd
from stormpy import models as sm

from rac.engine.graph import ExploredGraph
from rac.engine.layered import safety_game

#: Labels ``to_mdp`` adds itself; the graph's own labels must not use them.
RESERVED_LABELS = ("init", "terminal")
KINDS = ("E<>", "E[]", "A[]", "A<>")


def _row_layout(graph: ExploredGraph) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Storm's row layout: (row group starts (n,), row of each graph choice (m,), terminal mask (n,))."""
    terminal = graph.terminal()
    extra_before = np.cumsum(terminal) - terminal  # self-loop rows inserted before each state
    group_starts = graph.choice_offsets[:-1] + extra_before
    counts = np.diff(graph.choice_offsets)
    choice_rows = np.arange(graph.n_choices, dtype=np.int64) + np.repeat(extra_before, counts)
    return group_starts.astype(np.int64), choice_rows, terminal


def bit_vector(mask: np.ndarray) -> sd.BitVector:
    """Storm's ``BitVector`` of a boolean mask, from its packed bits (Storm's text form: the length,
    then 64-bit buckets, most significant bit first) — not from a Python list of set indices, which
    costs ~50 bytes per set bit and three times the time."""
    mask = np.asarray(mask, dtype=bool).reshape(-1)
    padded = np.zeros(-(-mask.size // 64) * 64, dtype=bool)
    padded[:mask.size] = mask
    buckets = np.frombuffer(np.packbits(padded, bitorder="big").tobytes(), dtype=">u8")
    return sd.BitVector.load_from_string(f"{mask.size}" + "".join(f" {bucket}" for bucket in buckets.tolist()))


def to_mdp(graph: ExploredGraph) -> sm.SparseMdp:
    """The graph as a Storm ``SparseMdp[float]``, built from numpy arrays in one builder call.

    Labels: every ``graph.labels`` entry, ``"init"`` (the initial state) and ``"terminal"``.
    Row ``choice_rows[c]`` of the matrix is graph choice ``c`` (see ``_row_layout``).
    """
    for name in RESERVED_LABELS:
        if name in graph.labels:
            raise ValueError(f"label {name!r} is reserved")
    n = graph.n_states
    group_starts, choice_rows, terminal = _row_layout(graph)
    n_rows = graph.n_choices + int(terminal.sum())
    cols = np.empty(n_rows, dtype=np.int64)
    cols[choice_rows] = graph.choice_target
    terminal_states = np.flatnonzero(terminal)
    cols[group_starts[terminal_states]] = terminal_states
    builder = sd.SparseMatrixBuilder[float](rows=n_rows, columns=n, entries=n_rows, force_dimensions=True,
                                             has_custom_row_grouping=True, row_groups=n)
    # One entry per row, rows in order: no duplicate (row, col) pairs, and no empty trailing group.
    builder.add_next_values(np.arange(n_rows, dtype=np.int64), cols, np.ones(n_rows), group_starts)
    matrix = builder.build()

    labeling = sm.StateLabeling(n)
    masks = {**graph.labels, "init": np.arange(n) == graph.initial, "terminal": terminal}
    for name, mask in masks.items():
        labeling.add_label(name)
        labeling.set_states(name, bit_vector(mask))
    components = sm.SparseModelComponents(transition_matrix=matrix, state_labeling=labeling)
    return sm.SparseMdp[float](components)


@dataclass(frozen=True)
class Verdict:
    """A query's answer. ``trace`` (state indices from the initial state) is, when present:
    E<> p holds: a path to a p-state; A[] p fails: a path to a !p-state; E[] p holds: a path
    staying in p to a terminal state; A<> p fails: a path staying in !p to a terminal state.
    On a graph with cycles an E[]-trace may instead end by revisiting one of its states (a lasso)."""

    query: str
    holds: bool
    n_states: int
    n_choices: int
    seconds: float
    trace: list[int] | None = None


def check_formula(mdp: sm.SparseMdp, formula: str) -> tuple[np.ndarray, object]:
    """Storm's value vector (all states) and scheduler for ``formula`` (a PRISM-syntax property)."""
    prop = stormpy.parse_properties(formula)[0]
    result = stormpy.model_checking(mdp, prop, only_initial_states=False, extract_scheduler=True)
    return np.asarray(result.get_value_vector(), dtype=float), result.get_scheduler()


def _scheduler_trace(graph: ExploredGraph, scheduler: Any, good: np.ndarray, stop: np.ndarray) -> list[int] | None:
    """Follow Storm's scheduler from the initial state while in ``good``, until a ``stop`` state
    (included), a terminal state or a repeated state; None when the path leaves ``good``."""
    state, path, seen = graph.initial, [], set()
    while True:
        if not good[state]:
            return None
        path.append(state)
        if stop[state] or state in seen or graph.choice_offsets[state] == graph.choice_offsets[state + 1]:
            return path
        seen.add(state)
        local = scheduler.get_choice(state).get_deterministic_choice()
        state = int(graph.choice_target[graph.choice_offsets[state] + local])


def _bfs_trace(graph: ExploredGraph, allowed: np.ndarray, goal: np.ndarray) -> list[int] | None:
    """A shortest path from the initial state to a ``goal`` state through ``allowed`` states."""
    start = graph.initial
    if not allowed[start]:
        return None
    parent = {start: -1}
    queue = deque([start])
    while queue:
        state = queue.popleft()
        if goal[state]:
            path = [state]
            while parent[path[-1]] >= 0:
                path.append(parent[path[-1]])
            return path[::-1]
        for c in graph.choices(state):
            nxt = int(graph.choice_target[c])
            if allowed[nxt] and nxt not in parent:
                parent[nxt] = state
                queue.append(nxt)
    return None


@dataclass(frozen=True)
class SafeReach:
    """What ``E<> target`` means on a pruned graph (unsafe states end a run there): ``until`` — a
    run that stays safe until it reaches ``target`` exists (the verdict, with a trace); and
    ``to_horizon`` — one of those stays safe to the horizon too. ``rac verify``'s Qc message,
    ``rac preanalyse``'s Qc columns and ``rac experiment``'s safety judgement read these two."""

    until: Verdict
    to_horizon: bool


def safe_reach(pruned: ExploredGraph, target: np.ndarray, safe_label: str = "safe") -> SafeReach:
    """:class:`SafeReach` of the states ``target`` on the complete graph ``pruned`` (``safe_label``
    marks the safe states; the graph's unsafe states are terminal, as :func:`rac.engine.explore.explore`
    leaves them with ``prune_unsafe=True``), read from the graph rather than asked of Storm: a target
    state it reaches (one of the earliest sample: the trace is a shortest one), and whether one of
    them wins the safety game (:func:`rac.engine.layered.safety_game`: Storm's ``Pmax G safe = 1``).
    ``ValueError`` for a graph that is not complete (it proves no "no")."""
    if not pruned.complete:
        raise ValueError("safe_reach needs a complete graph: an exploration stopped early proves no absence")
    t0 = time.perf_counter()
    # on the pruned graph every reachable state is reached through safe states only
    reached = target & pruned.reachable()
    hits = np.flatnonzero(reached)
    trace = pruned.path_to(int(hits[0])) if hits.size else None
    until = Verdict("E<> target", bool(hits.size), pruned.n_states, pruned.n_choices, time.perf_counter() - t0, trace)
    if not until.holds:
        return SafeReach(until, False)
    winning, _ = safety_game(pruned, pruned.labels[safe_label])
    return SafeReach(until, bool(np.any(reached & winning)))


def decide(graph: ExploredGraph, kind: str, prop_label: str) -> Verdict:
    """Decide ``kind prop_label`` (kind one of E<>, E[], A[], A<>) at the initial state with Storm.

    E<> p = Pmax F p > 0; A[] p = not E<> !p; E[] p = Pmax G p > 0 (runs end at terminal states,
    which self-loop); A<> p = not E[] !p. Values are 0 or 1 (deterministic choices).
    """
    if kind not in KINDS:
        raise ValueError(f"unknown query kind {kind!r}; expected one of {KINDS}")
    if prop_label not in graph.labels:
        raise KeyError(f"no state label {prop_label!r}")
    t0 = time.perf_counter()
    mdp = to_mdp(graph)
    p = graph.labels[prop_label]
    negate = kind in ("A[]", "A<>")
    target = ~p if negate else p
    atom = f'!"{prop_label}"' if negate else f'"{prop_label}"'
    if kind in ("E<>", "A[]"):
        values, scheduler = check_formula(mdp, f"Pmax=? [F {atom}]")
        reachable = values > 0.5
        exists = bool(reachable[graph.initial])
        trace = None
        if exists:
            trace = _scheduler_trace(graph, scheduler, reachable, target)
            if trace is None or not target[trace[-1]]:
                trace = _bfs_trace(graph, reachable, target)
    else:
        values, scheduler = check_formula(mdp, f"Pmax=? [G {atom}]")
        winning = values > 0.5
        exists = bool(winning[graph.initial])
        trace = None
        if exists:
            trace = _scheduler_trace(graph, scheduler, winning, np.zeros(graph.n_states, dtype=bool))
            if trace is None:
                trace = _bfs_trace(graph, winning, graph.terminal())
    holds = not exists if negate else exists
    return Verdict(f"{kind} {prop_label}", holds, graph.n_states, graph.n_choices, time.perf_counter() - t0, trace)


@dataclass(frozen=True)
class Shield:
    """The most permissive strategy for ``control: A[] safe``.

    ``winning`` (n,) marks the states from which some run stays safe to the horizon;
    ``allowed_choices`` (m,) marks, in winning states, the choices whose successor is winning."""

    graph: ExploredGraph
    winning: np.ndarray
    allowed_choices: np.ndarray
    seconds: float

    @property
    def shield_exists(self) -> bool:
        """The initial state is winning: the strategy exists."""
        return bool(self.winning[self.graph.initial])

    def allowed(self, state: int) -> np.ndarray:
        """The action indices (``choice_action``) allowed in ``state``; empty in losing or terminal states."""
        choices = slice(int(self.graph.choice_offsets[state]), int(self.graph.choice_offsets[state + 1]))
        return self.graph.choice_action[choices][self.allowed_choices[choices]]


def safety_shield(graph: ExploredGraph, safe_label: str) -> Shield:
    """The permissive safety shield of ``control: A[] safe_label``: the winning states and allowed
    choices of :func:`rac.engine.layered.safety_game` (a backward pass over the graph's layers, no
    Storm model built), the same as :func:`safety_shield_storm`'s on every graph."""
    if safe_label not in graph.labels:
        raise KeyError(f"no state label {safe_label!r}")
    t0 = time.perf_counter()
    winning, allowed = safety_game(graph, graph.labels[safe_label])
    return Shield(graph, winning, allowed, time.perf_counter() - t0)


def safety_shield_storm(graph: ExploredGraph, safe_label: str) -> Shield:
    """:func:`safety_shield` read from Storm's ``Pmax=? [G "safe"]`` value vector (the oracle of the tests).

    A state is winning when its value is 1; a choice is allowed when its state and its (only)
    successor are winning — one vectorised pass over the choice arrays.
    """
    if safe_label not in graph.labels:
        raise KeyError(f"no state label {safe_label!r}")
    t0 = time.perf_counter()
    values, _ = check_formula(to_mdp(graph), f'Pmax=? [G "{safe_label}"]')
    winning = values > 1.0 - 1e-9
    source = np.repeat(np.arange(graph.n_states), np.diff(graph.choice_offsets))
    allowed = winning[source] & winning[graph.choice_target]
    return Shield(graph, winning, allowed, time.perf_counter() - t0)


def uniform_reach_probability(graph: ExploredGraph, label: str) -> float:
    """The probability, from the initial state, of eventually reaching a ``label`` state when each
    state takes each of its choices with equal probability — what SMC estimates with actions drawn
    uniformly (:func:`rac.engine.simulate.simulate`).

    The graph becomes a Storm DTMC: state ``i`` with ``c`` choices moves to each choice's target
    with probability ``1/c`` (choices sharing a target are summed into one entry); a terminal
    state loops on itself. Storm then checks ``P=? [F "label"]``.
    """
    if label not in graph.labels:
        raise KeyError(f"no state label {label!r}")
    if label in RESERVED_LABELS:
        raise ValueError(f"label {label!r} is reserved")
    n = graph.n_states
    counts = np.diff(graph.choice_offsets)
    sources = np.repeat(np.arange(n, dtype=np.int64), counts)
    probabilities = 1.0 / np.repeat(counts, counts)
    terminal = np.flatnonzero(counts == 0)
    rows = np.concatenate([sources, terminal])
    cols = np.concatenate([graph.choice_target, terminal])
    # merge duplicate (row, col) entries: Storm's builder rejects them; keys sort row-major
    keys, inverse = np.unique(rows * n + cols, return_inverse=True)
    values = np.bincount(inverse.reshape(-1), weights=np.concatenate([probabilities, np.ones(terminal.size)]))
    builder = sd.SparseMatrixBuilder[float](rows=n, columns=n, entries=keys.size, force_dimensions=True)
    builder.add_next_values(keys // n, keys % n, values)
    labeling = sm.StateLabeling(n)
    for name, mask in ((label, graph.labels[label]), ("init", np.arange(n) == graph.initial)):
        labeling.add_label(name)
        labeling.set_states(name, bit_vector(mask))
    dtmc = sm.SparseDtmc[float](sm.SparseModelComponents(transition_matrix=builder.build(), state_labeling=labeling))
    prop = stormpy.parse_properties(f'P=? [F "{label}"]')[0]
    result = stormpy.model_checking(dtmc, prop, only_initial_states=True)
    return float(result.get_value(graph.initial))
