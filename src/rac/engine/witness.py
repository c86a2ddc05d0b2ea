"""Looking for one run instead of building them all (issue 20): the witness searches that come before
an exhaustive exploration, and the replay that checks a witness before it is reported.

A *witness* is a run of the model from the ego's start (:class:`Witness`) whose states before the last
satisfy ``through`` and whose last state satisfies ``target`` (both :data:`Predicate`): a run reaching
``q`` for ``E<> q`` and the counterexample of ``A[] !q``; a run staying in ``p`` to the horizon for
``E[] p`` and the counterexample of ``A<> !p``. With ``prune_unsafe`` the states before the last must
also be safe (the pruned model of :func:`rac.engine.explore.explore`). Three searches, cheapest first:

- :func:`random_runs`: runs stepped together in one numpy batch, each decision drawn uniformly among
  the allowed actions (seeded); a run ends at its first state outside ``through``;
- :func:`beam_search`: :func:`~rac.engine.explore.explore` layer by layer keeping the ``width``
  states of each layer that score best (:func:`goal_distance`: nearest the goal; ties broken at
  random, seeded), stopping at the first layer with a target state;
- :func:`layered_search`: :func:`~rac.engine.explore.explore` of every state, stopping at the first
  layer with a target state — within the exploration's budget.

The first two are bounded (:class:`Bounds`: runs, the beam's width and states, a work budget that is
the same on every machine, so that the same seed finds the same witness anywhere; a time limit far
beyond that work is only a safety net, and :attr:`Found.timed_out` says when it cut a search) and
never prove that no witness exists; an exploration proves it only when it completes
(:attr:`ExploredGraph.complete`): a beam that never had to drop a state is such an exploration.
:func:`replay` runs a witness again with the scalar model (:class:`rac.model.native.NativeModel`)
before it is reported; a mismatch is a bug in rac (:class:`ReplayMismatch`).

Example::

    found = search(data, target, horizon_samples=140, prune_unsafe=True, seed=1)
    if found.witness is not None:
        replay(data, found.witness, target, prune_unsafe=True)
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rac.core.diagnostics import RacError
from rac.engine.allow import ActionGuard, action_pairs
from rac.engine.budget import Budget, BudgetExceeded
from rac.engine.explore import COLUMNS, STICKY_COLUMNS, Progress, explore
from rac.engine.graph import ExploredGraph
from rac.model.batch import BatchModel, batch_model
from rac.model.data import ModelData
from rac.model.native import NativeModel
from rac.model.sample import ACTION, CRASHED, EGO, GRAPH_EGO, GRAPH_LAYER_ROW, GraphColumn, safe
from rac.model.sample import labels as sample_labels

__all__ = ["SAFETY_SECONDS", "Bounds", "Found", "Predicate", "ReplayMismatch", "Witness", "beam_search",
           "goal_distance", "layered_search", "planned_runs", "random_runs", "replay", "safe_states", "search",
           "witness_along", "witness_graph", "witness_in"]

#: ``predicate(k, rows) -> (n,) bool`` over states of sample ``k``: ``rows`` as
#: :func:`rac.engine.explore.explore` stores them, without ``k`` (the ego columns; ``crashed`` too under
#: ``collision sticky``).
Predicate = Callable[[int, np.ndarray], np.ndarray]
#: ``score(k, rows) -> (n,) float``: lower is better (the beam keeps the lowest).
Score = Callable[[int, np.ndarray], np.ndarray]

#: The random runs stepped together in one batch.
RUN_BATCH = 1000


#: The witness search's safety net (seconds): far beyond what its work budget takes on any machine rac
#: runs on (its 4 million states take well under a minute), so that the budget, not the speed, ends it.
SAFETY_SECONDS = 300.0


@dataclass(frozen=True)
class Bounds:
    """What the cheap witness searches (:func:`search`) may spend: ``runs`` random runs and a beam of
    ``width`` states per layer, each search at most ``max_states`` states — a budget of work, so that
    what they find depends on the seed alone. ``safety_seconds`` (None: none) is only a safety net
    against a machine far slower than expected; where it cuts a search, :attr:`Found.timed_out` says
    so and the outcome depends on the machine's speed. ``runs`` or ``width`` 0 leaves that search out.
    ``max_bytes`` (None: none) is the memory the beam's graph, and a batch of random runs, may take
    (``--max-memory``): the work budget alone lets the beam grow to some 150 MB; where the memory cuts
    a search, :attr:`Found.out_of_memory` says so."""

    runs: int = 2000
    width: int = 5000
    safety_seconds: float | None = SAFETY_SECONDS
    max_states: int = 2_000_000
    max_bytes: int | None = None


@dataclass(frozen=True)
class Witness:
    """A run of the model: ``states`` ``(T + 1, d)`` int32 in ``columns`` (``k`` first, then
    :data:`rac.engine.explore.COLUMNS`' ego columns, ``crashed`` under ``collision sticky``), from sample
    0; ``actions`` ``(T,)``: the action index (row of :func:`rac.engine.allow.action_pairs`) chosen at
    each sample, -1 between decisions. ``search`` says which search found it (``"random runs"``,
    ``"beam"``, ``"breadth-first"``)."""

    states: np.ndarray
    columns: tuple[str, ...]
    actions: np.ndarray
    search: str

    @property
    def last(self) -> np.ndarray:
        """The last state's row without ``k``."""
        return self.states[-1, GRAPH_LAYER_ROW]

    @property
    def samples(self) -> int:
        """The sample of the last state."""
        return int(self.states[-1, GraphColumn.K])


@dataclass(frozen=True)
class Found:
    """What a search found: the ``witness`` (None: none), the ``states`` it generated, and — for the
    searches that explore — the ``graph`` they built (``graph.complete``: every state was explored,
    so without a witness none exists); ``timed_out``: stopped by its time limit (the safety net, or a
    deadline the caller set), not by its work budget; ``out_of_memory``: stopped by its memory limit
    (:attr:`Bounds.max_bytes`); ``runs``: the random runs :func:`random_runs` started (fewer than asked
    where a limit or a witness stopped them, none where not one fitted in the memory), 0 for the other
    searches."""

    witness: Witness | None
    states: int
    graph: ExploredGraph | None = None
    timed_out: bool = False
    out_of_memory: bool = False
    runs: int = 0

    @property
    def proves_absence(self) -> bool:
        """No witness, and the search's graph is complete: no run is a witness."""
        return self.witness is None and self.graph is not None and self.graph.complete


class ReplayMismatch(RacError, RuntimeError):
    """A witness that the scalar model does not reproduce: an internal error (a bug in rac)."""


class _OutOfTime(RacError):
    """Raised inside an exploration when a search's time is up."""


def _columns(data: ModelData) -> tuple[str, ...]:
    return STICKY_COLUMNS if data.sticky else COLUMNS


def start_row(data: ModelData, model: BatchModel) -> np.ndarray:
    """The start's row (without ``k``), as exploration and the witness searches begin: the ego, and under
    ``collision sticky`` whether ``collide()`` holds there."""
    start = np.asarray([model.native.initial_state()], dtype=np.int32)
    if data.sticky:
        start = np.column_stack([start, model.collide(start, 0)]).astype(np.int32)
    return start[0]


def safe_states(data: ModelData, k: int, rows: np.ndarray) -> np.ndarray:
    """``!collide() && !offroad()`` (the ``safe`` label) on rows of sample ``k`` (a :data:`Predicate`)."""
    model = batch_model(data)
    collide = rows[:, CRASHED] != 0 if data.sticky else model.collide(rows[:, EGO], k)
    return safe(collide, model.offroad(rows[:, EGO], k))


def goal_distance(data: ModelData) -> Score:
    """The beam's default score: ``dist_goal()``, the distance from the goal region's centre."""
    model = batch_model(data)
    return lambda k, rows: model.dist_goal(rows[:, EGO])


# ---------------------------------------------------------------- random runs
def random_runs(data: ModelData, target: Predicate, *, horizon_samples: int, runs: int, seed: int,
                through: Predicate | None = None, prune_unsafe: bool = False, deadline: float | None = None,
                start: tuple[int, np.ndarray] | None = None, via: Predicate | None = None,
                out_of_time: Callable[[], bool] | None = None, max_bytes: int | None = None) -> Found:
    """Up to ``runs`` random runs (:data:`RUN_BATCH` at a time) until one is a witness.

    At each decision a run draws one of its allowed actions uniformly (``allow when``; a run with none
    ends); a run ends at its first state outside ``through`` (and, with ``prune_unsafe``, at its first
    unsafe state) — after that state was tested against ``target``. ``start`` ``(k, row)`` starts the
    runs there instead of at the ego's start (the witness then starts at ``k``). With ``via`` a run is
    a witness only once one of its states satisfied ``via`` too. ``deadline``: a
    :func:`time.perf_counter` value after which no new batch is started (the searches' safety net);
    ``out_of_time``: asked once per sample, True stops the runs there (a caller's time limit, which a
    batch of long runs, a good part of a second, would otherwise overrun). Either sets :attr:`Found.timed_out`.
    ``max_bytes`` (None: none): a batch's runs are held whole (each state and choice of each run), so a
    batch holds no more runs than fit in it; where not even one run fits, none is made
    (:attr:`Found.out_of_memory`)."""
    model = batch_model(data)
    guard = ActionGuard(data)
    pairs = action_pairs(data)
    rng = np.random.default_rng(seed)
    first_k, first = start if start is not None else (0, start_row(data, model))
    length = horizon_samples - first_k + 1
    columns = _columns(data)
    generated = done = 0
    batch = RUN_BATCH
    if max_bytes is not None:
        # a run's history (its states, int32) and its choices (int64), for every sample to the horizon
        batch = min(batch, max_bytes // (length * (len(first) * 4 + 8)))
        if batch < 1:
            return Found(None, 0, out_of_memory=True)
    while done < runs:
        if deadline is not None and done and time.perf_counter() > deadline:
            return Found(None, generated, timed_out=True, runs=done)
        n = min(batch, runs - done)
        rows = np.repeat(np.asarray(first, dtype=np.int32)[None], n, axis=0)
        history = np.zeros((n, length, rows.shape[1]), dtype=np.int32)
        chosen = np.full((n, max(length - 1, 0)), -1, dtype=np.int64)
        alive = np.arange(n)
        visited = np.zeros(n, dtype=bool) if via is not None else np.ones(n, dtype=bool)
        for k in range(first_k, horizon_samples + 1):
            if out_of_time is not None and out_of_time():
                return Found(None, generated, timed_out=True, runs=done + n)
            step = k - first_k
            history[alive, step] = rows[alive]
            generated += alive.size
            if via is not None:
                visited[alive] |= np.asarray(via(k, rows[alive]), dtype=bool)
            hit = np.asarray(target(k, rows[alive]), dtype=bool) & visited[alive]
            if hit.any():
                run = int(alive[np.flatnonzero(hit)[0]])
                states = np.column_stack([np.arange(first_k, k + 1, dtype=np.int32), history[run, :step + 1]])
                witness = Witness(states, columns, chosen[run, :step].copy(), "random runs")
                return Found(witness, generated, runs=done + n)
            if k == horizon_samples:
                break
            go = np.ones(alive.size, dtype=bool)
            if prune_unsafe:
                go &= safe_states(data, k, rows[alive])
            if through is not None:
                go &= np.asarray(through(k, rows[alive]), dtype=bool)
            alive = alive[go]
            if k % data.decide_every == 0 and alive.size:
                masks = guard.masks(rows[alive, EGO], k)
                draw = np.where(masks, rng.random(masks.shape), -1.0)
                action = draw.argmax(axis=1)
                allowed = masks.any(axis=1)
                alive, action = alive[allowed], action[allowed]
                rows[alive, ACTION] = pairs[action]
                chosen[alive, step] = action
            if not alive.size:
                break
            moved = model.sense(rows[alive, EGO])
            if data.sticky:
                crashed = (rows[alive, CRASHED] != 0) | model.collide(moved, k + 1)
                rows[alive] = np.column_stack([moved, crashed]).astype(np.int32)
            else:
                rows[alive] = moved
        done += n
    return Found(None, generated, runs=done)


# ---------------------------------------------------------------- explorations that stop at a witness
def witness_in(graph: ExploredGraph, target: Predicate, search: str) -> Witness | None:
    """A witness ending in the last layer of ``graph`` (where an exploration with ``stop_at`` stops), or
    None when no state there satisfies ``target``."""
    if graph.n_states == 0:
        return None
    k = int(graph.states[-1, GraphColumn.K])
    layer = np.flatnonzero(graph.states[:, GraphColumn.K] == k)
    hit = np.asarray(target(k, graph.states[layer, GRAPH_LAYER_ROW]), dtype=bool)
    if not hit.any():
        return None
    return witness_along(graph, graph.path_to(int(layer[np.flatnonzero(hit)[0]])), search)


def witness_along(graph: ExploredGraph, path: list[int], search: str) -> Witness:
    """The run of ``graph`` through the states ``path`` (consecutive ones joined by a choice)."""
    actions = []
    for source, following in zip(path, path[1:]):
        choices = graph.choices(source)
        local = np.flatnonzero(graph.choice_target[choices.start:choices.stop] == following)
        actions.append(int(graph.choice_action[choices.start + int(local[0])]))
    return Witness(graph.states[path].copy(), graph.columns, np.asarray(actions, dtype=np.int64), search)


def beam_search(data: ModelData, target: Predicate, *, horizon_samples: int, width: int, seed: int,
                through: Predicate | None = None, prune_unsafe: bool = False, score: Score | None = None,
                deadline: float | None = None, max_bytes: int | None = None) -> Found:
    """A beam search: each layer keeps its ``width`` states of lowest ``score`` (default:
    :func:`goal_distance`; ties broken at random, seeded), the target states first and, with ``through``,
    only states satisfying it; it stops at the first layer with a target state. When no layer had to
    be cut (and none was filtered by ``through``), the graph it returns is the whole exploration
    (``complete``). Past ``max_bytes`` it stops without a witness (:attr:`Found.out_of_memory`)."""
    if through is not None:
        # explore's beam chooses among each new layer's states, never the start's: a start outside ``through``
        # (and not a target) ends every run there, as in random_runs and the replay
        start = start_row(data, batch_model(data))[None, :]
        if not bool(np.asarray(target(0, start))[0]) and not bool(np.asarray(through(0, start))[0]):
            return Found(None, 1)
    rng = np.random.default_rng(seed)
    rank = score if score is not None else goal_distance(data)
    generated = [0]

    def keep(k: int, rows: np.ndarray) -> np.ndarray:
        if deadline is not None and time.perf_counter() > deadline:
            raise _OutOfTime
        candidates = np.arange(rows.shape[0])
        if through is not None:
            candidates = np.flatnonzero(np.asarray(through(k, rows), dtype=bool))
        if candidates.size <= width:
            return candidates
        values = np.asarray(rank(k, rows[candidates]), dtype=np.float64)
        values = np.where(np.asarray(target(k, rows[candidates]), dtype=bool), -np.inf, values)
        best = np.lexsort((rng.random(candidates.size), values))[:width]
        return np.sort(candidates[best])

    def count(layer: int, frontier: int, total: int) -> None:
        generated[0] = total

    try:
        graph = explore(data, horizon_samples=horizon_samples, prune_unsafe=prune_unsafe, stop_at=target,
                        beam=keep, progress=count, max_bytes=max_bytes)
    except _OutOfTime:
        return Found(None, generated[0], timed_out=True)
    except BudgetExceeded as exc:  # a search that proves nothing: its caller goes on as after any cut search
        return Found(None, exc.states, out_of_memory=True)
    return Found(witness_in(graph, target, "beam"), graph.n_states, graph)


def layered_search(data: ModelData, target: Predicate, *, horizon_samples: int, prune_unsafe: bool = False,
                   budget: Budget | None = None, progress: Progress | None = None) -> Found:
    """Every state, breadth-first, checking each layer for a target state as soon as it is built and
    stopping at the first (:func:`~rac.engine.explore.explore` with ``stop_at``). Without a witness the
    graph is the complete exploration. :class:`~rac.engine.budget.BudgetExceeded` beyond ``budget``."""
    limits = budget or Budget()
    graph = explore(data, horizon_samples=horizon_samples, prune_unsafe=prune_unsafe, stop_at=target,
                    progress=progress, max_states=limits.max_states, max_bytes=limits.max_bytes)
    return Found(witness_in(graph, target, "breadth-first"), graph.n_states, graph)


def planned_runs(bounds: Bounds, horizon_samples: int) -> int:
    """The random runs :func:`search` makes at most: ``bounds.runs``, no more than its ``max_states``
    leave room for (each run a state per sample to the horizon), but at least one."""
    return min(bounds.runs, max(bounds.max_states // (horizon_samples + 1), 1))


def search(data: ModelData, target: Predicate, *, horizon_samples: int, seed: int, bounds: Bounds = Bounds(),
           through: Predicate | None = None, prune_unsafe: bool = False, score: Score | None = None) -> Found:
    """The cheap searches in turn — :func:`random_runs`, then :func:`beam_search` — within ``bounds``;
    the first witness found, else the beam's outcome (its graph complete when it never cut a layer),
    with the random runs made (:attr:`Found.runs`)."""
    deadline = None if bounds.safety_seconds is None else time.perf_counter() + bounds.safety_seconds
    runs = planned_runs(bounds, horizon_samples)
    width = min(bounds.width, max(bounds.max_states // (horizon_samples + 1), 1))
    seeds = np.random.SeedSequence(seed).spawn(2)
    found = Found(None, 0)
    if runs > 0:
        found = random_runs(data, target, horizon_samples=horizon_samples, runs=runs, seed=_seed(seeds[0]),
                            through=through, prune_unsafe=prune_unsafe, deadline=deadline, max_bytes=bounds.max_bytes)
    if found.witness is not None or width <= 0:
        return found
    beam = beam_search(data, target, horizon_samples=horizon_samples, width=width, seed=_seed(seeds[1]),
                       through=through, prune_unsafe=prune_unsafe, score=score, deadline=deadline,
                       max_bytes=bounds.max_bytes)
    return Found(beam.witness, found.states + beam.states, beam.graph, beam.timed_out,
                 found.out_of_memory or beam.out_of_memory, found.runs)


def _seed(sequence: np.random.SeedSequence) -> int:
    return int(sequence.generate_state(1)[0])


# ---------------------------------------------------------------- replay
def _text(columns: tuple[str, ...], row: list[int]) -> str:
    return ", ".join(f"{name}={value}" for name, value in zip(columns, row))


def replay(data: ModelData, witness: Witness, target: Predicate, *, through: Predicate | None = None,
           prune_unsafe: bool = False) -> None:
    """Run ``witness`` again with the scalar model (:class:`~rac.model.native.NativeModel`, the model's
    reference semantics) and check it: it starts at the ego's start at sample 0 and advances one
    sample per state, each state is ``sense()`` of the one before with the action chosen (allowed by
    ``allow when`` at decisions, kept between them), the states before the last satisfy ``through``
    (and are safe with ``prune_unsafe``), and the last satisfies ``target``.
    :class:`ReplayMismatch` otherwise."""
    native = NativeModel(data)
    guard = ActionGuard(data)
    pairs = action_pairs(data).tolist()
    found_by = f"the witness found by {witness.search}"

    def fail(sample: int, what: str) -> ReplayMismatch:
        return ReplayMismatch(f"{found_by} does not replay with the scalar model (rac.model.native) at sample "
                              f"{sample}: {what} (a bug in rac: the searches and the scalar model disagree)")

    states = witness.states.tolist()
    if len(witness.actions) != len(states) - 1:
        raise fail(0, f"{len(states)} states but {len(witness.actions)} actions")
    state = native.initial_state()
    crashed = native.collide(state, 0)
    columns = witness.columns[1:]
    for i, row in enumerate(states):
        k = i
        mine = [*state, int(crashed)] if data.sticky else list(state)
        if row[0] != k:
            raise fail(k, f"the witness's state {i} is at sample {row[0]}")
        if row[1:] != mine:
            raise fail(k, f"the search has {_text(columns, row[1:])}, the scalar model {_text(columns, mine)}")
        if i == len(states) - 1:
            break
        if prune_unsafe and (crashed or native.collide(state, k) or native.offroad(state, k)):
            raise fail(k, "the run passes through an unsafe state")
        if through is not None and not bool(through(k, np.asarray([mine], dtype=np.int32))[0]):
            raise fail(k, "the run leaves the states it must stay in")
        action = int(witness.actions[i])
        decide = k % data.decide_every == 0
        if decide != (action >= 0):
            raise fail(k, f"action {action} at a {'decision' if decide else 'sample between decisions'}")
        if decide:
            state = state._replace(jerk=pairs[action][0], turn=pairs[action][1])
        following = native.sense(state)
        if decide and not bool(guard.successors_allowed(np.asarray([following], dtype=np.int32), k + 1)[0]):
            raise fail(k, f"action {action} is not allowed by `allow when`")
        crashed = crashed or native.collide(following, k + 1)
        state = following
    last = [*state, int(crashed)] if data.sticky else list(state)
    if not bool(target(len(states) - 1, np.asarray([last], dtype=np.int32))[0]):
        raise fail(len(states) - 1, "the run's last state does not satisfy the target")


def witness_graph(data: ModelData, witness: Witness) -> ExploredGraph:
    """The witness as a graph of one path (its states, their labels, one choice each but the last), as
    :meth:`rac.verify.symbolic.SymbolicAnswerer.trace_rows` reads traces."""
    model = batch_model(data)
    n = witness.states.shape[0]
    k = witness.states[:, GraphColumn.K].astype(np.int64)
    rows = witness.states[:, GRAPH_EGO]
    collide = witness.states[:, GraphColumn.CRASHED] != 0 if data.sticky else model.collide(rows, k)
    labels = sample_labels(collide, model.offroad(rows, k), model.goal(rows, k))
    offsets = np.minimum(np.arange(n + 1, dtype=np.int64), n - 1)
    return ExploredGraph(states=witness.states, columns=witness.columns, choice_offsets=offsets,
                         choice_action=witness.actions.astype(np.int64),
                         choice_target=np.arange(1, n, dtype=np.int64), labels=labels)
