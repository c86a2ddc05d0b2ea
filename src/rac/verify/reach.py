"""Runs that ``rac verify`` looks for before it builds everything (issue 20): the witness of ``E<> q``,
the counterexamples of ``A[] p`` and ``A<> p``, the witness of ``E[] p`` and the reachability goals of
control queries, on the model (the product's are :mod:`rac.verify.symbolic`'s).

:meth:`Reacher.find` looks for a run through ``through`` to ``target`` in three steps, each only when the
one before found nothing:

1. a complete graph explored for an earlier query, when there is one, is read at once;
2. the cheap searches of :func:`rac.engine.witness.search` (random runs, a beam nearest the goal),
   seeded from the context and bounded by :attr:`VerifyOptions.witness`; a beam that never had to drop a
   state is the complete exploration, kept for later queries;
3. the breadth-first exploration that checks each layer as it is built and stops at the first witness
   (:func:`rac.engine.witness.layered_search`), within the state and memory budget; when it completes it
   is kept for later queries too.

Every witness is replayed with the scalar model (:func:`rac.engine.witness.replay`) before it is
reported. "No run" is only ever read from a complete graph (:attr:`ExploredGraph.complete`). The
result says which step decided (:attr:`Reached.method`, a key of :data:`rac.verify.status.METHODS`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from rac.core.diagnostics import counted, short_count
from rac.core.resources import memory_option
from rac.engine.budget import Budget, BudgetExceeded
from rac.engine.graph import ExploredGraph
from rac.engine.witness import (
    Bounds,
    Found,
    Predicate,
    Witness,
    layered_search,
    planned_runs,
    random_runs,
    replay,
    safe_states,
    search,
    witness_along,
)
from rac.model.data import ModelRangeError
from rac.model.sample import GRAPH_LAYER_ROW, GraphColumn
from rac.verify.context import Context, UnknownVerdict, left_int32, over_budget

__all__ = ["Reached", "Reacher", "in_graph"]


@dataclass(frozen=True)
class Reached:
    """What :meth:`Reacher.find` found: the ``witness`` (None: the complete graph ``graph`` has none),
    how (``method``), the ``states`` generated on the way (or the complete graph's), and whether it
    was looked for on the ``pruned`` model (a witness there is safe before its last state)."""

    witness: Witness | None
    method: str
    states: int
    pruned: bool
    graph: ExploredGraph | None = None


def in_graph(graph: ExploredGraph, target: Predicate) -> np.ndarray:
    """``target`` on every state of ``graph`` (layer by layer: a predicate reads one sample)."""
    mask = np.zeros(graph.n_states, dtype=bool)
    k = graph.states[:, GraphColumn.K]
    for sample in np.unique(k).tolist():
        rows = np.flatnonzero(k == sample)
        mask[rows] = target(int(sample), graph.states[rows, GRAPH_LAYER_ROW])
    return mask


class Reacher:
    """Finds runs of one file's model, sharing the context's explored graphs."""

    def __init__(self, context: Context) -> None:
        self.context = context

    def find(self, target: Predicate, *, prune: bool, through: Predicate | None = None,
             exhaustive: bool = True) -> Reached | None:
        """A run of the model (of the pruned model with ``prune``: safe before its last state) whose
        states before the last satisfy ``through`` and whose last satisfies ``target``, replayed.

        Without one: a :class:`Reached` without a witness when a complete graph proves that none
        exists — only for ``through`` None, since the graphs hold every run; None when the search ends
        without a proof (``exhaustive`` False, or a ``through`` condition). :class:`UnknownVerdict` when
        the exploration exceeds the budget."""
        ctx = self.context
        horizon = ctx.horizon_samples
        cached = ctx.graphs.get(prune)
        if cached is not None and through is None:
            hits = np.flatnonzero(in_graph(cached, target))
            if not hits.size:
                return Reached(None, "exhaustive", cached.n_states, prune, cached)
            path = cached.path_to(int(hits[0]))
            witness = witness_along(cached, path, "the explored graph")
            replay(ctx.data, witness, target, prune_unsafe=prune)
            return Reached(witness, "exhaustive", cached.n_states, prune, cached)
        try:
            bounds = ctx.options.witness
            # its graph shares --max-memory with the graphs kept for later queries, as any exploration does
            bounds = dataclasses.replace(bounds, max_states=min(bounds.max_states, ctx.options.max_states),
                                         max_bytes=ctx.memory_left())
            left = ctx.limit.remaining()  # the search's safety net within --max-seconds
            net = bounds.safety_seconds
            if left is not None and (net is None or left < net):
                bounds = dataclasses.replace(bounds, safety_seconds=left)
            found = search(ctx.data, target, horizon_samples=horizon, seed=ctx.search_seed(), bounds=bounds,
                           through=through, prune_unsafe=prune)
        except ModelRangeError as exc:
            raise UnknownVerdict(left_int32(exc)) from None
        if found.timed_out and bounds.safety_seconds == net:
            # the safety net, not --max-seconds (which ends the query, UNKNOWN, at its next check): said in
            # the answer, which now depends on the machine's speed (the runner's note)
            ctx.witness_clocked += 1
        if found.witness is not None:
            replay(ctx.data, found.witness, target, through=through, prune_unsafe=prune)
            return Reached(found.witness, "witness search", found.states, prune)
        if found.proves_absence and through is None:
            assert found.graph is not None
            ctx.graphs.setdefault(prune, found.graph)
            return Reached(None, "exhaustive", found.graph.n_states, prune, found.graph)
        if not exhaustive or through is not None:
            return None
        budget = Budget(ctx.options.max_states, ctx.memory_left(), "the model", float(ctx.period))
        try:
            layered = layered_search(ctx.data, target, horizon_samples=horizon, prune_unsafe=prune, budget=budget,
                                     progress=ctx.explore_progress)
        except BudgetExceeded as exc:
            raise UnknownVerdict(f"{over_budget(exc)}{ctx.kept_note()}; {_searched(found, bounds, horizon)}"
                                 ) from None
        except ModelRangeError as exc:
            raise UnknownVerdict(left_int32(exc)) from None
        assert layered.graph is not None
        if layered.witness is not None:
            replay(ctx.data, layered.witness, target, prune_unsafe=prune)
            return Reached(layered.witness, "on the fly", found.states + layered.states, prune)
        ctx.graphs.setdefault(prune, layered.graph)
        return Reached(None, "exhaustive", layered.graph.n_states, prune, layered.graph)

    def continues_safely(self, witness: Witness, target: Predicate) -> Found:
        """A run of the pruned model through a ``target`` state that stays safe to the horizon — a
        continuation of ``witness`` (whose last state satisfies ``target``), or else a run from the
        start — found by random runs and replayed (no witness: none found, which proves nothing). The runs
        stop at the query's time limit (``--max-seconds``; :attr:`Found.timed_out`), and hold no more runs at
        once than the memory budget leaves room for (:attr:`Found.out_of_memory` when not one fits)."""
        ctx = self.context
        horizon = ctx.horizon_samples
        data = ctx.data
        runs = ctx.options.witness.runs
        limit = ctx.limit

        def out_of_time() -> bool:
            return limit.remaining() == 0

        def at_end(k: int, rows: np.ndarray) -> np.ndarray:
            return safe_states(data, k, rows) & (k == horizon)

        found = random_runs(data, at_end, horizon_samples=horizon, runs=runs, seed=ctx.search_seed(),
                            prune_unsafe=True, start=(witness.samples, witness.last), out_of_time=out_of_time,
                            max_bytes=ctx.memory_left())
        made = found.runs
        tail = found.witness
        whole: Witness | None = None
        if tail is not None:
            whole = Witness(np.concatenate([witness.states[:-1], tail.states]), witness.columns,
                            np.concatenate([witness.actions, tail.actions]), witness.search)
        elif not found.timed_out and not found.out_of_memory:
            found = random_runs(data, at_end, horizon_samples=horizon, runs=runs, seed=ctx.search_seed(),
                                prune_unsafe=True, via=target, out_of_time=out_of_time, max_bytes=ctx.memory_left())
            whole = found.witness
            made += found.runs
        if whole is None:
            return Found(None, found.states, timed_out=found.timed_out, out_of_memory=found.out_of_memory, runs=made)
        replay(data, whole, at_end, prune_unsafe=True)
        return Found(whole, found.states, runs=made)


def _searched(found: Found, bounds: Bounds, horizon_samples: int) -> str:
    """What the cheap searches (:func:`~rac.engine.witness.search` within ``bounds``) tried, for an
    unknown verdict's message: the random runs they made (:attr:`Found.runs`), not those asked for."""
    cut = ", cut short by a time limit" if found.timed_out else ""
    if found.out_of_memory:
        cut = f", cut short by {memory_option()}"
    beam = f"a beam search ({counted(found.states, 'state')}{cut})"
    asked, made = bounds.runs, found.runs
    planned = planned_runs(bounds, horizon_samples)
    if made == asked:
        tried = f"no witness was found by {counted(asked, 'random run')} and {beam}"
    elif not made:  # random_runs makes none only where not one fits in the memory
        tried = f"no random run fitted in {memory_option()} and {beam} found no witness"
    else:
        why = ("cut short by a time limit" if made < planned
               else f"as many as a budget of {counted(bounds.max_states, 'state')} leaves room for")
        tried = f"no witness was found by {short_count(made)} of {counted(asked, 'random run')} ({why}) and {beam}"
    return f"{tried}, and the exhaustive exploration needed to prove that none exists is beyond the budget"
