"""Breadth-first exploration of the model's state space, vectorised with numpy (issue 4).

:func:`explore` steps the whole frontier at once with the model's functions over arrays
(:class:`rac.model.batch.BatchModel`), merging duplicate states per layer, and produces an
:class:`rac.engine.graph.ExploredGraph`.

Example::

    graph = explore(data, horizon_samples=20, prune_unsafe=True)
    graph.labels["safe"], graph.states[graph.initial]
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from rac.core.numbers import INT32_MAX
from rac.engine.allow import ActionGuard, action_pairs
from rac.engine.budget import (
    GRAPH_BYTES_PER_CHOICE,
    GRAPH_BYTES_PER_STATE,
    Budget,
    BudgetExceeded,
    projected_states,
)
from rac.engine.evaluate import Frame
from rac.engine.graph import ExploredGraph
from rac.ir.vocabulary import EGO_STATE
from rac.model.batch import BatchModel, batch_model, distinct_values
from rac.model.data import ModelData
from rac.model.sample import ACTION, CRASHED, EGO, GRAPH_LAYER_ROW, LABELS, Ego, GraphColumn, collides
from rac.model.sample import labels as sample_labels

__all__ = ["COLUMNS", "GEOMETRY", "STICKY_COLUMNS", "Beam", "Geometry", "Stop", "action_pairs", "explore",
           "forgets_actions"]

#: The columns of :attr:`ExploredGraph.states` produced by :func:`explore`.
COLUMNS: tuple[str, ...] = ("k", *EGO_STATE)
#: ... under ``collision sticky``: one more, whether ``collide()`` held at this sample or before (0/1).
STICKY_COLUMNS: tuple[str, ...] = (*COLUMNS, "crashed")

Progress = Callable[[int, int, int], None]
#: ``stop_at(k, rows) -> (n,) bool``: the states of layer ``k`` (its rows as the graph stores them, without
#: the ``k`` column) at which :func:`explore` stops — a witness found, nothing more to build.
Stop = Callable[[int, np.ndarray], np.ndarray]
#: ``beam(k, rows) -> indices``: the states of layer ``k`` (rows as for :data:`Stop`) that :func:`explore`
#: keeps (distinct, ascending); the others are dropped with the choices leading to them.
Beam = Callable[[int, np.ndarray], np.ndarray]


def _unique_rows(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(rows, axis=0, return_inverse=True)`` of a 2-d integer array, faster.

    Rows are ordered lexicographically by their columns (signed), as ``np.unique`` orders them;
    here each row is packed into one int64 key that keeps that order (each column offset by its
    minimum, in mixed radix; a column whose span is too wide is first replaced by its rank among
    the column's distinct values). When even that does not fit in 62 bits, ``np.unique`` does
    the work. The inverse is int64."""
    n, width = rows.shape
    if n == 0:
        unique, inverse = np.unique(rows, axis=0, return_inverse=True)
        return unique, inverse.reshape(-1).astype(np.int64, copy=False)
    lows = [int(value) for value in rows.min(axis=0)]
    spans = [int(value) - low + 1 for value, low in zip(rows.max(axis=0), lows)]
    ranks: dict[int, np.ndarray] = {}
    unranked = sorted(range(width), key=spans.__getitem__)  # the widest last
    while math.prod(spans) >= 1 << 62:
        if not unranked:
            unique, inverse = np.unique(rows, axis=0, return_inverse=True)
            return unique, inverse.reshape(-1).astype(np.int64, copy=False)
        widest = unranked.pop()
        distinct, ranks[widest] = distinct_values(rows[:, widest])
        spans[widest] = len(distinct)
    key = np.zeros(n, dtype=np.int64)
    for column in range(width):  # key = key * span + digit, column by column: below 2**62
        key *= spans[column]
        key += ranks[column] if column in ranks else rows[:, column].astype(np.int64) - lows[column]
    order = np.argsort(key)
    ordered = key[order]
    first = np.empty(n, dtype=bool)
    first[0] = True
    np.not_equal(ordered[1:], ordered[:-1], out=first[1:])
    inverse = np.empty(n, dtype=np.int64)
    inverse[order] = np.cumsum(first, dtype=np.int64) - 1
    return rows[order[first]], inverse


# ---------------------------------------------------------------- exploration
#: How many successors a layer computes at a time: their sensing and merging need about 150 B each
#: (measured with tracemalloc), so a chunk's temporary arrays stay near 300 MB. Fewer chunks are
#: faster (a layer of a million successors: one chunk, no second merge).
CHUNK_ROWS = 1 << 21
#: The temporary bytes per successor row of a chunk.
CHUNK_BYTES_PER_ROW = 150


def _graph_bytes(states: int, choices: int) -> int:
    return states * GRAPH_BYTES_PER_STATE + choices * GRAPH_BYTES_PER_CHOICE


#: The model's functions of a state's position (what :class:`Geometry` computes): none reads the action
#: (jerk, turn) that led to the state, nor, under ``collision sticky``, its history.
GEOMETRY: dict[str, type] = {"offroad": bool, "mindist": float, "goal": bool, "dist_goal": float}


class Geometry:
    """The model's functions of position (:data:`GEOMETRY`) at one sample, on rows of ego columns (distinct
    positions; their jerk and turn are not read), each computed at most once per row and only for the
    rows asked for.

    Exploration keys a layer's successors by these rows before anything reads the model: the ``allow
    when`` rule, the sticky collision test and the labels then share one evaluation per distinct
    position, however many actions or histories lead there (issue 20: before, ``offroad`` ran on every
    successor for the rule and again for the labels)."""

    def __init__(self, model: BatchModel, rows: np.ndarray, k: int) -> None:
        self.model = model
        self.rows = rows
        self.k = k
        self._values: dict[str, np.ndarray] = {}
        self._known: dict[str, np.ndarray] = {}

    @property
    def n(self) -> int:
        return int(self.rows.shape[0])

    def _compute(self, name: str, rows: np.ndarray) -> np.ndarray:
        model, k = self.model, self.k
        if name == "offroad":
            return model.offroad(rows, k)
        if name == "mindist":
            return model.mindist(rows, k)
        if name == "goal":
            return model.goal(rows, k)
        if name == "dist_goal":
            return model.dist_goal(rows)
        raise KeyError(f"{name}() is not a function of the position")

    def __call__(self, name: str, index: np.ndarray) -> np.ndarray:
        """``name()`` of rows ``index`` (any order, repeats allowed), computing the rows not known yet."""
        values = self._values.get(name)
        if values is None:
            values = self._values[name] = np.zeros(self.n, dtype=GEOMETRY[name])
            self._known[name] = np.zeros(self.n, dtype=bool)
        known = self._known[name]
        todo = np.zeros(self.n, dtype=bool)
        todo[index] = True
        todo &= ~known
        count = int(np.count_nonzero(todo))
        if count == self.n:  # all of them: no copy of the rows
            values[:] = self._compute(name, self.rows)
            known[:] = True
        elif count:
            missing = np.flatnonzero(todo)
            values[missing] = self._compute(name, self.rows[missing])
            known[missing] = True
        return values[index]

    @staticmethod
    def merged(parts: list[Geometry]) -> tuple[Geometry, list[np.ndarray]]:
        """One geometry of the distinct rows of ``parts`` (of one sample), what any of them knew kept,
        and for each part its rows' index in it."""
        rows, inverse = _unique_rows(np.concatenate([part.rows for part in parts]))
        whole = Geometry(parts[0].model, rows, parts[0].k)
        bounds = np.cumsum([0, *(part.n for part in parts)])
        maps = [inverse[low:high] for low, high in zip(bounds[:-1], bounds[1:])]
        for name in {name for part in parts for name in part._values}:
            values = whole._values[name] = np.zeros(whole.n, dtype=GEOMETRY[name])
            known = whole._known[name] = np.zeros(whole.n, dtype=bool)
            for part, where in zip(parts, maps):
                if name in part._known:
                    have = part._known[name]
                    values[where[have]] = part._values[name][have]
                    known[where[have]] = True
        return whole, maps


def _ranks(values: np.ndarray) -> tuple[np.ndarray, int]:
    """Each value's rank among the distinct ``values`` (their order kept), and how many there are."""
    distinct, rank = distinct_values(values)
    return rank, len(distinct)


def _expand(model: BatchModel, sources: np.ndarray, pairs: np.ndarray | None, sample: int,
            check: Callable[[int], None], guard: ActionGuard | None = None, forget: bool = False,
            sticky: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, Geometry, np.ndarray]:
    """The distinct successors (at ``sample``) of ``sources`` (one per (jerk, turn) pair of ``pairs``, or
    one with their own actions when ``pairs`` is None) in lexicographic order, each kept choice's
    successor, which choices are kept (``guard``: the ``allow when`` rule; None keeps all), and the
    successors' :class:`Geometry` with each successor's row in it. With ``forget`` the successors' jerk
    and turn are set to 0 (after the rule read them), so that successors differing only in the action
    that led to them merge. With ``sticky`` rows carry the ``crashed`` column: the source's, or
    ``collide()`` of the successor.

    Where the rule or the collision test reads the successors before they merge, each chunk's
    successors are keyed by their position first (:func:`_by_position`), so that the model is read
    once per distinct position, and the labels later reuse it; otherwise the successors merge first
    and the labels read the model once per distinct successor.

    Successors are computed :data:`CHUNK_ROWS` at a time and merged as they come, so the memory
    beyond the result stays bounded; ``check(distinct)`` is called with the distinct successors
    found so far whenever they are merged (it raises to stop)."""
    per = 1 if pairs is None else len(pairs)
    step = max(1, CHUNK_ROWS // per)
    parts: list[tuple[np.ndarray, np.ndarray, Geometry]] = []  # distinct rows, their geometry rows, geometry
    inverses: list[np.ndarray] = []  # per chunk: each choice's row in the concatenation of parts
    kept: list[np.ndarray] = []
    merged_rows = pending = 0
    for start in range(0, sources.shape[0], step):
        block = sources[start:start + step]
        if pairs is None:
            chosen = block
        else:
            chosen = np.repeat(block, per, axis=0)
            chosen[:, ACTION] = np.tile(pairs, (block.shape[0], 1))
        moved = model.sense(chosen[:, EGO])
        if guard is None and not sticky:  # nothing reads the model before the successors merge
            kept.append(np.ones(chosen.shape[0], dtype=bool))
            if forget:
                moved[:, ACTION] = 0
            rows, inverse = _unique_rows(moved)  # the geometry reads the rows themselves (not their jerk, turn)
            part = (rows, np.arange(rows.shape[0], dtype=np.int64), Geometry(model, rows, sample))
        else:
            part, inverse = _by_position(model, chosen, moved, sample, guard, forget, kept)
        inverses.append(inverse + merged_rows + pending)
        parts.append(part)
        pending += part[0].shape[0]
        if pending > max(merged_rows, CHUNK_ROWS):  # merge: memory stays within twice the distinct rows
            parts = [_merge(parts, inverses)]
            merged_rows, pending = parts[0][0].shape[0], 0
            check(merged_rows)
    if not parts:
        return (np.zeros((0, sources.shape[1]), dtype=np.int32), np.zeros(0, dtype=np.int64),
                np.zeros(0, dtype=bool), Geometry(model, np.zeros((0, 7), dtype=np.int32), sample),
                np.zeros(0, dtype=np.int64))
    if len(parts) > 1:
        parts = [_merge(parts, inverses)]
    rows, where, geometry = parts[0]
    check(rows.shape[0])
    return np.ascontiguousarray(rows, dtype=np.int32), np.concatenate(inverses), np.concatenate(kept), geometry, where


def _by_position(model: BatchModel, chosen: np.ndarray, moved: np.ndarray, sample: int, guard: ActionGuard | None,
                 forget: bool, kept: list[np.ndarray]) -> tuple[tuple[np.ndarray, np.ndarray, Geometry], np.ndarray]:
    """:func:`_expand` of one chunk whose successors ``moved`` (of the rows ``chosen``) are read before
    they merge (the ``allow when`` rule, the sticky collision when ``chosen`` has the ``crashed``
    column): ``(distinct rows, their geometry rows, geometry)`` and each kept choice's row; the chunk's
    kept mask is appended to ``kept``. The successors are keyed by position first, so that the model is
    read once per distinct position; the distinct rows are then found from that key's rank and the few
    other columns, in the order ``np.unique`` gives the rows."""
    key = moved.copy()
    key[:, ACTION] = 0
    places, where = _unique_rows(key)
    del key
    geometry = Geometry(model, np.ascontiguousarray(places, dtype=np.int32), sample)
    sticky = chosen.shape[1] > moved.shape[1]
    crashed = collides(geometry("mindist", where), model.native.td_d, chosen[:, CRASHED] != 0) if sticky else None
    if guard is not None:
        frame = Frame(k=np.full(moved.shape[0], sample, dtype=np.int64), ego=moved,
                      functions=lambda name: geometry(name, where))
        allowed = guard.allowed_in(frame)
        kept.append(allowed)
        moved, where = moved[allowed], where[allowed]
        crashed = crashed[allowed] if crashed is not None else None
    else:
        kept.append(np.ones(chosen.shape[0], dtype=bool))
    # the distinct successors: by position (rank `where`), then jerk, turn and crashed, as the rows sort
    code, span = np.zeros(moved.shape[0], dtype=np.int64), 1
    if not forget:
        for column in (Ego.JERK, Ego.TURN):
            rank, count = _ranks(moved[:, column])
            code, span = code * count + rank, span * count
    if crashed is not None:
        code, span = code * 2 + crashed, span * 2
    distinct, inverse = distinct_values(where * span + code)
    rows = np.empty((distinct.size, moved.shape[1] + (crashed is not None)), dtype=np.int32)
    rows[inverse, EGO] = moved
    if forget:
        rows[:, ACTION] = 0
    if crashed is not None:
        rows[inverse, CRASHED] = crashed
    return (rows, distinct // span, geometry), inverse


def _merge(parts: list[tuple[np.ndarray, np.ndarray, Geometry]],
           inverses: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, Geometry]:
    """One distinct, ordered array of the rows of ``parts``, with their geometry merged; ``inverses``
    are rewritten in place to index it."""
    rows, inverse = _unique_rows(np.concatenate([part[0] for part in parts]))
    for i, old in enumerate(inverses):
        inverses[i] = inverse[old]
    geometry, maps = Geometry.merged([part[2] for part in parts])
    where = np.empty(rows.shape[0], dtype=np.int64)
    where[inverse] = np.concatenate([places[part[1]] for places, part in zip(maps, parts)])
    return rows, where, geometry


def forgets_actions(k: int | np.ndarray, decide_every: int, horizon_samples: int) -> np.ndarray:
    """Where :func:`explore` with ``forget_actions=True`` holds jerk and turn as 0: at decision samples
    (the action is chosen anew before anything reads it) and at the horizon (nothing follows)."""
    k = np.asarray(k)
    return (k % decide_every == 0) | (k == horizon_samples)


def _trim(frontier: np.ndarray, inverse: np.ndarray, kept: np.ndarray,
          rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The layer ``frontier`` cut to its ``rows``: the kept rows, each surviving choice's row among them,
    and which choices are kept (those leading to a dropped row are no longer)."""
    remap = np.full(frontier.shape[0], -1, dtype=np.int64)
    remap[rows] = np.arange(rows.size, dtype=np.int64)
    inverse = remap[inverse]
    survives = inverse >= 0
    kept = kept.copy()
    kept[np.flatnonzero(kept)[~survives]] = False
    return np.ascontiguousarray(frontier[rows]), inverse[survives], kept


def explore(data: ModelData, *, horizon_samples: int | None = None, prune_unsafe: bool = False,
            progress: Progress | None = None, max_states: int | None = None,
            max_bytes: int | None = None, forget_actions: bool = False,
            stop_at: Stop | None = None, beam: Beam | None = None) -> ExploredGraph:
    """Explore every state reachable from the ego's start, breadth-first, one sample per layer.

    A state is ``(k, x, y, v, acc, head, jerk, turn)`` (:data:`COLUMNS`; int32); state 0 is the
    start ``(0, ego..., 0, 0)``. At a decision sample (``k % decide_every == 0``) a state has one
    choice per (jerk, turn) pair (action index as in :func:`action_pairs`); at other samples one
    choice, action ``-1``, keeping its jerk and turn. The successor of a choice is ``sense()`` of
    the state with the chosen actions, at ``k + 1``. Each layer's successors are merged
    (``np.unique`` over rows; states at different samples never coincide, so this merges every
    duplicate). States at ``k == horizon_samples`` are terminal. Under the model's ``allow when``
    (:class:`rac.engine.allow.ActionGuard`) a decision state has only its allowed choices; one with
    none is terminal (the run stops there, as the emitted model deadlocks).

    ``horizon_samples`` defaults to the goal interval's last sample (``goal()`` is false ever
    after); ``ValueError`` when that is unbounded. With ``prune_unsafe=True`` states that collide
    or are off-road are also terminal (not expanded): enough for ``E[] safe``, ``E<> safe && goal``
    and the safety shield, and far smaller; their choices are then absent, so a consumer must not
    read a terminal state before the horizon as "the run ends safely".

    ``forget_actions=True`` merges states that differ only in the action that led to them where that
    action is never read again (:func:`forgets_actions`: at decision samples, where the next choice
    replaces it before ``sense()`` runs, and at the horizon): their jerk and turn are held as 0. The
    labels do not read them and the ``allow when`` rule reads them before they are forgotten, so
    every label, choice and successor is unchanged — only the count of states (on CommonUppRoad's
    ZAM_Ramp, by half). A consumer must then not read those states' jerk and turn (a query over
    ``jerk``/``turn``, a trace printing them) and must look them up with the same two columns at 0
    (:class:`rac.engine.shield.ShieldTable` does, given ``forget_every``).

    Under ``collision sticky`` (:attr:`ModelData.sticky`) a state has one more column, ``crashed``
    (:data:`STICKY_COLUMNS`): whether ``collide()`` held at its sample or an earlier one of its run —
    the ``collide`` label. States reached with and without a collision on the way stay apart.

    Labels (``(n,)`` bool): ``collide``, ``offroad``, ``goal``, ``safe`` (``!collide && !offroad``).
    The model's functions of position are read once per distinct position of a layer
    (:class:`Geometry`): the ``allow when`` rule, the sticky collision test and the labels share it.
    ``progress(layer, frontier_size, total_states)`` is called once per explored layer.

    Searching rather than building (:mod:`rac.engine.witness`): ``stop_at`` (:data:`Stop`) is asked
    about each layer as soon as it is built; when it marks a state the exploration stops there, that
    layer's states without choices. ``beam`` (:data:`Beam`) chooses which states of each new layer
    are kept. A graph stopped early or cut by the beam has :attr:`ExploredGraph.complete` False: its
    terminal states are not the model's, and no query may be decided "no" on it.

    Budgets (:mod:`rac.engine.budget`): :class:`~rac.engine.budget.BudgetExceeded` (a ``MemoryError``)
    as soon as more than ``max_states`` states have been found, or when deciding a query on the
    graph would need more than ``max_bytes`` — checked before a layer is expanded and while it is
    merged: a layer is expanded :data:`CHUNK_ROWS` successors at a time, so the memory a layer needs
    beyond the graph stays bounded, and an exploration stops before it allocates what exceeds the budget.
    """
    if horizon_samples is None:
        if data.goal_high >= INT32_MAX:
            raise ValueError("explore() needs horizon_samples: the goal's time interval is unbounded")
        horizon_samples = data.goal_high
    if horizon_samples < 0:
        raise ValueError(f"horizon_samples must be >= 0, not {horizon_samples}")
    model = batch_model(data)
    native = model.native
    guard = ActionGuard(data)
    pairs = action_pairs(data)
    n_pairs = len(pairs)
    budget = Budget(max_states, max_bytes, "the model", float(data.period))
    start = np.asarray([native.initial_state()], dtype=np.int32)
    sticky = data.sticky
    # ego columns of layer k; under `collision sticky` one more: collide() held at this sample or before
    frontier = np.column_stack([start, model.collide(start, 0)]).astype(np.int32) if sticky else start
    # the frontier's positions: the model's functions on them, shared with the rule that made them
    place = start.copy()
    place[:, ACTION] = 0
    geometry, where = Geometry(model, place, 0), np.zeros(1, dtype=np.int64)
    td = native.td_d
    columns = STICKY_COLUMNS if sticky else COLUMNS
    layers: list[np.ndarray] = []
    counts: list[np.ndarray] = []  # choices per state
    actions: list[np.ndarray] = []
    targets: list[np.ndarray] = []
    labels: dict[str, list[np.ndarray]] = {name: [] for name in LABELS}
    total = choices = 0
    complete = True  # False once a layer is cut by the beam or the search stops before the horizon
    try:
        for k in range(horizon_samples + 1):
            size = frontier.shape[0]
            layers.append(frontier)
            collide = frontier[:, CRASHED] != 0 if sticky else collides(geometry("mindist", where), td)
            layer_labels = sample_labels(collide, geometry("offroad", where), geometry("goal", where))
            for name, mask in layer_labels.items():
                labels[name].append(mask)
            safe = layer_labels["safe"]
            base = total + size  # index of the next layer's first state
            total = base
            if progress is not None:
                progress(k, size, total)
            budget.check_states(total, k)
            witnessed = stop_at is not None and bool(np.any(stop_at(k, frontier)))
            if k == horizon_samples or witnessed:
                counts.append(np.zeros(size, dtype=np.int64))
                complete = complete and k == horizon_samples
                break
            expand = safe if prune_unsafe else np.ones(size, dtype=bool)
            sources = frontier[expand]
            decide = k % data.decide_every == 0
            per_state = n_pairs if decide else 1
            # Before anything is allocated: the graph with this layer's choices and, at most, one new
            # state per choice must leave room to decide a query on it.
            choices += sources.shape[0] * per_state
            budget.check_bytes(_graph_bytes(total + sources.shape[0] * per_state, choices), total, k + 1,
                               min(sources.shape[0] * per_state, CHUNK_ROWS) * CHUNK_BYTES_PER_ROW)
            action = (np.tile(np.arange(n_pairs, dtype=np.int64), sources.shape[0]) if decide
                      else np.full(sources.shape[0], -1, dtype=np.int64))
            found = total  # the states before this layer's successors

            def check(distinct: int) -> None:
                budget.check_states(found + distinct, k + 1)  # noqa: B023 - called within this iteration

            restricted = decide and guard.restricts
            forget = forget_actions and bool(forgets_actions(k + 1, data.decide_every, horizon_samples))
            frontier, inverse, kept, geometry, where = _expand(model, sources, pairs if decide else None, k + 1,
                                                               check, guard if restricted else None, forget, sticky)
            if beam is not None and frontier.shape[0]:
                rows = np.asarray(beam(k + 1, frontier), dtype=np.int64)
                if rows.size < frontier.shape[0]:
                    frontier, inverse, kept = _trim(frontier, inverse, kept, rows)
                    where = where[rows]
                    restricted, complete = True, False  # some choices now lead nowhere: dropped
            choices -= kept.size - int(kept.sum())  # the disallowed choices are not in the graph
            count = np.zeros(size, dtype=np.int64)
            count[expand] = kept.reshape(-1, per_state).sum(axis=1) if restricted else per_state
            counts.append(count)
            actions.append(action[kept] if restricted else action)
            targets.append(base + inverse)
            if frontier.shape[0] == 0:
                break
    except BudgetExceeded as exc:
        # how far the horizon is, at the growth seen so far: which settings to change, and how much
        estimate = projected_states([layer.shape[0] for layer in layers], data.decide_every, horizon_samples)
        if estimate is not None and estimate[0] > exc.states:
            exc.project(*estimate, horizon_samples)
        raise
    states = np.empty((sum(layer.shape[0] for layer in layers), len(columns)), dtype=np.int32)
    row = 0
    for k, layer in enumerate(layers):
        states[row:row + layer.shape[0], GraphColumn.K] = k
        states[row:row + layer.shape[0], GRAPH_LAYER_ROW] = layer
        row += layer.shape[0]
    offsets = np.zeros(states.shape[0] + 1, dtype=np.int64)
    np.cumsum(np.concatenate(counts), out=offsets[1:])
    return ExploredGraph(
        states=states, columns=columns, choice_offsets=offsets,
        choice_action=np.concatenate(actions) if actions else np.zeros(0, dtype=np.int64),
        choice_target=np.concatenate(targets) if targets else np.zeros(0, dtype=np.int64),
        initial=0, labels={name: np.concatenate(masks) for name, masks in labels.items()}, complete=complete,
        forget_every=int(data.decide_every) if forget_actions else 0, model=data.digest)
