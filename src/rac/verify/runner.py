"""``rac verify``: a file's queries, and the paper's standard ones, answered by the native engine.

Every query form of the language is routed to the engine part that can answer it:

- ``A[] p``, ``E<> p``, ``E[] p``, ``A<> p`` and ``p --> q`` — exhaustive: the model is explored
  breadth-first (:func:`rac.engine.explore.explore`) up to the horizon, or its product with the
  automaton (:mod:`rac.engine.product`) when ``p`` reads the automaton's names, and Storm decides;
- ``strategy S = control: A[] p`` — the most permissive strategy keeping ``p`` (the shield),
  saved to ``OUT/S.shield.npz`` (load it with :func:`rac.engine.shield.load`) and usable by later
  queries ``... under S``;
- ``Pr[<=T](<> p)`` (Clopper–Pearson interval), ``Pr[...] >= θ`` (sequential test),
  ``E[<=T;N](max: e)`` and ``simulate[<=T;N]{e...}`` — statistical: runs simulated with
  actions drawn uniformly (restricted to a shield ``under S``) and the ground truth integrated
  finely (:mod:`rac.engine.simulate`); ``simulate`` writes ``OUT/NAME.csv`` and a plot;
- ``strategy S = maxE(e)[<=T]{d...}->{c...}: <> p under S0`` — learned by tabular Q-learning on
  episodes of the model (:func:`rac.learning.qlearning.learn`), saved to ``OUT/S.strategy.npz`` (load it
  with :meth:`rac.learning.qlearning.LearnedStrategy.load`); ``A[] p``, ``E<> p``, ``E[] p``, ``A<> p``
  ``under S`` are answered on the strategy's one run (model and strategy are deterministic).

Exhaustive queries are answered within a horizon (default: the automaton's ``horizon``) and a
state budget: a model that grows beyond it gets the verdict *unknown* with the sample it reached,
never a crash. Example::

    results = verify(compile_file("model.ra"), VerifyOptions(horizon=Fraction(2)))
    print(render_text(results))
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import numpy as np

from rac.check.standard import STANDARD
from rac.check.standard import standard_queries as checked_standard_queries
from rac.compiler import CompileResult
from rac.engine import shield, storm
from rac.engine.evaluate import EvaluationError, Evaluator, Frame
from rac.engine.explore import action_pairs, explore
from rac.engine.graph import ExploredGraph
from rac.ir import expr as ie
from rac.ir import query as iq
from rac.ir.vocabulary import EGO_STATE
from rac.model.data import ModelData, ModelRangeError
from rac.verify.learning import LearningQueries, _Learned
from rac.verify.report import QueryResult, _Unknown, render_json, render_text
from rac.verify.statistical import StatisticalQueries

__all__ = ["QueryResult", "UnknownQuery", "VerifyOptions", "render_json", "render_text", "standard_queries",
           "verify"]

#: What each standard query asks, in words (printed under its name); the queries themselves:
#: :data:`rac.check.standard.STANDARD`.
STANDARD_TITLES = {q.name: q.title for q in STANDARD if q.verify}


@dataclass(frozen=True)
class VerifyOptions:
    """How :func:`verify` answers queries (the ``rac verify`` options)."""

    #: Horizon of exhaustive queries in seconds (None: the automaton's ``horizon``).
    horizon: Fraction | None = None
    #: Exhaustive exploration stops with *unknown* beyond this many states.
    max_states: int = 5_000_000
    #: Seed of the statistical queries (None: a fresh seed, printed with the result).
    seed: int | None = None
    #: ``Pr[...](<> p)``: stop when the interval's half-width is at most epsilon (UPPAAL's -E).
    epsilon: float = 0.05
    #: Confidence of intervals (UPPAAL's 1 - alpha).
    confidence: float = 0.95
    #: Error bounds and indifference region of ``Pr[...] >= θ`` (UPPAAL's -a, -B, -d).
    alpha: float = 0.05
    beta: float = 0.05
    delta: float = 0.01
    #: Where strategies, CSV files and plots go (None: ``<file>.out`` beside the .ra file).
    out_dir: Path | None = None
    #: Also answer the paper's standard queries Qa–Qd and the Fig. 7 simulations.
    standard: bool = False
    #: Only these queries (by name); None: all.
    only: tuple[str, ...] | None = None
    #: Draw plots for ``simulate`` queries.
    plots: bool = True
    #: ``progress(message)``: called before each query (the CLI shows it on a TTY).
    progress: Callable[[str], None] | None = None
    #: Exploration callback ``(layer, frontier, total)`` (the CLI's progress bar).
    explore_progress: Callable[[int, int, int], None] | None = None
    #: Learning queries (``maxE``/``minE``, :func:`rac.learning.qlearning.learn`): the episode budget,
    #: the episodes stepped together, and the early stop after this many greedy evaluations
    #: without improvement once the greedy run succeeded.
    learn_episodes: int = 1000
    learn_parallel: int = 32
    learn_stop_after: int = 10
    #: Show a progress bar (on a terminal) while learning, with the running mean return.
    bars: bool = False


def standard_queries(result: CompileResult, horizon_seconds: Fraction | None = None) -> tuple[iq.QueryDecl, ...]:
    """The paper's standard queries that ``rac verify --standard`` answers, checked against the file's
    automaton, with ``MAXT`` the horizon (default: the automaton's)."""
    automaton = result.raise_for_errors()
    if horizon_seconds is None or horizon_seconds == automaton.horizon:
        return tuple(d for d in automaton.standard_queries if d.name in STANDARD_TITLES)
    return checked_standard_queries(automaton, horizon_seconds, verify_only=True)


def _decimal(value: Fraction) -> str:
    return str(value.numerator) if value.denominator == 1 else repr(float(value))


class UnknownQuery(KeyError):
    """``VerifyOptions.only`` names a query the file (and ``--standard``) does not have; ``args[0]``
    lists the missing names."""


class _Verifier(LearningQueries, StatisticalQueries):
    """Answers one file's queries in order, keeping the explored graphs and the strategies that
    later queries use (``under S``). Exhaustive and strategy queries are here; the statistical
    and learning ones in :mod:`rac.verify.statistical` and :mod:`rac.verify.learning`."""

    def __init__(self, result: CompileResult, options: VerifyOptions) -> None:
        automaton = result.raise_for_errors()
        if automaton.model is None or result.model_data is None:
            raise ValueError("rac verify needs a `model` block: the queries are answered on the scenario model")
        self.automaton = automaton
        self.data: ModelData = result.model_data
        self.options = options
        self.evaluator = Evaluator(self.data, automaton)
        self.period = Fraction(automaton.period)
        horizon = options.horizon if options.horizon is not None else Fraction(automaton.horizon)
        if (horizon / self.period).denominator != 1:
            raise ValueError(f"the horizon {_decimal(horizon)} s is not a whole number of samples of "
                             f"{_decimal(self.period)} s")
        self.horizon_samples = int(horizon / self.period)
        self.graphs: dict[bool, ExploredGraph] = {}
        self.strategies: dict[str, tuple[storm.Shield, shield.ShieldTable]] = {}
        #: Learned strategies (``strategy S = maxE(...)``) by name, for later queries ``under S``.
        self.learned: dict[str, _Learned] = {}
        self.result = result
        self.pairs = action_pairs(self.data)
        self.out_dir = options.out_dir
        self.seed_source = np.random.SeedSequence(options.seed)
        self.source_path = automaton.model.scenario_path

    # ------------------------------------------------------------ shared pieces
    def out(self, name: str) -> Path:
        if self.out_dir is None:
            raise _Unknown("no output folder")
        self.out_dir.mkdir(parents=True, exist_ok=True)
        return self.out_dir / name

    def graph(self, prune: bool) -> ExploredGraph:
        """The explored model up to the horizon (pruned: unsafe states are not expanded)."""
        if prune not in self.graphs:
            try:
                self.graphs[prune] = explore(self.data, horizon_samples=self.horizon_samples, prune_unsafe=prune,
                                             progress=self.options.explore_progress,
                                             max_states=self.options.max_states)
            except MemoryError as exc:
                raise _Unknown(f"{exc}: shorten the horizon (--horizon), coarsen the model (exponent, "
                               "action steps, decide_period) or raise --max-states") from None
            except ModelRangeError as exc:
                raise _Unknown(f"a sensed value left the int32 range: {exc}") from None
        return self.graphs[prune]

    def label(self, graph: ExploredGraph, expr: ie.Expr) -> np.ndarray:
        """A state formula on every state of a plain explored graph."""
        if ie.uses_prev(expr):
            raise EvaluationError("`prev(...)` in an exhaustive query is not supported: a merged state has no "
                                  "single previous sample")
        frame = Frame(k=graph.states[:, 0].astype(np.int64), ego=graph.states[:, 1:8])
        return np.ascontiguousarray(self.evaluator.evaluate_bool(expr, frame), dtype=bool)

    @staticmethod
    def needs_product(expr: ie.Expr) -> bool:
        """Whether ``expr`` reads the automaton's state (inputs, rewards, locations)."""
        return ie.reads_automaton(expr)

    def strategy(self, name: str) -> tuple[storm.Shield, shield.ShieldTable]:
        if name not in self.strategies:
            raise _Unknown(f"the strategy `{name}` has not been computed (it is defined by a query that was "
                           "skipped or failed; run it first)")
        if not self.strategies[name][0].shield_exists:
            # As in UPPAAL: a control query that is not satisfied yields no strategy to use.
            raise _Unknown(f"the strategy `{name}` does not exist: no safe strategy exists from the start")
        return self.strategies[name]

    def under_shield(self, name: str, what: str) -> ExploredGraph:
        """The explored model restricted to the choices the shield ``name`` allows; a learned
        strategy is refused (its one run is answered for path queries only)."""
        if name in self.learned:
            raise EvaluationError(f"{what} under the learned strategy `{name}` is not supported (under a shield "
                                  "it is; path queries under a learned strategy are answered on its one run)")
        shield_, _ = self.strategy(name)
        return _restricted(shield_)

    def bound_samples(self, bound: iq.Bound) -> int:
        """The samples within a query's time bound ``[<=T]`` (whole samples up to T s). A step bound
        ``[#<=K]`` is refused: UPPAAL counts transitions with it, and a sample of the model takes
        three or more (``accrue``, ``read``, ``sense``, at decisions ``decide`` and the choice)."""
        if bound.kind == "steps":
            raise EvaluationError("`[#<=K]` counts UPPAAL's transitions, not samples (a sample takes three or "
                                  "more): rac verify answers time bounds `[<=T]`")
        return math.floor(bound.limit / self.period)

    @staticmethod
    def runs_of(runs: int | None, default: int) -> int:
        return default if runs is None else runs

    def next_seed(self) -> int:
        """A fresh seed per query, all derived from the options' seed (reproducible as a whole)."""
        return int(self.seed_source.spawn(1)[0].generate_state(1)[0])

    def policy(self, under: str | None):
        """The simulation policy of the shield ``under`` (None: every action)."""
        return None if under is None else self.strategy(under)[1].masks_at

    def trace_rows(self, graph: ExploredGraph, trace: list[int] | None) -> tuple[dict, ...] | None:
        if not trace:
            return None
        rows = []
        scale = float(self.data.scale)
        columns = list(graph.columns)
        for index in trace:
            state = graph.states[index]
            row: dict[str, float | int | str] = {"time": round(int(state[columns.index("k")]) * float(self.period), 9)}
            for name in EGO_STATE:
                row[name] = int(state[columns.index(name)]) / scale
            if "location" in columns and self.automaton.location_names:
                row["location"] = self.automaton.location_names[int(state[columns.index("location")])]
            if "phase" in columns:  # a product state: which instant of its sample, and the rewards
                from rac.engine.product import PHASES

                row["phase"] = PHASES[int(state[columns.index("phase")])]
                for reward in self.automaton.rewards:
                    if reward not in row:  # a reward named like an ego column would hide it
                        row[reward] = int(state[columns.index(f"mirror:{reward}")]) / scale
            for label in ("collide", "offroad", "goal"):
                if label in graph.labels:
                    row[label] = bool(graph.labels[label][index])
            rows.append(row)
        return tuple(rows)

    # ------------------------------------------------------------ one query
    def answer(self, decl: iq.QueryDecl, title: str | None) -> QueryResult:
        query = decl.query
        base = QueryResult(decl.name, decl.text, _kind(query), "unknown", title=title, span=decl.span)
        t0 = time.perf_counter()
        try:
            result = self._answer(query, base)
        except _Unknown as exc:
            result = dataclasses.replace(base, status="unknown", message=str(exc))
        except EvaluationError as exc:
            result = dataclasses.replace(base, status="unsupported", message=str(exc))
        return dataclasses.replace(result, seconds=time.perf_counter() - t0)

    def _answer(self, query: iq.Query, base: QueryResult) -> QueryResult:
        if isinstance(query, iq.PathQuery):
            return self.path(query, base)
        if isinstance(query, iq.LeadsToQuery):
            return self.leads_to(query, base)
        if isinstance(query, iq.ControlStrategy):
            return self.control(query, base)
        if isinstance(query, iq.ProbabilityQuery):
            return self.probability(query, base)
        if isinstance(query, iq.ExpectationQuery):
            return self.expectation(query, base)
        if isinstance(query, iq.SimulateQuery):
            return self.simulate(query, base)
        if isinstance(query, iq.LearnStrategy):
            return self.learn(query, base)
        return dataclasses.replace(base, status="unsupported", message=f"{type(query).__name__} is not answered")

    # ------------------------------------------------------------ exhaustive
    def path(self, query: iq.PathQuery, base: QueryResult) -> QueryResult:
        if query.under is not None and query.under in self.learned:
            return self.path_under_learned(query, base)
        if self.needs_product(query.expr):
            return self.path_in_product(query, base)
        # Pruning unsafe states is sound for A[]/E[] of a formula that unsafe states violate
        # (reaching one already decides the query), never for E<>/A<>.
        prune = query.quantifier in ("A[]", "E[]") and _implies_safe(query.expr) and query.under is None
        graph = self.graph(prune)
        if query.under is not None:
            shield_, _ = self.strategy(query.under)
            graph = _restricted(shield_)
        labelled = dataclasses.replace(graph, labels={**graph.labels, "query": self.label(graph, query.expr)})
        verdict = storm.decide(labelled, query.quantifier, "query")
        message = None
        if verdict.trace and "safe" in graph.labels and not graph.labels["safe"][verdict.trace[:-1]].all():
            # A collision does not end a run of the model (as in the emitted UPPAAL model), so a
            # witness may pass through unsafe states; say so, and whether a safe one exists.
            message = "the trace passes through unsafe states (a collision does not end a run)"
            if query.quantifier == "E<>" and query.under is None:
                safe_graph = self.graph(True)
                target = self.label(safe_graph, query.expr) & safe_graph.labels["safe"]
                safe_verdict = storm.decide(dataclasses.replace(safe_graph, labels={**safe_graph.labels,
                                                                                   "query": target}), "E<>", "query")
                message += ("; a run that stays safe also reaches it" if safe_verdict.holds
                            else "; NO run that stays safe reaches it")
        return dataclasses.replace(base, status="satisfied" if verdict.holds else "not satisfied",
                                   states=graph.n_states, horizon_samples=self.horizon_samples,
                                   trace=self.trace_rows(graph, verdict.trace), message=message)

    def path_in_product(self, query: iq.PathQuery, base: QueryResult) -> QueryResult:
        from rac.engine.product import decide_product, explore_product

        if query.under is not None:
            raise _Unknown("`under` a strategy is not supported on the product of model and automaton")
        try:
            graph = explore_product(self.data, self.automaton, horizon_samples=self.horizon_samples,
                                    progress=self.options.explore_progress, max_states=self.options.max_states)
        except MemoryError as exc:
            raise _Unknown(f"{exc}: the product of model and automaton grows quickly; shorten the horizon "
                           "(--horizon) or coarsen the model") from None
        verdict = decide_product(graph, query, base.formula)
        return dataclasses.replace(base, status="satisfied" if verdict.holds else "not satisfied",
                                   states=graph.n_states, horizon_samples=self.horizon_samples,
                                   trace=self.trace_rows(graph, verdict.trace))

    def leads_to(self, query: iq.LeadsToQuery, base: QueryResult) -> QueryResult:
        if self.needs_product(query.left) or self.needs_product(query.right):
            raise _Unknown("`-->` over the automaton's names is not supported yet")
        graph = self.under_shield(query.under, "`-->`") if query.under is not None else self.graph(False)
        p, q = self.label(graph, query.left), self.label(graph, query.right)
        # p --> q fails exactly when a reachable p-state has a run avoiding q forever (E[] !q there).
        values, _ = storm._check(storm.to_mdp(dataclasses.replace(graph, labels={"notq": ~q})), 'Pmax=? [G "notq"]')
        holds = not bool(np.any(p & (values > 0.5) & _reachable(graph)))
        return dataclasses.replace(base, status="satisfied" if holds else "not satisfied", states=graph.n_states,
                                   horizon_samples=self.horizon_samples)

    def control(self, query: iq.ControlStrategy, base: QueryResult) -> QueryResult:
        if self.needs_product(query.expr):
            raise _Unknown("strategies over the automaton's names are not supported yet")
        within = self.under_shield(query.under, "a strategy") if query.under is not None else None
        if query.goal != "A[]":
            graph = within if within is not None else self.graph(False)
            labelled = dataclasses.replace(graph, labels={**graph.labels, "query": self.label(graph, query.expr)})
            verdict = storm.decide(labelled, "E<>", "query")
            return dataclasses.replace(base, status="satisfied" if verdict.holds else "not satisfied",
                                       states=graph.n_states, horizon_samples=self.horizon_samples,
                                       message="reachability strategies are decided but not saved")
        graph = within if within is not None else self.graph(_implies_safe(query.expr))
        labelled = dataclasses.replace(graph, labels={**graph.labels, "query": self.label(graph, query.expr)})
        computed = storm.safety_shield(labelled, "query")
        table = shield.table(computed, n_actions=len(self.pairs))
        self.strategies[query.name] = (computed, table)
        files: tuple[str, ...] = ()
        if self.out_dir is not None and computed.shield_exists:  # UPPAAL defines no strategy either
            files = (str(shield.save(table, self.out(f"{query.name}.shield.npz"))),)
        allowed = int(computed.allowed_choices.sum())
        message = (f"{int(computed.winning.sum()):,} winning states, {allowed:,} allowed choices"
                   if computed.shield_exists else "no safe strategy exists from the start")
        return dataclasses.replace(base, status="satisfied" if computed.shield_exists else "not satisfied",
                                   states=graph.n_states, horizon_samples=self.horizon_samples, files=files,
                                   message=message)

    # ------------------------------------------------------------ all
    def run(self, decls: Iterable[tuple[iq.QueryDecl, str | None]]) -> list[QueryResult]:
        results = []
        for decl, title in decls:
            if self.options.progress is not None:
                self.options.progress(f"{decl.name}: {decl.text}")
            results.append(self.answer(decl, title))
        return results


def verify(result: CompileResult, options: VerifyOptions | None = None) -> list[QueryResult]:
    """Answer the queries of a checked file (and, with ``options.standard``, the paper's standard
    queries first). :class:`rac.core.diagnostics.CheckError` when the file has errors; ``ValueError``
    when it has no ``model`` block; :class:`UnknownQuery` when ``options.only`` names a missing query."""
    return run_queries(result, options)[1]


def run_queries(result: CompileResult, options: VerifyOptions | None = None) -> tuple[_Verifier, list[QueryResult]]:
    """:func:`verify`, also returning the verifier, which keeps the strategies it computed
    (``.strategies`` for shields, ``.learned`` and :meth:`learned_run` for learned ones)."""
    options = options or VerifyOptions()
    verifier = _Verifier(result, options)
    decls: list[tuple[iq.QueryDecl, str | None]] = []
    if options.standard:
        decls += [(d, d.title or None) for d in standard_queries(result, options.horizon)]
    decls += [(d, None) for d in verifier.automaton.queries]
    if options.only is not None:
        known = {d.name for d, _ in decls}
        missing = [name for name in options.only if name not in known]
        if missing:
            raise UnknownQuery(", ".join(missing))
        # A query `under S` needs S: keep the strategies it names, in order. Backwards, so that a
        # strategy learned `under` a shield brings the shield too (a strategy precedes its uses).
        wanted = set(options.only)
        for decl, _ in reversed(decls):
            if decl.name in wanted and getattr(decl.query, "under", None):
                wanted |= {d.name for d, _ in decls if getattr(d.query, "name", None) == decl.query.under}
        decls = [(d, t) for d, t in decls if d.name in wanted]
    return verifier, verifier.run(decls)


# ---------------------------------------------------------------- helpers
def _kind(query: iq.Query) -> str:
    return {iq.PathQuery: "symbolic", iq.LeadsToQuery: "symbolic", iq.ControlStrategy: "strategy",
            iq.ProbabilityQuery: "probability", iq.ExpectationQuery: "expectation",
            iq.SimulateQuery: "simulate"}.get(type(query), "learning")


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


def _reachable(graph: ExploredGraph) -> np.ndarray:
    """The states reachable from the initial one through the graph's choices (a restricted graph
    keeps every explored state, also those its choices no longer reach)."""
    seen = np.zeros(graph.n_states, dtype=bool)
    frontier = np.array([graph.initial], dtype=np.int64)
    seen[frontier] = True
    while frontier.size:
        starts, ends = graph.choice_offsets[frontier], graph.choice_offsets[frontier + 1]
        counts = ends - starts
        index = np.repeat(starts - np.concatenate([[0], np.cumsum(counts)[:-1]]), counts) + np.arange(counts.sum())
        targets = np.unique(graph.choice_target[index])
        frontier = targets[~seen[targets]]
        seen[frontier] = True
    return seen


def _restricted(computed: storm.Shield) -> ExploredGraph:
    """The shield's graph with only the allowed choices (states without one become terminal)."""
    graph = computed.graph
    keep = computed.allowed_choices
    owner = np.repeat(np.arange(graph.n_states), np.diff(graph.choice_offsets))
    counts = np.bincount(owner[keep], minlength=graph.n_states)
    offsets = np.zeros(graph.n_states + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    return dataclasses.replace(graph, choice_offsets=offsets, choice_action=graph.choice_action[keep],
                               choice_target=graph.choice_target[keep])


