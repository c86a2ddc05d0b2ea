"""``rac verify``'s symbolic queries: ``A[] p``, ``E<> p``, ``E[] p``, ``A<> p``, ``p --> q`` and
``strategy S = control: ...``, within the horizon and the state budget of the
:class:`~rac.verify.context.Context`: a run that decides a path query is looked for first
(:mod:`rac.verify.reach`); without one, and for the other forms, Storm decides on the complete
explored model (or its product with the automaton)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from rac import ir
from rac.core.diagnostics import counted
from rac.core.resources import memory_option
from rac.engine import shield, storm
from rac.engine.allow import action_pairs
from rac.engine.budget import BudgetExceeded, format_bytes
from rac.engine.evaluate import EvaluationError
from rac.engine.graph import ExploredGraph
from rac.engine.lookahead import Lookahead, LookaheadSettings
from rac.engine.ondemand import on_demand
from rac.engine.product import PHASES, ProductGraph, decide_product, explore_product, trace_to
from rac.engine.witness import Predicate, Witness, start_row, witness_graph
from rac.ir import expr as ie
from rac.ir import query as iq
from rac.ir.text import format_checked
from rac.ir.vocabulary import EGO_STATE
from rac.model.batch import batch_model
from rac.model.data import ModelData
from rac.model.native import NativeModel
from rac.verify import compositional
from rac.verify.context import Context, UnknownVerdict, over_budget, restricted
from rac.verify.reach import Reached, Reacher, in_graph
from rac.verify.report import TRACE_FLAGS, QueryResult, TraceRow
from rac.verify.status import NOT_SATISFIED, SATISFIED

if TYPE_CHECKING:  # the product is imported when a query needs it (a sweep task's memory limit is tight)
    from rac.engine.product import ProductGraph

__all__ = ["START_SAFETY_SECONDS", "START_WORK", "SymbolicAnswerer", "start_nodes"]


#: What a reachability strategy's result says: decided, and kept under no name (no table to save).
REACH_NOT_SAVED = "reachability strategies are decided but not saved"


class SymbolicAnswerer:
    """Answers path, leads-to and control queries on the explored model; a shield computed by a
    control query is kept in the context for later queries ``under`` it."""

    def __init__(self, context: Context) -> None:
        self.context = context
        self.reacher = Reacher(context)
        #: ``E<> p`` answers whose "safe to the horizon too?" was left open (no complete pruned graph yet),
        #: by query name: the open clause of the message and ``p``, for :meth:`settle` once a later
        #: query has explored that graph.
        self.open_horizons: dict[str, tuple[str, Predicate]] = {}

    def path(self, query: iq.PathQuery, base: QueryResult) -> QueryResult:
        """``A[] p``, ``E<> p``, ``E[] p``, ``A<> p`` (optionally ``under`` a shield), with a witness or
        counterexample trace.

        Under a shield the query is answered on what the shield allows (the shield's graph with its
        choices), never on the whole model; a shield that is missing or does not exist is reported
        before anything is explored. Otherwise the run that decides the query — the witness of ``E<>``
        and ``E[]``, the counterexample of ``A[]`` and ``A<>`` — is looked for first
        (:class:`~rac.verify.reach.Reacher`: a cheap search, then a layered one that stops at the first
        witness), and only its absence needs the complete graph. ``E<> p`` is tried on the pruned model
        first (unsafe states end a run there): a run found there is a run of the model."""
        if query.under is None and ie.state_independent(query.expr):
            return self._constant(query, base)
        if query.under is None and query.quantifier in ("A<>", "E[]") and not ie.reads_automaton(query.expr):
            at_start = self._at_start(query, base)
            if at_start is not None:
                return at_start
        if ie.reads_automaton(query.expr) or (self.context.program.automaton.ending is not None
                                               and query.under is None):
            # `episode ends when` ends runs early, as in the emitted model: only the product ends them
            return self.path_in_product(query, base)
        if query.under is not None:
            return self._decided(query, base, self.under_shield(query.under, "a query"))
        if query.quantifier == "E<>":
            return self._reach(query.expr, base)
        if query.quantifier == "A[]":
            return self._invariant(query.expr, base)
        return self._stays(query, base)

    def _constant(self, query: iq.PathQuery, base: QueryResult) -> QueryResult:
        """A formula that reads no state (:func:`rac.ir.expr.state_independent`: ``A[] !deadlock``, ``A[] true``)
        has one value in every state, and every state lies on a run to the horizon: ``A[] p``, ``E<> p``,
        ``E[] p`` and ``A<> p`` each hold exactly when ``p`` does, decided without exploring (a search for a
        state where ``A[] true`` fails has none to find, and only the complete graph would prove that)."""
        return dataclasses.replace(base, status=SATISFIED if self._value(query.expr) else NOT_SATISFIED,
                                   horizon_samples=self.context.horizon_samples, method="constant")

    def _at_start(self, query: iq.PathQuery, base: QueryResult) -> QueryResult | None:
        """``A<> p`` where ``p`` holds at the start, and ``E[] p`` where it does not, are decided there: every
        run begins in that state (a search for a run that never meets ``p`` has none to find, and only the
        complete graph would prove that). None when the start does not decide the query."""
        ctx = self.context
        holds = self._value(query.expr)
        if holds != (query.quantifier == "A<>"):
            return None
        status, said = (SATISFIED, "holds") if holds else (NOT_SATISFIED, "fails")
        return dataclasses.replace(base, status=status, states=1, horizon_samples=ctx.horizon_samples,
                                   method="initial state",
                                   message=f"`{format_checked(query.expr)}` {said} at t = 0")

    def _value(self, expr: ie.Expr) -> bool:
        """The value of the state formula ``expr`` at the start (the one value of a formula that reads no state,
        :func:`rac.ir.expr.state_independent`)."""
        ctx = self.context
        return bool(np.all(ctx.predicate(expr)(0, start_row(ctx.data, batch_model(ctx.data))[None, :])))

    def _constant_control(self, query: iq.ControlStrategy, base: QueryResult) -> QueryResult:
        """``control: A[] p`` or ``control: E<> p`` whose ``p`` reads no state: the start satisfies ``p`` exactly
        when every state does, so a strategy exists exactly when ``p`` holds (``A[] true``: every action keeps
        it; ``E<> true``: the start reaches it; ``false``: the start already fails). Decided without exploring;
        a safety strategy that exists is computed (every action allowed) when a query under it needs it."""
        ctx = self.context
        holds = self._value(query.expr)
        decided = dataclasses.replace(base, status=SATISFIED if holds else NOT_SATISFIED, method="constant",
                                      horizon_samples=ctx.horizon_samples)
        if query.goal != "A[]":
            ctx.reachability.add(query.name)  # as a searched one: decided, not kept
            return dataclasses.replace(decided, message=REACH_NOT_SAVED)
        goal = format_checked(query.expr)
        ctx.strategy_goals[query.name] = goal
        if not holds:
            return dataclasses.replace(decided, message=f"no strategy keeps `{goal}` from the start: it is false at "
                                                        "the start")

        def every_action() -> tuple[storm.Shield, shield.ShieldTable]:
            graph = ctx.graph(False)
            return self._shield(graph, np.ones(graph.n_states, dtype=bool))

        ctx.deferred[query.name] = every_action
        return dataclasses.replace(decided, message="every action keeps it, in every state; the strategy's table is "
                                                    "computed (on the whole model) when a query under it needs it, "
                                                    "and not saved")

    def _shield(self, graph: ExploredGraph, keep: np.ndarray) -> tuple[storm.Shield, shield.ShieldTable]:
        """The most permissive shield keeping the states ``keep`` on ``graph``, and its table."""
        ctx = self.context
        computed = storm.safety_shield(dataclasses.replace(graph, labels={**graph.labels, "query": keep}), "query")
        return computed, shield.table(computed, n_actions=len(ctx.pairs), model=ctx.data)

    def _reach(self, expr: ie.Expr, base: QueryResult) -> QueryResult:
        """``E<> p``: a safe run reaching ``p`` (the pruned model), else any run (the whole model)."""
        ctx = self.context
        target = ctx.predicate(expr)
        found = self._reaches(target)
        if found.witness is None:
            return dataclasses.replace(base, status="not satisfied", states=found.states,
                                       horizon_samples=ctx.horizon_samples, method=found.method)
        if found.pruned:
            message = self._safe_meaning(target, found.witness, base.name) if _implies_safe(expr) else None
        else:  # the pruned model has no such run: every witness passes through an unsafe state
            message = ("the trace passes through unsafe states (a collision does not end a run); NO run that stays "
                       "safe until it gets there exists")
        return self._witnessed(base, found, "satisfied", message)

    def _reaches(self, target: Predicate) -> Reached:
        """A run reaching ``target``: on the pruned model first (unsafe states end a run there; a run
        found there is a run of the model), then — when the pruned model proves that no run reaches it
        while safe — on the whole model, since a collision does not end a run of the model (as in the
        emitted UPPAAL model)."""
        found = self.reacher.find(target, prune=True)
        assert found is not None  # an exhaustive search either finds a run or proves there is none
        if found.witness is not None:
            return found
        anyway = self.reacher.find(target, prune=False)
        assert anyway is not None
        return anyway

    def _invariant(self, expr: ie.Expr, base: QueryResult) -> QueryResult:
        """``A[] p``: a run reaching ``!p`` is its counterexample. When unsafe states violate ``p``, the
        pruned model holds every first violation (the states before it are safe)."""
        ctx = self.context
        found = self.reacher.find(ctx.predicate(expr, negate=True), prune=_implies_safe(expr))
        assert found is not None
        status = "satisfied" if found.witness is None else "not satisfied"
        if found.witness is not None:
            return self._witnessed(base, found, status)
        return dataclasses.replace(base, status=status, states=found.states, horizon_samples=ctx.horizon_samples,
                                   method=found.method)

    def _stays(self, query: iq.PathQuery, base: QueryResult) -> QueryResult:
        """``E[] p`` (a run keeping ``p`` to the horizon) and ``A<> p`` (fails on a run keeping ``!p``): the
        cheap search for that run first, then Storm on the complete graph. Pruning unsafe states is sound
        for a formula that unsafe states violate (reaching one ends the run's claim)."""
        ctx = self.context
        horizon = ctx.horizon_samples
        keep = ctx.predicate(query.expr, negate=query.quantifier == "A<>")

        def to_end(k: int, rows: np.ndarray) -> np.ndarray:
            return keep(k, rows) & (k == horizon)

        prune = query.quantifier == "E[]" and _implies_safe(query.expr)
        found = self.reacher.find(to_end, prune=prune, through=keep, exhaustive=False)
        if found is not None and found.witness is not None:
            return self._witnessed(base, found, "satisfied" if query.quantifier == "E[]" else "not satisfied")
        return self._decided(query, base, ctx.graph(prune))

    def _witnessed(self, base: QueryResult, found: Reached, status: str, message: str | None = None) -> QueryResult:
        """The verdict a replayed witness gives, with its trace."""
        assert found.witness is not None
        chain = witness_graph(self.context.data, found.witness)
        return dataclasses.replace(base, status=status, states=found.states,
                                   horizon_samples=self.context.horizon_samples, message=message, method=found.method,
                                   trace=self.trace_rows(chain, list(range(chain.n_states))))

    def _safe_meaning(self, target: Predicate, witness: Witness, name: str | None = None) -> str:
        """What ``E<> p`` (query ``name``) found on the pruned model means, for a ``p`` that excludes
        collisions: whether one of the runs that stay safe until ``p`` stays safe to the horizon too —
        exactly when the complete pruned graph is at hand, else as far as a continuation of the witness
        shows it (left open for :meth:`settle` when that shows nothing)."""
        ctx = self.context
        complete = ctx.graphs.get(True)
        to_horizon: bool | None
        why = "random runs found none"
        if complete is not None:
            to_horizon = self._to_horizon(complete, target)
        else:
            found = self.reacher.continues_safely(witness, target)
            to_horizon = True if found.witness is not None else None
            if found.timed_out:
                why = "the random runs that look for one were cut short by --max-seconds"
            elif found.out_of_memory:
                why = f"not one random run to the horizon fits in {memory_option()}"
        clause = self._horizon_clause(to_horizon, why)
        if to_horizon is None and name is not None:
            self.open_horizons[name] = (clause, target)
        return "a run that stays safe until it gets there exists (the trace); " + clause

    @staticmethod
    def _to_horizon(complete: ExploredGraph, target: Predicate) -> bool:
        """Whether a run that stays safe until ``target`` stays safe to the horizon, exact on the
        ``complete`` pruned graph."""
        return storm.safe_reach(complete, in_graph(complete, target)).to_horizon

    def _horizon_clause(self, to_horizon: bool | None, why: str = "") -> str:
        """The part of ``E<> p``'s message that says whether a safe run to ``p`` stays safe to the horizon."""
        horizon = f"{self.context.horizon_samples * float(self.context.period):g} s"
        return (f"one of them stays safe to the horizon ({horizon}) too" if to_horizon
                else f"NONE of them stays safe to the horizon ({horizon})" if to_horizon is False
                else f"whether one of them stays safe to the horizon ({horizon}) is not known: {why} "
                     "(the complete pruned model would decide it)")

    def settle(self, results: list[QueryResult]) -> None:
        """Decide, in place, what :meth:`_safe_meaning` left open once a later query of the run has explored
        the complete pruned graph (a shield's, ``E[]``'s): the same exact answer as when that graph comes
        first, so that the run's answers agree (e.g. with a learning query's proof that no shielded run
        reaches the goal)."""
        complete = self.context.graphs.get(True)
        if complete is None or not complete.complete:
            return
        for i, result in enumerate(results):
            opened = self.open_horizons.pop(result.name, None)
            if opened is None or result.message is None or opened[0] not in result.message:
                continue
            clause, target = opened
            decided = (self._horizon_clause(self._to_horizon(complete, target))
                       + " (decided on the complete pruned model, which a later query explored)")
            results[i] = dataclasses.replace(result, message=result.message.replace(clause, decided))

    def _decided(self, query: iq.PathQuery, base: QueryResult, graph: ExploredGraph) -> QueryResult:
        """``query`` decided by Storm on ``graph`` (a complete one: a shield's, or the explored model)."""
        ctx = self.context
        assert graph.complete, "a query is decided only on a complete graph"
        labelled = dataclasses.replace(graph, labels={**graph.labels, "query": ctx.label(graph, query.expr)})
        verdict = storm.decide(labelled, query.quantifier, "query")
        return dataclasses.replace(base, status="satisfied" if verdict.holds else "not satisfied",
                                   states=graph.n_states, horizon_samples=ctx.horizon_samples, method="exhaustive",
                                   trace=self.trace_rows(graph, verdict.trace))

    def path_in_product(self, query: iq.PathQuery, base: QueryResult) -> QueryResult:
        """A path query over the automaton's names: on the automaton alone where that decides it
        (:mod:`rac.verify.compositional`), else on the product of model and automaton, explored
        layer by layer and stopped at the first witness or counterexample (on the fly)."""

        ctx = self.context
        if query.under is not None:
            raise EvaluationError("`under` a strategy is not supported on the product of model and automaton")
        holds, meaning = compositional.decide(ctx, query.quantifier, query.expr)
        if holds is not None:
            return dataclasses.replace(base, status=SATISFIED if holds else NOT_SATISFIED, method="compositional",
                                       horizon_samples=ctx.horizon_samples, message=meaning)
        stop = None
        if query.quantifier in ("A[]", "E<>"):
            box = query.quantifier == "A[]"

            def stop(layer: ProductGraph) -> np.ndarray:
                mask = layer.label(query.expr, box=box)
                return ~mask if box else mask
        if stop is not None:
            # the automaton reaches a violation (or the witness): search the model for a run that
            # produces it first, a beam toward the locations where it happens and toward the goal
            guided = self._guided_product(query, stop)
            if guided is not None:
                return dataclasses.replace(base, status=NOT_SATISFIED if query.quantifier == "A[]" else SATISFIED,
                                           method="product search", states=guided.n_states,
                                           horizon_samples=ctx.horizon_samples,
                                           trace=self.trace_rows(guided, trace_to(guided, guided.stopped_at)))
        try:
            graph = explore_product(ctx.data, ctx.automaton, horizon_samples=ctx.horizon_samples,
                                    progress=ctx.explore_progress, max_states=ctx.options.max_states,
                                    max_bytes=ctx.memory_left(), stop_at=stop)
        except BudgetExceeded as exc:
            raise UnknownVerdict(f"{over_budget(exc)}{ctx.kept_note()} (the automaton alone does not decide it: "
                                 f"{meaning})") from None
        if graph.stopped_at >= 0:
            return dataclasses.replace(base, status=NOT_SATISFIED if query.quantifier == "A[]" else SATISFIED,
                                       method="on the fly", states=graph.n_states, horizon_samples=ctx.horizon_samples,
                                       trace=self.trace_rows(graph, trace_to(graph, graph.stopped_at)))
        verdict = decide_product(graph, query, base.formula)
        return dataclasses.replace(base, status=SATISFIED if verdict.holds else NOT_SATISFIED, method="exhaustive",
                                   states=graph.n_states, horizon_samples=ctx.horizon_samples,
                                   trace=self.trace_rows(graph, verdict.trace))

    def _guided_product(self, query: iq.PathQuery, stop: Callable[[ProductGraph], np.ndarray]) -> ProductGraph | None:
        """A beam search of the product toward where ``stop`` marks a state (the automaton's own
        distance to the locations where the query can fail, then the distance to the goal), bounded
        by :data:`GUIDED_WIDTH` states per sample and :data:`GUIDED_STATES` in all; the partial graph
        with the first marked state, or None (which proves nothing)."""

        ctx = self.context
        automaton = ctx.automaton
        targets = _query_locations(query.expr, len(automaton.locations))
        distance = _distances_to(automaton, targets)
        jitter = np.random.default_rng(ctx.search_seed())
        locations = ProductGraph.columns_of(automaton).index("location")

        def score(layer: ProductGraph) -> np.ndarray:
            loc = layer.states[:, locations].astype(np.int64)
            goal = np.asarray(layer.evaluate(ie.call("dist_goal")), dtype=float)
            return distance[loc] * 1e6 + np.minimum(goal, 1e5) + jitter.random(layer.n_states)

        # a width that keeps the whole search within GUIDED_STATES: each expanded state has a choice
        # per action pair at a decision and one between decisions, in about three phases per sample
        branching = max(1, len(ctx.pairs) // max(1, ctx.data.decide_every))
        width = int(np.clip(GUIDED_STATES // (3 * max(1, ctx.horizon_samples) * branching), 8, GUIDED_WIDTH))
        try:
            # its progress is the query's: --max-seconds checked per sample (TimeExceeded: UNKNOWN), the bar counts
            graph = explore_product(ctx.data, automaton, horizon_samples=ctx.horizon_samples,
                                    progress=ctx.explore_progress,
                                    max_states=min(ctx.options.max_states, GUIDED_STATES),
                                    max_bytes=ctx.memory_left(), stop_at=stop, beam=(width, score))
        except BudgetExceeded:
            return None
        return graph if graph.stopped_at >= 0 else None

    def leads_to(self, query: iq.LeadsToQuery, base: QueryResult) -> QueryResult:
        """``p --> q``: every reachable ``p``-state is followed by ``q`` on every run."""
        ctx = self.context
        if ie.reads_automaton(query.left) or ie.reads_automaton(query.right):
            raise EvaluationError("`-->` over the automaton's names is not supported yet")
        if query.under is None:
            decided = self._constant_leads_to(query)
            if decided is not None:
                return dataclasses.replace(base, status=SATISFIED if decided[0] else NOT_SATISFIED, method="constant",
                                           horizon_samples=ctx.horizon_samples, message=decided[1])
        graph = self.under_shield(query.under, "`-->`") if query.under is not None else ctx.graph(False)
        p, q = ctx.label(graph, query.left), ctx.label(graph, query.right)
        # p --> q fails exactly when a reachable p-state has a run avoiding q forever (E[] !q there).
        mdp = storm.to_mdp(dataclasses.replace(graph, labels={"notq": ~q}))
        values, _ = storm.check_formula(mdp, 'Pmax=? [G "notq"]')
        holds = not bool(np.any(p & (values > 0.5) & graph.reachable()))
        return dataclasses.replace(base, status="satisfied" if holds else "not satisfied", states=graph.n_states,
                                   horizon_samples=ctx.horizon_samples, method="exhaustive")

    def _constant_leads_to(self, query: iq.LeadsToQuery) -> tuple[bool, str] | None:
        """``p --> q`` where a side that reads no state decides it, with why: ``q`` true (every ``p``-state
        is a ``q``-state), ``p`` false (no ``p``-state), or ``p`` true and ``q`` false (the start is a
        ``p``-state and no state is a ``q``-state); None otherwise (``true --> q`` reads ``q`` in every
        reachable state, ``p --> false`` asks whether a ``p``-state is reachable)."""
        left = self._value(query.left) if ie.state_independent(query.left) else None
        right = self._value(query.right) if ie.state_independent(query.right) else None
        p, q = format_checked(query.left), format_checked(query.right)
        if right is True:
            return True, f"`{q}` holds in every state, so every `{p}`-state is followed by it at once"
        if left is False:
            return True, f"`{p}` holds in no state, so no state has to be followed by `{q}`"
        if left is True and right is False:
            return False, f"`{p}` holds at the start, and `{q}` in no state"
        return None

    def control(self, query: iq.ControlStrategy, base: QueryResult) -> QueryResult:
        """``strategy S = control: A[] p``: the most permissive shield keeping ``p``, kept as ``S`` and
        saved to ``OUT/S.shield.npz``; a reachability goal (``E<> p``) is decided, not saved."""
        ctx = self.context
        if ie.reads_automaton(query.expr):
            raise EvaluationError("strategies over the automaton's names are not supported yet")
        if query.under is None and ie.state_independent(query.expr):
            return self._constant_control(query, base)
        within = self.under_shield(query.under, "a strategy") if query.under is not None else None
        if query.goal != "A[]":
            saved = REACH_NOT_SAVED
            ctx.reachability.add(query.name)  # a query `under` it says so (a failed one: not applicable)
            if within is None:  # a run reaching p: the strategy that follows it exists
                found = self._reaches(ctx.predicate(query.expr))
                return dataclasses.replace(base, status="not satisfied" if found.witness is None else "satisfied",
                                           states=found.states, horizon_samples=ctx.horizon_samples,
                                           method=found.method, message=saved)
            labelled = dataclasses.replace(within, labels={**within.labels, "query": ctx.label(within, query.expr)})
            verdict = storm.decide(labelled, "E<>", "query")
            return dataclasses.replace(base, status="satisfied" if verdict.holds else "not satisfied",
                                       states=within.n_states, horizon_samples=ctx.horizon_samples,
                                       method="exhaustive", message=saved)
        try:
            graph = within if within is not None else ctx.graph(_implies_safe(query.expr))
        except UnknownVerdict as exc:
            if within is not None or not _is_safety(query.expr):
                raise
            return self._on_demand(query, base, str(exc))
        keep = ctx.label(graph, query.expr)
        computed, table = self._shield(graph, keep)
        ctx.strategies[query.name] = (computed, table)
        ctx.strategy_goals[query.name] = format_checked(query.expr)
        files: tuple[str, ...] = ()
        if ctx.out_dir is not None and computed.shield_exists:  # UPPAAL defines no strategy either
            files = (str(shield.save(table, ctx.out(f"{query.name}.shield.npz"))),)
        allowed = int(computed.allowed_choices.sum())
        if computed.shield_exists:
            message = f"{int(computed.winning.sum()):,} winning states, {allowed:,} allowed choices"
        else:
            kept = _longest_kept(graph, keep)
            message = (f"no strategy keeps `{format_checked(query.expr)}` from the start: "
                       + ("it is false at the start" if kept < 0 else
                          f"the longest any run keeps it is until t = {kept * float(ctx.period):g} s, before the "
                          f"horizon ({ctx.horizon_samples * float(ctx.period):g} s)"))
        return dataclasses.replace(base, status="satisfied" if computed.shield_exists else "not satisfied",
                                   states=graph.n_states, horizon_samples=ctx.horizon_samples, files=files,
                                   message=message, method="exhaustive")

    def _on_demand(self, query: iq.ControlStrategy, base: QueryResult, too_large: str) -> QueryResult:
        """``control: A[] !collide() && !offroad()`` where the model is too large to explore: decided by
        the runtime shield searching the whole horizon from the start (a safe continuation proves the
        strategy exists; a complete search without one, that it does not); the strategy is then the
        on-demand shield (:mod:`rac.engine.ondemand`), computed state by state as runs reach them."""

        ctx = self.context
        native = NativeModel(ctx.data)
        start = native.initial_state()
        row = np.array([0, *list(start)[:7]], dtype=np.int64)
        goal = format_checked(query.expr)
        ctx.strategy_goals[query.name] = goal
        at = ctx.period
        if native.collide(start, 0) or native.offroad(start, 0):
            return dataclasses.replace(base, status=NOT_SATISFIED, method="on demand",
                                       horizon_samples=ctx.horizon_samples,
                                       message=f"no strategy keeps `{goal}` from the start: it is false at the start")
        nodes = start_nodes(ctx.data)
        ctx.limit.check()  # --max-seconds already spent (exploring the model): nothing left to search in
        # --max-seconds bounds the search too; without it the work budget decides (the same on every machine)
        # and the safety net only guards against a machine far slower than expected
        left = ctx.limit.remaining()
        limited = left is not None and left < START_SAFETY_SECONDS
        seconds = max(left, 1e-9) if limited and left is not None else START_SAFETY_SECONDS
        # --max-memory too: at its work budget's worst (a layer of millions of successors) it holds ~0.5 GB
        memory = ctx.memory_left()
        search = Lookahead(ctx.data, ctx.horizon_samples,
                           LookaheadSettings(depth=ctx.horizon_samples + 1, seconds=seconds, nodes=nodes,
                                             max_bytes=memory))
        # tqdm (via rac.output.progress): importing rac.verify.symbolic stays light
        from rac.output.progress import Progress

        # up to half a minute at its budget's worst: a bar on a terminal, the nodes in the heartbeat's line
        with Progress(total=nodes, desc=f"{query.name}: search from the start", unit="search nodes",
                      enabled=None if ctx.options.bars else False) as bar:
            found = search.decide(row, progress=lambda spent: bar.update(spent - bar.n))
        proved = found.depth >= found.target and found.depth > 0
        reach = f"t = {found.until * float(at):g} s"
        # what stopped an incomplete search: its node budget (the same answer on every machine) or, before
        # that was spent, the memory budget or --max-seconds (the user's limits, named) or the safety time
        # limit (then the answer is the machine's, and says so)
        budget = counted(nodes, "search node")
        stopped = (f"the memory budget of {format_bytes(memory or 0)} ({memory_option()}) before spending its "
                   f"budget of {budget}{ctx.kept_note()}" if found.memory else
                   f"the time limit of {ctx.limit.seconds:g} s (--max-seconds) before spending its budget of "
                   f"{budget}" if found.clock and limited else
                   f"its safety time limit of {START_SAFETY_SECONDS:g} s before spending its budget of {budget}"
                   if found.clock else
                   f"its budget of {budget}, the same on every machine")
        if found.clock and not limited and not found.memory:
            ctx.start_clocked += 1  # the answer is the machine's: the runner's note says so, as for witness searches
        if not proved and not found.complete:
            raise UnknownVerdict(f"{too_large}; a search for a safe run to the horizon from the start found none "
                                 f"(the longest it proved safe reaches {reach}; it stopped at {stopped})")
        if not proved:
            return dataclasses.replace(base, status=NOT_SATISFIED, method="on demand",
                                       horizon_samples=ctx.horizon_samples,
                                       message=(f"no strategy keeps `{goal}` from the start: the complete search of "
                                                f"the runs from the start keeps it until {reach} at best"))
        # the queries under it ask for states as their runs reach them, thousands in one sample of many runs:
        # each query's --max-seconds (ctx.limit, set per query) is checked between their searches
        computed = on_demand(ctx.data, ctx.horizon_samples, check=lambda: ctx.limit.check())
        ctx.on_demand[query.name] = computed
        allowed = int(found.mask.sum())
        # a search its budget stopped proved these and may have missed others: the count is a lower bound
        count = (f"{allowed} of {found.mask.size} actions have" if found.complete else
                 f"at least {allowed} of {found.mask.size} actions (the search stopped at {stopped}) have")
        return dataclasses.replace(
            base, status=SATISFIED, method="on demand", horizon_samples=ctx.horizon_samples,
            message=(f"{too_large.split(':')[0]}, so the shield is computed state by state: at the start "
                     f"{count} a safe continuation to the horizon; later "
                     f"states when runs reach them ({computed.nodes:,} search nodes each at most, the same on "
                     "every machine; an action not proved within them is not allowed). Not saved."))

    # ------------------------------------------------------------ pieces
    def under_shield(self, name: str, what: str) -> ExploredGraph:
        """The explored model restricted to the choices the shield ``name`` allows; a learned
        strategy is refused (its one run is answered for path queries only)."""
        if name in self.context.learned:
            raise EvaluationError(f"{what} under the learned strategy `{name}` is not supported (under a shield "
                                  "it is; path queries under a learned strategy are answered on its one run)")
        shield_, _ = self.context.strategy(name)
        return restricted(shield_)

    def trace_rows(self, graph: ExploredGraph, trace: list[int] | None) -> tuple[TraceRow, ...] | None:
        """The states of a witness trace as :data:`~rac.verify.report.TraceRow` s (None: no trace)."""
        if not trace:
            return None
        automaton = self.context.automaton
        rows = []
        scale = float(self.context.data.scale)
        columns = list(graph.columns)
        for index in trace:
            state = graph.states[index]
            row: TraceRow = {"time": round(int(state[columns.index("k")]) * float(self.context.period), 9)}
            for name in EGO_STATE:
                row[name] = int(state[columns.index(name)]) / scale
            if "location" in columns and automaton.location_names:
                row["location"] = automaton.location_names[int(state[columns.index("location")])]
            if "phase" in columns:  # a product state: which instant of its sample, and the rewards

                row["phase"] = PHASES[int(state[columns.index("phase")])]
                for reward in automaton.rewards:
                    if reward not in row:  # a reward named like an ego column would hide it
                        row[reward] = int(state[columns.index(f"mirror:{reward}")]) / scale
            for label in TRACE_FLAGS:
                if label in graph.labels:
                    row[label] = bool(graph.labels[label][index])
            rows.append(row)
        return tuple(rows)


def _longest_kept(graph: ExploredGraph, keep: np.ndarray) -> int:
    """The last sample that some run reaches while ``keep`` has held at every state so far (-1: not
    even the initial state keeps it): the counterexample of a shield that does not exist."""
    if not keep[graph.initial]:
        return -1
    owner = np.repeat(np.arange(graph.n_states), np.diff(graph.choice_offsets))
    k = graph.states[:, graph.columns.index("k")]
    frontier = np.zeros(graph.n_states, dtype=bool)
    frontier[graph.initial] = True
    last = int(k[graph.initial])
    while frontier.any():
        targets = graph.choice_target[frontier[owner]]
        targets = targets[keep[targets]]
        if targets.size == 0:
            break
        frontier = np.zeros(graph.n_states, dtype=bool)
        frontier[targets] = True
        last = max(last, int(k[targets].max()))
    return last


#: The guided search of the product: states expanded per sample, and states in all.
GUIDED_WIDTH, GUIDED_STATES = 2_000, 2_000_000


def _query_locations(expr: ie.Expr, count: int) -> np.ndarray:
    """The locations a query names (where it can turn), or all of them when it names none."""
    named = {node.index for node in ie.walk(expr) if isinstance(node, ie.Ref) and node.kind is ie.RefKind.LOCATION}
    mask = np.zeros(count, dtype=bool)
    mask[sorted(named) if named else list(range(count))] = True
    return mask


def _distances_to(automaton: ir.Automaton, targets: np.ndarray) -> np.ndarray:
    """Per location, the fewest edges to one of ``targets`` (guards ignored; unreachable: a large number)."""
    count = len(automaton.locations)
    distance = np.full(count, 1_000, dtype=np.int64)
    distance[targets] = 0
    for _ in range(count):
        for here, edges in enumerate(automaton.edges):
            for edge in edges:
                distance[here] = min(distance[here], distance[edge.target] + 1)
    return distance


#: The work the on-demand shield's search from the start for a safe run to the horizon (Qd's verdict) may
#: do: successor samples (search nodes x actions x samples per decision), which is what its time follows.
#: Spent in full it takes 6 s (9 actions every 20 samples, the head-on street) to 15 s (45 actions every 2,
#: the tutorial road, 0.4 GB: benchmarks/start_search.py) on the 2-core machine of docs/benchmarks.md,
#: within the 20 s of wall clock it had before (which gave UNKNOWN on a slow or busy machine where a fast
#: one answered); the benchmark scenes' and examples' searches need at most 44,000 (the head-on street's
#: 244 nodes). A budget of work gives the same verdict on every machine.
START_WORK = 12_000_000
#: The start search's safety net (seconds), far beyond what :data:`START_WORK` takes: where it stops the
#: search first, the answer says that it depends on the machine's speed and load.
START_SAFETY_SECONDS = 300.0


def start_nodes(data: ModelData) -> int:
    """The search nodes :data:`START_WORK` allows the start search over ``data`` (a node expands a state under
    every action for one decision period; at least 1, the first decision period, always searched)."""
    return max(1, START_WORK // (len(action_pairs(data)) * int(data.decide_every)))


def _is_safety(expr: ie.Expr) -> bool:
    """``expr`` is exactly ``!collide() && !offroad()`` (in either order): what the runtime shield keeps."""
    return (isinstance(expr, ie.Binary) and expr.op == "&&" and _implies_safe(expr)
            and all(isinstance(side, ie.Unary) for side in (expr.left, expr.right)))


def _implies_safe(expr: ie.Expr) -> bool:
    """``expr`` is a conjunction containing ``!collide()`` and ``!offroad()`` (so unsafe states violate it)."""
    found: set[str] = set()

    def walk(node: ie.Expr) -> None:
        if isinstance(node, ie.Binary) and node.op == "&&":
            walk(node.left)
            walk(node.right)
        elif (isinstance(node, ie.Unary) and node.op == "!" and isinstance(node.operand, ie.Call)
              and node.operand.function.kind == "model"):
            found.add(node.operand.name)

    walk(expr)
    return {"collide", "offroad"} <= found
